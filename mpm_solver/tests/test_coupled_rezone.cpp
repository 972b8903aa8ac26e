// The continuum's side of a rezone (CoupledContinuum::plan_rezone and complete_rezone,
// docs/design.md section 5.6): where a cell's material goes when its new zone cannot hold it.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <utility>
#include <vector>

#include "coupler/conversion.hpp"
#include "coupler/fill_pressure.hpp"
#include "coupler/protocol.hpp"
#include "coupler/tuning.hpp"
#include "mpm/coupled_continuum.hpp"

namespace {

constexpr double kCell = 0.01;          // m
constexpr double kGrainDensity = 2500;  // kg/m^2 (2D)
constexpr int kCells = 12;              // cells per axis of the box
const double kSolidContent = kGrainDensity * kCell * kCell;  // a cell's volume of solid grain material

coupler::Hello square_box() {
  coupler::Hello hello;
  coupler::set_text(hello.units, "si");
  hello.dimension = 2;
  hello.cell = kCell;
  hello.dt = 1e-5;
  for (int a = 0; a < 2; ++a) {
    hello.box_hi[a] = kCells * kCell;
    hello.continuum.container_hi[a] = kCells * kCell;
  }
  hello.continuum.grain_density = kGrainDensity;
  hello.continuum.grain_diameter = kCell / 3;
  return hello;
}

struct Rezone {
  std::vector<coupler::CellGrains> volumes;
  std::map<std::uint64_t, coupler::GrainSums<2>> sums;
};

/// Four grains of `mass` in all at the quarter points of a cell, moving at `velocity`, each
/// carrying the share `carried` of its solid mass (its weight).
void add_grains(Rezone& r, const coupler::GridGeometry<2>& grid, std::uint64_t cell, double mass,
                const std::array<double, 4>& carried = {1, 1, 1, 1},
                const Eigen::Vector2d& velocity = Eigen::Vector2d::Zero()) {
  r.volumes.push_back({cell, mass / kGrainDensity, 0.25 * mass * (carried[0] + carried[1] + carried[2] + carried[3])});
  const Eigen::Vector2d centre = coupler::cell_center<2>(grid, coupler::cell_coords<2>(grid, cell));
  coupler::GrainSums<2>& s = r.sums[cell];
  s.carried.moments.cell = s.solid.moments.cell = cell;
  int i = 0;
  for (double dx : {-0.25, 0.25})
    for (double dy : {-0.25, 0.25}) {
      const Eigen::Vector2d x = centre + kCell * Eigen::Vector2d(dx, dy);
      const double e = 0.5 * std::pow(kCell / 6, 2);  // a disk's own inertia per mass, r^2/2
      s.carried.add_body(x, velocity, carried[i++] * mass / 4, coupler::Spin<2>::Zero(), e, Eigen::Matrix2d::Zero(),
                         centre);
      s.solid.add_body(x, velocity, mass / 4, coupler::Spin<2>::Zero(), e, Eigen::Matrix2d::Zero(), centre);
    }
}

/// Runs one rezone with the given zones and grains; returns the continuum's totals after it.
coupler::StepAck rezone(mpm::CoupledContinuum<2>& continuum, const std::vector<std::int8_t>& zones, const Rezone& r) {
  continuum.plan_rezone(0.0, coupler::kZonesGiven, zones, coupler::OracleSettings{}, {}, {r.volumes});
  std::vector<coupler::GrainSums<2>> sums;
  for (const auto& [cell, s] : r.sums) sums.push_back(s);
  continuum.complete_rezone({sums});
  return continuum.totals(0);
}

/// Makes the cell (5, 5) hybrid from grains of `mass` at rest (`zones` takes the map: all other
/// cells discrete); returns the cell, `points` the mass its points took.
std::uint64_t hybrid_cell_of_grains(mpm::CoupledContinuum<2>& continuum, std::vector<std::int8_t>& zones, double mass,
                                    double& points) {
  const auto& grid = static_cast<const coupler::GridGeometry<2>&>(continuum.solver().grid());
  zones.assign(coupler::num_cells(grid), coupler::kDiscrete);
  const std::uint64_t x = coupler::cell_index<2>(grid, coupler::cell_of<2>(grid, kCell * Eigen::Vector2d(5.5, 5.5)));
  zones[x] = coupler::kHybrid;
  Rezone start;
  add_grains(start, grid, x, mass);
  points = rezone(continuum, zones, start).mass;
  return x;
}

/// Makes the cells 3 to 8 of both axes continuum, their points from grains of `mass` a cell moving
/// at velocity(j) in row j.
template <class Velocity>
void continuum_block(mpm::CoupledContinuum<2>& continuum, double mass, Velocity velocity) {
  const auto& grid = static_cast<const coupler::GridGeometry<2>&>(continuum.solver().grid());
  std::vector<std::int8_t> zones(coupler::num_cells(grid), coupler::kDiscrete);
  Rezone start;
  for (int i = 3; i <= 8; ++i)
    for (int j = 3; j <= 8; ++j) {
      const std::uint64_t c =
          coupler::cell_index<2>(grid, coupler::cell_of<2>(grid, kCell * Eigen::Vector2d(i + 0.5, j + 0.5)));
      zones[c] = coupler::kContinuum;
      add_grains(start, grid, c, mass, {1, 1, 1, 1}, velocity(j));
    }
  rezone(continuum, zones, start);
}

/// The grid node nearest to (x, y).
std::uint64_t node_nearest(const coupler::GridGeometry<2>& grid, double x, double y) {
  return grid.index(((Eigen::Vector2d(x, y) - grid.origin) / kCell).array().round().cast<int>().matrix());
}

/// The points' mass in each cell.
std::map<std::uint64_t, double> point_mass_per_cell(const mpm::CoupledContinuum<2>& continuum) {
  const auto& grid = static_cast<const coupler::GridGeometry<2>&>(continuum.solver().grid());
  const auto& pts = continuum.solver().points();
  std::map<std::uint64_t, double> mass;
  for (std::size_t p = 0; p < pts.size(); ++p)
    mass[coupler::cell_index<2>(grid, coupler::cell_of<2>(grid, pts.x[p]))] += pts.mass[p];
  return mass;
}

// A cell turns discrete again and again with only points in it (grains that flowed in, became
// points, and find no room to be grains again): each time its whole material is a rest for the
// points of the cells around. Those must not pile it up: a cell holding its volume of solid
// material takes no more, so every cell's points end below 1.5 times it (one correction scales
// its carriers by at most 3/2), the rests spread outwards, and once every cell within reach is
// full the cell keeps its rest. Without that the 8 cells next to it would take all of it (here
// 12 cells' worth: 2.3 times a cell's solid content each). Mass stays exact throughout.
TEST(CoupledRezone, RestsDoNotPileUpInThePointsThatTakeThem) {
  mpm::CoupledContinuum<2> continuum(square_box());
  const auto& grid = static_cast<const coupler::GridGeometry<2>&>(continuum.solver().grid());
  const std::size_t n = coupler::num_cells(grid);
  auto cell_at = [&](int i, int j) {  // cell i, j of the box (the grid may reach beyond it)
    return coupler::cell_index<2>(grid, coupler::cell_of<2>(grid, kCell * Eigen::Vector2d(i + 0.5, j + 0.5)));
  };
  const double packed = 0.8 * kSolidContent;  // a cell of grains at packing 0.8

  // a 9 x 9 block of continuum made from grains, around the cell X = (5, 5)
  std::vector<std::int8_t> zones(n, coupler::kDiscrete);
  Rezone start;
  for (int i = 1; i <= 9; ++i)
    for (int j = 1; j <= 9; ++j) {
      zones[cell_at(i, j)] = coupler::kContinuum;
      add_grains(start, grid, cell_at(i, j), packed);
    }
  const double made = rezone(continuum, zones, start).mass;
  ASSERT_NEAR(made, 81 * packed, 1e-12 * made);

  const std::uint64_t x = cell_at(5, 5);
  double mass = made;
  std::int64_t moved = 0, kept = 0;
  for (int cycle = 0; cycle < 15; ++cycle) {
    zones[x] = coupler::kDiscrete;  // its points are a rest: no grains there, no points allowed
    const coupler::StepAck out = rezone(continuum, zones, Rezone{});
    EXPECT_NEAR(out.mass, mass, 1e-12 * mass) << "cycle " << cycle;
    ASSERT_EQ(out.rests_moved + out.rests_kept, 1) << "cycle " << cycle;
    moved += out.rests_moved, kept += out.rests_kept;
    if (out.rests_moved == 1) EXPECT_EQ(point_mass_per_cell(continuum).count(x), 0u) << "cycle " << cycle;

    zones[x] = coupler::kContinuum;  // grains flowed in: they become points
    Rezone in;
    add_grains(in, grid, x, packed);
    mass = rezone(continuum, zones, in).mass;
  }
  EXPECT_GE(moved, 8) << "the rests went to the points around";
  EXPECT_GE(kept, 1) << "with every cell within reach full, the cell keeps its rest";
  double most = 0, total = 0;
  for (const auto& [cell, m] : point_mass_per_cell(continuum)) {
    total += m;
    if (cell != x) most = std::max(most, m);
  }
  EXPECT_NEAR(total, mass, 1e-12 * mass);
  EXPECT_NEAR(mass, (81 + 15) * packed, 1e-12 * mass);
  EXPECT_LT(most, 1.5 * kSolidContent);
  EXPECT_GT(most, 0.95 * kSolidContent) << "the cells around filled up to their solid content";
}

// The rezones' energy on the points, split by what they did (made, removed, corrected, rests),
// sums to the ledger's rezone term: a moving block made from grains is all 'made'; turning its
// middle cell discrete removes that cell's points and hands their material to the points around
// as a rest, which gains what the removal lost but for the rigid correction's change.
TEST(CoupledRezone, TheRezonesEnergyOnThePointsSplitsByWhatTheyDid) {
  mpm::CoupledContinuum<2> continuum(square_box());
  const auto& grid = static_cast<const coupler::GridGeometry<2>&>(continuum.solver().grid());
  continuum_block(continuum, 0.8 * kSolidContent, [](int j) { return Eigen::Vector2d(0.1 * j, -0.05); });
  const auto& e = continuum.rezone_energy();
  const double made = e.made.total();
  ASSERT_GT(e.made.kinetic, 0);
  EXPECT_EQ(e.made.potential, 0);  // (no gravity in this box)
  EXPECT_NEAR(made, continuum.rezone_ledger(), 1e-12 * std::abs(made));
  EXPECT_EQ(e.removed.total(), 0);
  EXPECT_EQ(e.corrected.total(), 0);
  EXPECT_EQ(e.rests.total(), 0);
  // by the cells' zone change: grains turned into points (discrete to continuum) homogenise
  EXPECT_EQ(e.by_mechanism[coupler::kHomogenisation].total(), made);
  EXPECT_EQ(e.by_mechanism[coupler::kEnrichment].total(), 0);
  EXPECT_EQ(e.by_mechanism[coupler::kRepair].total(), 0);

  std::vector<std::int8_t> zones(coupler::num_cells(grid), coupler::kDiscrete);
  for (int i = 3; i <= 8; ++i)
    for (int j = 3; j <= 8; ++j)
      zones[coupler::cell_index<2>(grid, coupler::cell_of<2>(grid, kCell * Eigen::Vector2d(i + 0.5, j + 0.5)))] =
          coupler::kContinuum;
  zones[coupler::cell_index<2>(grid, coupler::cell_of<2>(grid, kCell * Eigen::Vector2d(5.5, 5.5)))] =
      coupler::kDiscrete;
  const coupler::StepAck out = rezone(continuum, zones, Rezone{});
  ASSERT_EQ(out.rests_moved, 1);
  EXPECT_LT(e.removed.kinetic, 0);
  EXPECT_GT(e.rests.kinetic, 0);
  EXPECT_EQ(e.made.total(), made);
  const double scale = std::abs(made) + std::abs(e.removed.total()) + std::abs(e.rests.total());
  EXPECT_NEAR(e.total(), continuum.rezone_ledger(), 1e-12 * scale);
  // the middle cell's turn to discrete is an enrichment: its points' removal and the rest it gave
  EXPECT_EQ(e.by_mechanism[coupler::kHomogenisation].total(), made);
  EXPECT_NEAR(e.by_mechanism[coupler::kEnrichment].total(), e.removed.total() + e.rests.total(), 1e-12 * scale);
  EXPECT_EQ(e.by_mechanism[coupler::kRepair].total(), 0);
}

// A discrete cell whose points find no other points within reach to take them keeps them,
// waiting for room for grains; every rezone plans it again (points where the zone wants none).
// Its points must wait where they are: corrected in place, not removed and remade at the
// cell's lattice every rezone (which moved them and reset their deformation, so a bed with
// such cells never came to rest).
TEST(CoupledRezone, KeptRestWaitsInTheSamePoints) {
  mpm::CoupledContinuum<2> continuum(square_box());
  const auto& grid = static_cast<const coupler::GridGeometry<2>&>(continuum.solver().grid());
  std::vector<std::int8_t> zones(coupler::num_cells(grid), coupler::kDiscrete);
  const std::uint64_t x = coupler::cell_index<2>(grid, coupler::cell_of<2>(grid, kCell * Eigen::Vector2d(5.5, 5.5)));
  zones[x] = coupler::kContinuum;
  Rezone in;
  add_grains(in, grid, x, 0.8 * kSolidContent);
  const double mass = rezone(continuum, zones, in).mass;
  ASSERT_NEAR(mass, 0.8 * kSolidContent, 1e-12 * mass);

  zones[x] = coupler::kDiscrete;
  const auto& pts = continuum.solver().points();
  std::vector<Eigen::Vector2d> where;
  for (int cycle = 0; cycle < 4; ++cycle) {
    const coupler::StepAck out = rezone(continuum, zones, Rezone{});
    EXPECT_NEAR(out.mass, mass, 1e-12 * mass) << "cycle " << cycle;
    ASSERT_EQ(out.rests_kept, 1) << "cycle " << cycle;
    EXPECT_EQ(out.points_made, 0) << "cycle " << cycle;
    EXPECT_EQ(out.points_removed, 0) << "cycle " << cycle;
    ASSERT_GT(pts.size(), 0u);
    std::vector<Eigen::Vector2d> now(pts.x.begin(), pts.x.end());
    if (!where.empty()) {
      ASSERT_EQ(now.size(), where.size());
      for (std::size_t p = 0; p < now.size(); ++p) EXPECT_LT((now[p] - where[p]).norm(), 1e-12 * kCell) << "cycle " << cycle;
    }
    where = now;
    EXPECT_EQ(point_mass_per_cell(continuum).count(x), 1u);
  }
}

// A hybrid cell keeps its zone while its grains flow out below it and points come in from above
// (the band over a silo's orifice). Once its grains carry less than kStarvedGrains of their share
// of its material the rezone plans it again so that new grains are made from its points: without
// that the band emptied of grains, its points had nothing to agree with and fell through it into
// the discrete region (the 2D silo of 90 d, from 0.4 s on). While its grains hold their share it
// is left alone.
TEST(CoupledRezone, HybridCellDrainedOfItsGrainsMakesThemAgain) {
  const coupler::Hello hello = square_box();
  mpm::CoupledContinuum<2> continuum(hello);
  std::vector<std::int8_t> zones;
  const double packed = 0.8 * kSolidContent, weight = hello.continuum.grain_weight;
  double points = 0;  // the points take the rest of the cell
  const std::uint64_t x = hybrid_cell_of_grains(continuum, zones, packed, points);
  ASSERT_NEAR(points, (1 - weight) * packed, 1e-12 * packed);

  auto planned = [&](double grains_carry) {  // is x planned, and to make grains, with its grains carrying this
    Rezone now;
    if (grains_carry > 0) now.volumes.push_back({x, grains_carry / weight / kGrainDensity, grains_carry});
    for (const auto& plan : continuum.plan_rezone(0.0, coupler::kZonesGiven, zones, coupler::OracleSettings{}, {},
                                                  {now.volumes}))
      if (plan.cell == x) return plan.make_grains == 1 ? 2 : 1;
    return 0;
  };
  EXPECT_EQ(planned(weight * packed), 0) << "grains at their share: left alone";
  continuum.complete_rezone({});
  EXPECT_EQ(planned(0.6 * weight * packed), 0) << "a few left: still left alone";
  continuum.complete_rezone({});
  EXPECT_EQ(planned(0.3 * weight * packed), 2) << "most drained out: grains made again";
}

// A repair of material at rest that leaves the cell as it was (here: no grain could be made in
// the starved cell, so none comes back in the grain sums) is not planned again at every oracle
// step while the cell's grains and points stay the same (a 100 d collapse near rest replanned the
// same 2 cells at every one); it is once a grain comes or goes, and always while it moves.
TEST(CoupledRezone, ARepairThatChangedNothingWaitsForTheCellsGrainsToChange) {
  coupler::Hello hello = square_box();
  hello.continuum.gravity[1] = -9.81;  // (without gravity nothing is at rest)
  mpm::CoupledContinuum<2> continuum(hello);
  std::vector<std::int8_t> zones;
  const double packed = 0.8 * kSolidContent, weight = hello.continuum.grain_weight;
  double points = 0;
  const std::uint64_t x = hybrid_cell_of_grains(continuum, zones, packed, points);

  // is x planned, its grains (the volume that would carry `volume_of` at their weight) carrying `grains_carry`
  double kinetic = 0;  // of the grains in x
  auto planned_carrying = [&](double volume_of, double grains_carry) {
    const std::vector<coupler::CellGrains> volumes{{x, volume_of / weight / kGrainDensity, grains_carry, kinetic}};
    bool found = false;
    for (const auto& plan :
         continuum.plan_rezone(0.0, coupler::kZonesGiven, zones, coupler::OracleSettings{}, {}, {volumes}))
      found = found || plan.cell == x;
    continuum.complete_rezone({});  // no grain made, none in the sums: the points keep the cell
    return found;
  };
  auto planned = [&](double grains_carry) { return planned_carrying(grains_carry, grains_carry); };
  const double drained = 0.2 * weight * packed;
  EXPECT_TRUE(planned(drained)) << "most drained out: repaired";
  EXPECT_FALSE(planned(drained)) << "the same grains and points: the repair would do the same again";
  EXPECT_FALSE(planned(drained * (1 + 1e-12))) << "round-off in the grains' volume is no change";
  EXPECT_TRUE(planned(1.2 * drained)) << "a grain came: repaired again";
  EXPECT_FALSE(planned(1.2 * drained));
  // the same volume, lighter grains (a heavier one left, a lighter one came): repaired again
  EXPECT_TRUE(planned_carrying(1.2 * drained, 1.1 * drained));
  EXPECT_TRUE(planned(1.2 * drained)) << "and back";
  EXPECT_FALSE(planned(1.2 * drained));
  // a rezone of the cell for another reason (its zone changes, and back) forgets the repair
  zones[x] = coupler::kContinuum;
  EXPECT_TRUE(planned(1.2 * drained));
  zones[x] = coupler::kHybrid;
  EXPECT_TRUE(planned(1.2 * drained)) << "the zone changed back";
  EXPECT_TRUE(planned(1.2 * drained)) << "starved: the first repair since";
  EXPECT_FALSE(planned(1.2 * drained));
  // grains moving at 10 rest speeds (a flow): repaired every time
  kinetic = 0.5 * 1.2 * drained * std::pow(10 * coupler::kRestSpeed * std::sqrt(9.81 * hello.continuum.grain_diameter), 2);
  EXPECT_TRUE(planned(1.2 * drained));
  EXPECT_TRUE(planned(1.2 * drained));
}

// Grains made in a hybrid cell carry their weight's share of their mass; when they flow on into a
// discrete cell (the band over a silo's orifice, into the discrete region around it) no zone
// changes, and they left the silo light. A discrete cell whose grains carry less than
// kLightGrains of their solid mass is planned, its grains get their full mass and the points of
// the hybrid cell next to it give it: mass and momentum exact. Grains at their solid mass, or
// short of it by round-off, are left alone.
TEST(CoupledRezone, LightGrainsInADiscreteCellTakeTheirFullMassFromThePointsNearby) {
  const coupler::Hello hello = square_box();
  mpm::CoupledContinuum<2> continuum(hello);
  const auto& grid = static_cast<const coupler::GridGeometry<2>&>(continuum.solver().grid());
  auto cell_at = [&](int i, int j) {
    return coupler::cell_index<2>(grid, coupler::cell_of<2>(grid, kCell * Eigen::Vector2d(i + 0.5, j + 0.5)));
  };
  std::vector<std::int8_t> zones(coupler::num_cells(grid), coupler::kDiscrete);
  const std::uint64_t band = cell_at(5, 6), below = cell_at(5, 5);
  zones[band] = coupler::kHybrid;
  const double packed = 0.8 * kSolidContent, weight = hello.continuum.grain_weight;
  Rezone start;
  add_grains(start, grid, band, packed);
  const double points = rezone(continuum, zones, start).mass;
  ASSERT_NEAR(points, (1 - weight) * packed, 1e-12 * packed);

  auto planned = [&](double carried_share) {  // is `below` planned, its grains carrying this share of their mass
    Rezone now;
    add_grains(now, grid, band, packed, {weight, weight, weight, weight});
    now.volumes.push_back({below, packed / kGrainDensity, carried_share * packed});
    bool found = false;
    for (const auto& plan : continuum.plan_rezone(0.0, coupler::kZonesGiven, zones, coupler::OracleSettings{}, {},
                                                  {now.volumes}))
      found = found || plan.cell == below;
    continuum.complete_rezone({});
    return found;
  };
  EXPECT_FALSE(planned(1.0)) << "grains at their solid mass";
  EXPECT_FALSE(planned(1.0 - 1e-9)) << "round-off";
  EXPECT_TRUE(planned(1.0 - 0.5 / 30)) << "one grain of half weight among 30";

  // one of its four grains came at half weight, falling at 0.3 m/s with the others
  Rezone light;
  add_grains(light, grid, band, packed, {weight, weight, weight, weight});
  add_grains(light, grid, below, packed, {0.5, 1, 1, 1}, Eigen::Vector2d(0.0, -0.3));
  const auto plans = continuum.plan_rezone(0.0, coupler::kZonesGiven, zones, coupler::OracleSettings{}, {},
                                           {light.volumes});
  ASSERT_EQ(plans.size(), 1u);
  EXPECT_EQ(plans[0].cell, below);
  EXPECT_EQ(plans[0].make_grains, 0) << "the grains are there: they only take their mass";
  const auto corrections = continuum.complete_rezone({{light.sums.at(below)}});
  ASSERT_EQ(corrections.size(), 1u);
  EXPECT_EQ(corrections[0].weight, 1.0);
  EXPECT_EQ(corrections[0].remove, 0);
  EXPECT_NEAR(corrections[0].mass_factor, 1.0, 1e-12) << "the grains at their solid mass";
  const coupler::StepAck after = continuum.totals(0);
  EXPECT_EQ(after.rests_moved, 1);
  EXPECT_NEAR(after.mass, points - 0.125 * packed, 1e-12 * packed) << "the points gave what the grains took";
  // the mass came at the grains' velocity: grains plus points keep their momentum
  EXPECT_NEAR(after.momentum[1], -0.3 * -0.125 * packed, 1e-12 * packed);
  EXPECT_NEAR(after.momentum[0], 0.0, 1e-12 * packed);
}

// A light discrete cell takes its grains' missing mass from points within kRestReach cells; with
// none there the rezone could only keep the deficit, so the cell is not planned (a collapse whose
// continuum was gone replanned such cells at every oracle step to its end). The band's points
// count while within reach along every axis, not beyond; nor do points of a cell turning discrete.
TEST(CoupledRezone, LightGrainsWithNoPointsWithinReachAreLeftAlone) {
  const coupler::Hello hello = square_box();
  const double packed = 0.8 * kSolidContent, weight = hello.continuum.grain_weight;
  for (const int gap : {coupler::kRestReach, coupler::kRestReach + 1}) {
    for (const bool band_stays : {true, false}) {
      mpm::CoupledContinuum<2> continuum(hello);
      const auto& grid = static_cast<const coupler::GridGeometry<2>&>(continuum.solver().grid());
      auto cell_at = [&](int i, int j) {
        return coupler::cell_index<2>(grid, coupler::cell_of<2>(grid, kCell * Eigen::Vector2d(i + 0.5, j + 0.5)));
      };
      std::vector<std::int8_t> zones(coupler::num_cells(grid), coupler::kDiscrete);
      const std::uint64_t light = cell_at(2, 2), band = cell_at(2 + gap, 2 + gap);
      zones[band] = coupler::kHybrid;
      Rezone start;
      add_grains(start, grid, band, packed);
      rezone(continuum, zones, start);
      if (!band_stays) zones[band] = coupler::kDiscrete;
      Rezone now;
      add_grains(now, grid, band, packed, {weight, weight, weight, weight});
      now.volumes.push_back({light, packed / kGrainDensity, 0.9 * packed});
      bool found = false;
      for (const auto& plan : continuum.plan_rezone(0.0, coupler::kZonesGiven, zones, coupler::OracleSettings{}, {},
                                                    {now.volumes}))
        found = found || plan.cell == light;
      EXPECT_EQ(found, band_stays && gap <= coupler::kRestReach) << "gap " << gap << ", band stays " << band_stays;
    }
  }
}

// A flow's front on a floor the continuum touches: cell after cell along the row turns hybrid as
// half-weight grains arrive with no points in it, so each borrows half its material for its new
// points from the points within reach (a deficit, at most half of theirs each time). Points
// lighter than kLightestDebtor of a point's mass at the packing lend no more: without that the
// points behind such a front were drained geometrically, to 1e-8 of a point's mass in the 100 d
// collapse with the floor touched, where those slivers held pressures a hundred times the
// continuum's until one went non-finite. Mass stays exact; a cell with no lender near keeps its
// deficit in its grains.
TEST(CoupledRezone, PointsLightAlreadyLendNoDeficit) {
  coupler::Hello hello = square_box();
  hello.continuum.packing_fraction = 0.82;
  mpm::CoupledContinuum<2> continuum(hello);
  const auto& grid = static_cast<const coupler::GridGeometry<2>&>(continuum.solver().grid());
  auto cell_at = [&](int i, int j) {
    return coupler::cell_index<2>(grid, coupler::cell_of<2>(grid, kCell * Eigen::Vector2d(i + 0.5, j + 0.5)));
  };
  const double packed = 0.8 * kSolidContent, weight = hello.continuum.grain_weight;
  const double point_at_packing = 0.82 * kSolidContent / 4;  // 2 x 2 points a cell
  std::vector<std::int8_t> zones(coupler::num_cells(grid), coupler::kDiscrete);
  zones[cell_at(1, 5)] = coupler::kHybrid;
  Rezone start;
  add_grains(start, grid, cell_at(1, 5), packed);
  const double points = rezone(continuum, zones, start).mass;  // the points: 1 - weight of the cell
  ASSERT_NEAR(points, (1 - weight) * packed, 1e-12 * packed);
  double material = packed;            // points and grains, the grains at their carried masses
  double grains = weight * packed;     // the grains' carried mass
  std::int64_t kept = 0;
  for (int i = 2; i <= 10; ++i) {
    zones[cell_at(i, 5)] = coupler::kHybrid;
    Rezone front;
    add_grains(front, grid, cell_at(i, 5), packed, {weight, weight, weight, weight});
    continuum.plan_rezone(0.0, coupler::kZonesGiven, zones, coupler::OracleSettings{}, {}, {front.volumes});
    const auto corrections = continuum.complete_rezone({{front.sums.at(cell_at(i, 5))}});
    ASSERT_EQ(corrections.size(), 1u) << "cell " << i;
    const coupler::StepAck out = continuum.totals(0);
    kept += out.rests_kept;
    material += weight * packed;  // the half-weight grains that arrived
    // the cells behind keep their grains; the new cell's take the correction's factor
    grains += packed * corrections[0].mass_factor;  // the factor is on their solid mass
    EXPECT_NEAR(out.mass + grains, material, 1e-12 * material) << "cell " << i;
    material = out.mass + grains;
    const auto& pts = continuum.solver().points();
    for (std::size_t p = 0; p < pts.size(); ++p)
      EXPECT_GE(pts.mass[p], 0.5 * coupler::kLightestDebtor * point_at_packing) << "cell " << i << ", point " << p;
  }
  EXPECT_GE(kept, 1) << "the lenders ran light: a cell kept its deficit";
}

// rest_hold through the continuum's own rezone (docs/design.md 5.5, rule 7): a bed of grains
// whose free surface rises by two cells (grains poured on top) asks the oracle to step its cells
// under the old surface towards continuum. At rest (the grains' and points' speed below
// kRestSpeed sqrt(g d) in the cell and its neighbours) every zone is kept; with the hold off, or
// with the grains moving at ten times that speed, the same cells change; at half that speed they
// are held. The kinetic energy the grains report per cell is what decides.
TEST(CoupledRezone, ZonesOfABedAtRestAreHeldWhenItsSurfaceRises) {
  coupler::Hello hello = square_box();
  hello.continuum.gravity[1] = -9.81;
  const double rest_speed =
      coupler::kRestSpeed * std::sqrt(9.81 * hello.continuum.grain_diameter), weight = hello.continuum.grain_weight;
  coupler::OracleSettings oracle;
  oracle.continuum_depth = 1.5 * kCell;
  oracle.band = 0.8 * kCell;
  const double packed = 0.8 * kSolidContent;

  struct Outcome {
    std::vector<std::int8_t> before, after;
  };
  auto run = [&](bool hold, double speed) {
    oracle.rest_hold = hold ? 1 : 0;
    mpm::CoupledContinuum<2> continuum(hello);
    const auto& grid = static_cast<const coupler::GridGeometry<2>&>(continuum.solver().grid());
    auto cell_at = [&](int i, int j) {
      return coupler::cell_index<2>(grid, coupler::cell_of<2>(grid, kCell * Eigen::Vector2d(i + 0.5, j + 0.5)));
    };
    // the bed: 8 rows of grains at rest across the box, zoned by the oracle from scratch
    Rezone bed;
    for (int i = 0; i < kCells; ++i)
      for (int j = 0; j < 8; ++j) add_grains(bed, grid, cell_at(i, j), packed);
    std::vector<coupler::GrainSums<2>> sums;  // of the cells the rezone moves
    for (const auto& plan : continuum.plan_rezone(0.0, coupler::kZonesInitial, {}, oracle, {}, {bed.volumes}))
      sums.push_back(bed.sums.at(plan.cell));
    continuum.complete_rezone({sums});
    Outcome out{continuum.zones(), {}};
    // two rows poured on top; every cell's grains (the hybrid ones at their weight) move at `speed`
    std::vector<coupler::CellGrains> now;
    for (int i = 0; i < kCells; ++i)
      for (int j = 0; j < 10; ++j) {
        const std::uint64_t c = cell_at(i, j);
        const int zone = out.before[c];
        if (zone == coupler::kContinuum) continue;
        const double carried = (zone == coupler::kHybrid ? weight : 1.0) * packed;
        now.push_back({c, packed / kGrainDensity, carried, 0.5 * carried * speed * speed});
      }
    continuum.plan_rezone(0.0, coupler::kZonesOracle, {}, oracle, {}, {now});
    out.after = continuum.zones();
    continuum.complete_rezone({});
    return out;
  };
  auto changed = [](const Outcome& o) {
    int n = 0;
    for (std::size_t c = 0; c < o.before.size(); ++c) {
      if (o.after[c] == o.before[c]) continue;
      EXPECT_GT(o.after[c], o.before[c]) << "cell " << c << ": a rising surface moves zones towards continuum";
      ++n;
    }
    return n;
  };
  const Outcome free = run(false, 0.0);
  ASSERT_GT(std::count(free.before.begin(), free.before.end(), coupler::kContinuum), 0) << "the bed has a continuum";
  const int asked = changed(free);
  ASSERT_GT(asked, 0) << "without the hold the risen surface changes zones";
  EXPECT_EQ(changed(run(true, 0.0)), 0) << "at rest every zone is held";
  EXPECT_EQ(changed(run(true, 0.5 * rest_speed)), 0) << "below the rest speed";
  const Outcome moving = run(true, 10 * rest_speed);
  EXPECT_EQ(changed(moving), asked) << "moving material is not held";
  EXPECT_EQ(moving.after, free.after);
}

}  // namespace

