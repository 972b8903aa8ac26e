// Enrichment over several DEM ranks (coupler/dem_rezone.hpp, plan_new_grains): every rank
// plans the same new grains, and a grain held by another rank is in their way as much as one
// of its own. Runs in coupler_mpi_tests on 2 ranks.
#include <gtest/gtest.h>
#include <mpi.h>

#include <array>
#include <cmath>
#include <vector>

#include "coupler/dem_rezone.hpp"
#include "coupler/tuning.hpp"

namespace {

constexpr double kDx = 0.01, kD = 0.002;    // cell 5 grain diameters

struct Scene {
  coupler::GridGeometry<2> grid = coupler::padded_grid<2>(Eigen::Vector2d(0, 0), Eigen::Vector2d(0.05, 0.05), kDx);
  coupler::PackingTemplate<2> tmpl = coupler::make_packing_template<2>(10, 0.1, 12345);
  std::vector<coupler::RezoneCell<2>> cells;
  coupler::GrainRules rules;
  Eigen::Vector2d centre;
  Scene() {
    rules.dimension = 2, rules.density = 2500, rules.inertia = 0.5;
    coupler::RezoneCell<2> cell;
    const Eigen::Vector2i c(5, 5);    // inside the box (3 padding cells)
    cell.cell = coupler::cell_index<2>(grid, c);
    centre = coupler::cell_center<2>(grid, c);
    cell.make_grains = 1;
    cell.grain_weight = 0.5;
    cell.occupancy = ~coupler::Occupancy(0);
    // points holding the material of a cell at packing fraction 0.8, moving at (0.1, -0.2)
    const double mass = 0.8 * kDx * kDx * rules.density;
    cell.points.mass = mass;
    cell.points.first_moment() = mass * centre;
    cell.points.momentum() = mass * Eigen::Vector2d(0.1, -0.2);
    cells.push_back(cell);
  }
  std::vector<coupler::PlannedGrain<2>> plan(const coupler::DemGrains &obstacles) const {
    const double lo[3] = {0, 0, 0}, hi[3] = {0.05, 0.05, 0};
    return coupler::plan_new_grains<2>(grid, cells, {}, obstacles, tmpl, rules, kD, lo, hi, MPI_COMM_WORLD);
  }
};

TEST(DemRezoneRanks, EveryRankPlansTheSameGrainsAndAnotherRanksGrainIsInTheWay) {
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  Scene s;
  coupler::DemGrains none;
  const auto free = s.plan(none);
  // rank 1 holds a big frozen grain in the middle of the cell
  double xs[3] = {s.centre[0], s.centre[1], 0}, vs[3] = {0, 0, 0}, ws[3] = {0, 0, 0};
  double *x[1] = {xs}, *v[1] = {vs}, *w[1] = {ws};
  double radius[1] = {0.003}, rmass[1] = {1.0}, weight[1] = {1.0};
  int mask[1] = {2};
  coupler::DemGrains wall;
  if (rank == 1) {
    wall.n = 1, wall.x = x, wall.v = v, wall.omega = w, wall.radius = radius, wall.rmass = rmass;
    wall.mask = mask, wall.groupbit = 1, wall.weight = weight;
  }
  const auto blocked = s.plan(wall);

  ASSERT_FALSE(free.empty());
  EXPECT_LT(blocked.size(), free.size());
  double filled = 0, largest = 0;
  for (const auto &p : free) {
    EXPECT_EQ(p.slot, 0u);
    EXPECT_DOUBLE_EQ(p.share, 0.5);
    EXPECT_NEAR(p.grain.v[0], 0.1, 1e-12);    // the points' velocity (no gradient)
    EXPECT_NEAR(p.grain.v[1], -0.2, 1e-12);
    EXPECT_DOUBLE_EQ(p.grain.mass, s.rules.solid_mass(p.grain.radius));
    filled += p.grain.mass, largest = std::max(largest, p.grain.mass);
  }
  // as many as the material fills at their solid mass
  EXPECT_LE(filled - 0.5 * largest, s.cells[0].points.mass);
  for (const auto &p : blocked)
    EXPECT_GE((p.grain.x - s.centre).norm(), p.grain.radius + radius[0]) << "a new grain overlaps rank 1's grain";
  // the same plan on both ranks
  std::vector<double> mine;
  for (const auto &p : blocked) mine.insert(mine.end(), {p.grain.x[0], p.grain.x[1], p.grain.radius});
  int n = static_cast<int>(mine.size()), n0 = n;
  MPI_Bcast(&n0, 1, MPI_INT, 0, MPI_COMM_WORLD);
  ASSERT_EQ(n, n0);
  std::vector<double> first = mine;
  MPI_Bcast(first.data(), n, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  EXPECT_EQ(mine, first);
}

// Old grains along a cell's face overlap its candidates a little (by a tenth of a radius): the
// candidates are pushed off them, keeping their template size (shrinking them instead made the
// grains of a long silo discharge smaller than the DEM's), and end up overlapping nothing, inside
// their cell.
TEST(DemRezoneRanks, CandidatesAnOldGrainOverlapsALittleMoveOffItAndKeepTheirSize) {
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  Scene s;
  const auto free = s.plan(coupler::DemGrains{});
  const double face = s.centre[0] - 0.5 * kDx, r_old = 0.5 * kD;
  std::vector<std::array<double, 3>> xs, vs;
  for (const auto &p : free)
    if (p.grain.x[0] - face < 0.8 * kD)    // the candidates along the left face
      xs.push_back({p.grain.x[0] - (0.9 * p.grain.radius + r_old), p.grain.x[1], 0});
  ASSERT_GE(xs.size(), 3u);
  const int n = static_cast<int>(xs.size());
  vs.assign(xs.size(), {0, 0, 0});
  std::vector<double *> x(n), v(n);
  std::vector<double> radius(n, r_old), rmass(n, 1.0), weight(n, 1.0);
  std::vector<int> mask(n, 1);
  for (int i = 0; i < n; ++i) x[i] = xs[i].data(), v[i] = vs[i].data();
  coupler::DemGrains old;
  if (rank == 1) {    // held by the other rank
    old.n = n, old.x = x.data(), old.v = v.data(), old.omega = v.data(), old.radius = radius.data();
    old.rmass = rmass.data(), old.mask = mask.data(), old.groupbit = 1, old.weight = weight.data();
  }
  const auto fitted = s.plan(old);

  int moved = 0;
  double d2_free = 0, d2_fitted = 0;
  for (const auto &p : free) d2_free += p.grain.radius * p.grain.radius;
  for (const auto &p : fitted) {
    d2_fitted += p.grain.radius * p.grain.radius;
    // the template grain it was cut as: the free plan's nearest of the same size
    double nearest = 1;
    for (const auto &q : free)
      if (q.grain.radius == p.grain.radius) nearest = std::min(nearest, (q.grain.x - p.grain.x).norm());
    EXPECT_LE(nearest, (1 - coupler::kSmallestShrink) * p.grain.radius * (1 + 1e-9)) << "moved farther than it may";
    moved += nearest > 1e-12 ? 1 : 0;
    EXPECT_EQ(coupler::cell_of<2>(s.grid, p.grain.x), coupler::cell_coords<2>(s.grid, s.cells[0].cell));
    for (const auto &o : xs)
      EXPECT_GE((p.grain.x - Eigen::Vector2d(o[0], o[1])).norm(), p.grain.radius + r_old) << "overlaps an old grain";
    for (const auto &q : fitted)
      if (&q != &p) EXPECT_GE((p.grain.x - q.grain.x).norm(), p.grain.radius + q.grain.radius) << "two new grains overlap";
  }
  EXPECT_GE(moved, n / 2) << "the overlapped candidates were not pushed off";
  // the same sizes: every kept grain at its template size, as many grains within one
  EXPECT_NEAR(d2_fitted / static_cast<double>(fitted.size()), d2_free / static_cast<double>(free.size()),
              0.01 * d2_free / static_cast<double>(free.size()));
  EXPECT_NEAR(static_cast<double>(fitted.size()), static_cast<double>(free.size()), 1.0);
}

TEST(DemRezoneRanks, CellSumsAreSummedOverTheRanks) {
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  std::vector<coupler::BodySums<3>> sums(2);
  sums[0].moments.cell = 17;
  sums[0].moments.mass = rank + 1.0;
  sums[1].moments.momentum()[2] = 2.0;
  coupler::sum_over_ranks<3>(sums, MPI_COMM_WORLD);
  EXPECT_EQ(sums[0].moments.cell, 17u);
  EXPECT_DOUBLE_EQ(sums[0].moments.mass, 3.0);
  EXPECT_DOUBLE_EQ(sums[1].moments.momentum()[2], 4.0);
}

}    // namespace