// pic regime: each node's share of the field rule (NodeUpdate::field_share) from the flow regime of
// the points around it, at the agreement's rate. A block of continuum at rest answers the share the
// agreement closes over the interval T, 1 - exp(-T / agreement_time) (1 with agreement_time 0), at
// every node its points reach, corner nodes included (the points within a stencil of them); a node
// beyond their reach answers 0; the same block in simple shear without pressure (free: I infinite)
// answers 0, and so does the block sliding without shear (I = 0, but not still: without gravity
// the rest speed is 0).
TEST(CoupledRezone, FieldSharesFollowTheFlowRegimeOfThePoints) {
  constexpr double kInterval = 1e-5;  // s, between the exchanges below
  for (const double agreement_time : {0.0, 4 * kInterval})
  for (const auto& [shear, slide] : {std::pair{0.0, 0.0}, std::pair{20.0, 0.0}, std::pair{0.0, 0.05}}) {
    coupler::Hello hello = square_box();
    hello.continuum.agreement_time = agreement_time;
    mpm::CoupledContinuum<2> continuum(hello);
    const auto& grid = static_cast<const coupler::GridGeometry<2>&>(continuum.solver().grid());
    continuum_block(continuum, 0.8 * kSolidContent,
                    [&, shear = shear, slide = slide](int j) { return Eigen::Vector2d(slide + shear * kCell * (j - 5.5), 0.0); });
    auto node_at = [&](double x, double y) { return node_nearest(grid, x, y); };
    // the centre, the lower corner, the upper corner (reached only by the corner points' stencils,
    // at their far end), and a node two cells out of the block
    const std::vector<std::uint64_t> nodes = {node_at(0.06, 0.06), node_at(0.03, 0.03), node_at(0.10, 0.10),
                                              node_at(0.01, 0.01)};
    std::vector<coupler::NodeRecord> records;
    for (std::uint64_t k : nodes) records.push_back({k, 1e-6, {0, 0, 0}});
    std::vector<std::vector<coupler::NodeUpdate>> replies;
    for (int step = 1; step <= 2; ++step) {  // the second step's points carry the shear in their gradient
      continuum.advance_to(step * kInterval);
      replies = continuum.agree({records}, true);
      continuum.complete_step();
    }
    const double closing = agreement_time > 0 ? 1.0 - std::exp(-kInterval / agreement_time) : 1.0;
    const double inside = shear > 0 || slide > 0 ? 0.0 : closing;
    for (int n = 0; n < 3; ++n)  // the block's centre, its corners
      EXPECT_NEAR(replies[0][n].field_share, inside, 1e-15) << "node " << n << ", shear " << shear << ", slide "
                                                           << slide << ", agreement time " << agreement_time;
    EXPECT_EQ(replies[0][3].field_share, 0.0) << "shear " << shear << ", slide " << slide
                                              << ", agreement time " << agreement_time;
    // the run's tally, by the grains' mass at the nodes over both exchanges: at rest, three of the
    // four equal nodes take the field rule whole and the one out of reach none; sliding, none does
    const auto& tally = continuum.field_rule_tally();
    EXPECT_NEAR(tally.mass, 2 * 4 * 1e-6, 1e-18);
    if (shear > 0) continue;  // its first exchange's points carry no shear yet
    const double whole = slide > 0 ? 0.0 : 0.75;
    EXPECT_NEAR(tally.quasi_static / tally.mass, whole, 1e-12) << "slide " << slide;
    EXPECT_NEAR(tally.flowing / tally.mass, 1 - whole, 1e-12) << "slide " << slide;
    EXPECT_NEAR(tally.share / tally.mass, whole, 1e-12) << "slide " << slide;
    EXPECT_NEAR(tally.applied / tally.mass, whole * closing, 1e-12) << "slide " << slide;
  }
}

// The fill pressure (docs/design.md section 5.4): a node whose points and coupled grains hold
// more than the packing's mass pushes its points apart, by an isotropic stress whose forces on
// the nodes sum to zero, so the continuum's momentum stays what it was to round-off. A node at
// the packing, or one whose grains leave it below, pushes nothing; with fill 0 nothing moves.
TEST(CoupledFill, AnOverfullNodePushesItsPointsApartWithMomentumExact) {
  constexpr double kInterval = 1e-5, kPacking = 0.8;
  EXPECT_EQ(coupler::fill_pressure(1.0, 1.0, 1e5), 0.0);
  EXPECT_EQ(coupler::fill_pressure(0.9, 1.0, 1e5), 0.0);
  EXPECT_DOUBLE_EQ(coupler::fill_pressure(1.2, 1.0, 1e5), 2e4);
  for (const double fill : {0.0, 0.1}) {
    coupler::Hello hello = square_box();
    hello.continuum.fill_share = fill;
    hello.continuum.packing_fraction = kPacking;
    mpm::CoupledContinuum<2> continuum(hello);
    const auto& grid = static_cast<const coupler::GridGeometry<2>&>(continuum.solver().grid());
    // a block of points at the packing, at rest
    continuum_block(continuum, kPacking * kSolidContent, [](int) { return Eigen::Vector2d::Zero().eval(); });
    auto node_at = [&](double x, double y) { return node_nearest(grid, x, y); };
    const double full = kPacking * kSolidContent;
    // grains at rest on the block's centre node (a fifth over the packing with the points) and on a
    // node of its edge, whose points hold half a node: that one stays below the packing
    const std::vector<coupler::NodeRecord> records = {{node_at(0.06, 0.06), 0.2 * full, {0, 0, 0}},
                                                      {node_at(0.03, 0.06), 0.2 * full, {0, 0, 0}}};
    continuum.advance_to(kInterval);
    // the overlap the exchange reports, measured with or without the pressure: the centre node's
    // points and grains hold 0.2 full above the packing, the edge node's nothing
    const std::vector<double> node_mass = {continuum.solver().grid().mass[records[0].node],
                                           continuum.solver().grid().mass[records[1].node]};
    ASSERT_NEAR(node_mass[0], full, 1e-12 * full) << "the block's interior node holds a packed node's mass";
    ASSERT_LT(node_mass[1] + 0.2 * full, full) << "the edge node stays below the packing";
    continuum.agree({records});
    EXPECT_NEAR(continuum.grid_totals(1).overlap, (node_mass[0] + 0.2 * full - full) / (node_mass[0] + node_mass[1] + 0.4 * full),
                1e-12) << "fill " << fill;
    continuum.complete_step();
    const auto& pts = continuum.solver().points();
    const Eigen::Vector2d centre(0.06, 0.06), edge(0.03, 0.06);
    const double modulus = fill * continuum.solver().materials().front().bulk_modulus<2>();
    double at_centre = 0, at_edge = 0;
    for (std::size_t p = 0; p < pts.size(); ++p) {
      EXPECT_GE(pts.fill_pressure[p], 0.0);
      if ((pts.x[p] - centre).norm() < 0.4 * kCell) at_centre = std::max(at_centre, pts.fill_pressure[p]);
      if ((pts.x[p] - edge).norm() < 0.4 * kCell) at_edge = std::max(at_edge, pts.fill_pressure[p]);
    }
    // a point a quarter cell from the node on each axis has weight N(1/4)^2 = (3/4 - 1/16)^2 there
    EXPECT_NEAR(at_centre, 0.6875 * 0.6875 * 0.2 * modulus, 1e-9 * (1 + modulus)) << "fill " << fill;
    EXPECT_EQ(at_edge, 0.0) << "fill " << fill;
    // the next substep's P2G and grid update carry the pressure's forces to the nodes
    continuum.advance_to(2 * kInterval);
    const auto& g = continuum.solver().grid();
    Eigen::Vector2d momentum = Eigen::Vector2d::Zero();
    double outward = 0, scale = 0;
    for (std::size_t k = 0; k < g.num_nodes(); ++k) {
      if (!(g.mass[k] > 0)) continue;
      const Eigen::Vector2d x = g.node_position(g.node_of(k));
      momentum += g.mass[k] * g.momentum[k];  // a velocity after the grid update
      outward += g.mass[k] * g.momentum[k].dot(x - centre);
      scale += g.mass[k] * g.momentum[k].norm();
    }
    if (fill == 0) {
      EXPECT_EQ(scale, 0.0) << "no fill pressure: the points at rest stay at rest";
    } else {
      EXPECT_GT(outward, 0.0) << "the overfull node pushes its points apart";
      EXPECT_GT(scale, 0.0);
      EXPECT_LT(momentum.norm(), 1e-12 * scale) << "the fill pressure moves no momentum";
    }
    // its G2P spreads the points: the work it did there (fix vector entry 35)
    continuum.agree({records});
    continuum.complete_step();
    const double work = continuum.grid_totals(2).energy_fill;
    if (fill == 0) EXPECT_EQ(work, 0.0);
    else EXPECT_GT(work, 0.0) << "the pressure did work on the points it pushed apart";
  }
}
