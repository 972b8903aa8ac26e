// The zone oracle: packing fraction from grains, exact signed distance to the free surface
// and walls, and zones with the hybrid band as hysteresis.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>

#include "coupler/oracle.hpp"

namespace {

constexpr double kPi = 3.14159265358979323846;

template <int D>
using Vec = Eigen::Matrix<double, D, 1>;
template <int D>
using IVec = Eigen::Matrix<int, D, 1>;

/// Grid from the origin 0 with `cells` cells per axis.
template <int D>
coupler::GridGeometry<D> grid_of(const IVec<D>& cells, double dx) {
  coupler::GridGeometry<D> g;
  g.dx = dx;
  g.origin.setZero();
  g.dims = cells.array() + 1;
  return g;
}

/// Centres of a simple cubic lattice of touching grains of radius r filling [0, extent).
template <int D>
std::vector<Vec<D>> lattice(const Vec<D>& extent, double r) {
  IVec<D> n;
  for (int a = 0; a < D; ++a) n[a] = static_cast<int>(std::lround(extent[a] / (2 * r)));
  std::vector<Vec<D>> x;
  const int total = n.prod();
  for (int k = 0; k < total; ++k) {
    Vec<D> p;
    for (int a = D - 1, j = k; a >= 0; j /= n[a], --a) p[a] = ((j % n[a]) + 0.5) * 2 * r;
    x.push_back(p);
  }
  return x;
}

// ------------------------------------------------------------------------------ packing

template <int D>
void check_lattice_packing(double expected) {
  const double r = 0.01, dx = 0.04;  // 2 grains per cell per axis
  IVec<D> cells;
  for (int a = 0; a < D; ++a) cells[a] = 3 + a;
  const auto grid = grid_of<D>(cells, dx);
  const Vec<D> extent = dx * cells.template cast<double>();
  const auto x = lattice<D>(extent, r);
  ASSERT_EQ(x.size(), static_cast<std::size_t>(cells.prod() * (1 << D)));
  const std::vector<double> radius(x.size(), r);

  std::vector<double> volume;
  coupler::add_grain_volumes<D>(grid, x, radius, volume);
  const auto phi = coupler::packing_fraction<D>(grid, volume, {});
  ASSERT_EQ(phi.size(), coupler::num_cells(grid));
  for (double p : phi) EXPECT_NEAR(p, expected, 1e-12);

  // Two "ranks" each hold every other grain; their partial sums add up to the single sum.
  std::vector<double> rank0, rank1;
  for (std::size_t i = 0; i < x.size(); ++i)
    coupler::add_grain_volume<D>(grid, x[i], coupler::grain_volume<D>(r), i % 2 ? rank1 : rank0);
  for (std::size_t c = 0; c < volume.size(); ++c) {
    EXPECT_GT(rank0[c], 0);
    EXPECT_GT(rank1[c], 0);
    EXPECT_NEAR(rank0[c] + rank1[c], volume[c], 1e-14 * volume[c]);
  }
}

TEST(coupler_oracle, PackingOfSquareLatticeOfDisksIsPiOver4) { check_lattice_packing<2>(kPi / 4); }
TEST(coupler_oracle, PackingOfCubicLatticeOfSpheresIsPiOver6) { check_lattice_packing<3>(kPi / 6); }

TEST(coupler_oracle, PackingIsOneWithPointsAndClampedAndSkipsGrainsOffGrid) {
  const auto grid = grid_of<2>(IVec<2>(3, 2), 0.1);
  std::vector<double> volume;
  EXPECT_TRUE(coupler::add_grain_volume<2>(grid, Vec<2>(0.05, 0.05), 0.5 * 0.01, volume));  // phi 0.5
  EXPECT_TRUE(coupler::add_grain_volume<2>(grid, Vec<2>(0.15, 0.05), 3 * 0.01, volume));    // phi 3 -> 1
  EXPECT_FALSE(coupler::add_grain_volume<2>(grid, Vec<2>(0.35, 0.05), 0.01, volume));       // off grid
  EXPECT_FALSE(coupler::add_grain_volume<2>(grid, Vec<2>(0.05, -0.01), 0.01, volume));
  std::vector<std::uint8_t> points;
  coupler::mark_point_cell<2>(grid, Vec<2>(0.25, 0.15), points);
  const auto phi = coupler::packing_fraction<2>(grid, volume, points);
  const auto at = [&](int i, int j) { return phi[coupler::cell_index(grid, IVec<2>(i, j))]; };
  EXPECT_NEAR(at(0, 0), 0.5, 1e-12);
  EXPECT_EQ(at(1, 0), 1.0);
  EXPECT_EQ(at(2, 0), 0.0);
  EXPECT_EQ(at(2, 1), 1.0);
  EXPECT_EQ(at(0, 1), 0.0);
}

// ------------------------------------------------------------------------------ distance

template <int D>
void check_edt_against_brute_force(const IVec<D>& cells, double density, unsigned seed) {
  std::mt19937 rng(seed);
  std::bernoulli_distribution pick(density);
  const auto grid = grid_of<D>(cells, 1.0);
  const std::size_t n = coupler::num_cells(grid);
  std::vector<std::uint8_t> source(n);
  for (auto& s : source) s = pick(rng);
  const auto d2 = coupler::squared_distance_transform<D>(cells, source);
  for (std::size_t c = 0; c < n; ++c) {
    double best = std::numeric_limits<double>::infinity();
    const IVec<D> i = coupler::cell_coords(grid, c);
    for (std::size_t s = 0; s < n; ++s)
      if (source[s]) best = std::min(best, double((coupler::cell_coords(grid, s) - i).squaredNorm()));
    ASSERT_EQ(d2[c], best) << "cell " << i.transpose();
  }
}

TEST(coupler_oracle, DistanceTransformIsExactAgainstBruteForce2D) {
  check_edt_against_brute_force<2>(IVec<2>(13, 17), 0.05, 1);
  check_edt_against_brute_force<2>(IVec<2>(17, 13), 0.3, 2);
  check_edt_against_brute_force<2>(IVec<2>(9, 11), 0.0, 3);  // no source: all +inf
}

TEST(coupler_oracle, DistanceTransformIsExactAgainstBruteForce3D) {
  check_edt_against_brute_force<3>(IVec<3>(7, 9, 11), 0.03, 4);
  check_edt_against_brute_force<3>(IVec<3>(11, 6, 8), 0.2, 5);
}

/// The surface sits half way between centres: the error is >= -dx/2 (no outside centre is nearer
/// than the true surface for these convex shapes), and reaches it when a centre lies on the surface.
constexpr double kHalfCell = 0.5 + 1e-9;

/// Signed distance of the mask {phi_true(centre) > 0}, compared with phi_true at every cell whose
/// centre lies at least |phi_true| + margin inside the grid (so the grid edge does not cut off the
/// nearest surface point). Returns the largest error in cells.
template <int D, class TrueDistance>
double max_distance_error(const coupler::GridGeometry<D>& grid, TrueDistance&& exact) {
  const std::size_t n = coupler::num_cells(grid);
  std::vector<std::uint8_t> material(n);
  for (std::size_t c = 0; c < n; ++c)
    material[c] = exact(coupler::cell_center(grid, coupler::cell_coords(grid, c))) > 0;
  const auto d = coupler::signed_distance<D>(grid, material, {});
  const Vec<D> upper = grid.node_position(grid.dims.array() - 1);
  double worst = 0;
  int checked = 0;
  for (std::size_t c = 0; c < n; ++c) {
    const Vec<D> x = coupler::cell_center(grid, coupler::cell_coords(grid, c));
    const double want = exact(x);
    const double room = std::min((x - grid.origin).minCoeff(), (upper - x).minCoeff());
    if (room < std::abs(want) + 2 * grid.dx) continue;
    EXPECT_EQ(d[c] > 0, material[c] != 0);  // sign convention: positive inside
    worst = std::max(worst, std::abs(d[c] - want) / grid.dx);
    ++checked;
  }
  EXPECT_GT(checked, 100);  // enough cells away from the grid edge
  return worst;
}

TEST(coupler_oracle, SignedDistanceOfHalfSpaceIsDistanceToPlane) {
  // Axis-aligned planes (inside below): within half a cell, and exact when the plane is on faces.
  const auto g2 = grid_of<2>(IVec<2>(21, 31), 0.1);
  EXPECT_LE(max_distance_error<2>(g2, [](const Vec<2>& x) { return 1.234 - x[1]; }), kHalfCell);
  EXPECT_LE(max_distance_error<2>(g2, [](const Vec<2>& x) { return 1.2 - x[1]; }), 1e-9);
  const auto g3 = grid_of<3>(IVec<3>(19, 13, 15), 0.1);
  EXPECT_LE(max_distance_error<3>(g3, [](const Vec<3>& x) { return 0.987 - x[0]; }), kHalfCell);
  EXPECT_LE(max_distance_error<3>(g3, [](const Vec<3>& x) { return x[2] - 0.7; }), 1e-9);
  // Tilted planes.
  const Vec<2> n2 = Vec<2>(0.3, 0.8).normalized();
  EXPECT_LE(max_distance_error<2>(g2, [&](const Vec<2>& x) { return 1.71 - n2.dot(x); }), kHalfCell);
  const Vec<3> n3 = Vec<3>(0.3, 0.8, 0.5).normalized();
  EXPECT_LE(max_distance_error<3>(g3, [&](const Vec<3>& x) { return 1.13 - n3.dot(x); }), kHalfCell);
}

TEST(coupler_oracle, SignedDistanceOfDiskAndBallIsRMinusR) {
  const auto g2 = grid_of<2>(IVec<2>(40, 36), 0.05);
  const Vec<2> c2(1.013, 0.891);
  EXPECT_LE(max_distance_error<2>(g2, [&](const Vec<2>& x) { return 0.61 - (x - c2).norm(); }), kHalfCell);
  const auto g3 = grid_of<3>(IVec<3>(22, 24, 20), 0.05);
  const Vec<3> c3(0.551, 0.598, 0.493);
  EXPECT_LE(max_distance_error<3>(g3, [&](const Vec<3>& x) { return 0.37 - (x - c3).norm(); }), kHalfCell);
}

TEST(coupler_oracle, WallsAreSurfacesThroughBoundaryCells) {
  // All material: the distance is the one to the nearest wall of the box (exact: walls on faces).
  const Vec<3> lower(0, 0, 0), upper(1.0, 0.8, 0.6);
  const auto grid = coupler::padded_grid<3>(lower, upper, 0.1);
  const std::size_t n = coupler::num_cells(grid);
  const auto walls = coupler::cells_outside_box<3>(grid, lower, upper);
  const std::vector<std::uint8_t> material(n, 1);
  const auto d = coupler::signed_distance<3>(grid, material, walls);
  for (std::size_t c = 0; c < n; ++c) {
    const Vec<3> x = coupler::cell_center(grid, coupler::cell_coords(grid, c));
    if (walls[c]) {
      EXPECT_LT(d[c], 0);
      continue;
    }
    EXPECT_NEAR(d[c], std::min((x - lower).minCoeff(), (upper - x).minCoeff()), 1e-9);
  }
  // Without boundary cells there is no surface at all.
  for (double v : coupler::signed_distance<3>(grid, material, {}))
    EXPECT_EQ(v, std::numeric_limits<double>::infinity());
}

// ------------------------------------------------------------------------------ zones

coupler::OracleSettings band_settings() {
  coupler::OracleSettings s;
  s.continuum_depth = 0.3;  // lo = 0.2, hi = 0.4
  s.band = 0.1;
  return s;
}

/// Column: material in the lower half (last axis) of the box, walls as surfaces. 2D from a grain
/// lattice (phi = pi/4), 3D from material points. Checks the zones after one and two updates.
template <int D>
void check_column(bool from_grains) {
  const double dx = 0.1;
  Vec<D> lower = Vec<D>::Zero(), upper;
  for (int a = 0; a < D; ++a) upper[a] = 1.2 + 0.2 * a;
  upper[D - 1] = 2.0;  // top at 1: the floor is deeper than L + h below the spot checks
  const double top = upper[D - 1] / 2;
  const auto grid = coupler::padded_grid<D>(lower, upper, dx);
  const std::size_t n = coupler::num_cells(grid);

  std::vector<double> volume;
  std::vector<std::uint8_t> points;
  Vec<D> extent = upper;
  extent[D - 1] = top;
  if (from_grains) {
    const auto x = lattice<D>(extent, dx / 4);
    coupler::add_grain_volumes<D>(grid, x, std::vector<double>(x.size(), dx / 4), volume);
  } else {
    for (std::size_t c = 0; c < n; ++c) {
      const Vec<D> x = coupler::cell_center(grid, coupler::cell_coords(grid, c));
      if ((x.array() > lower.array()).all() && (x.array() < extent.array()).all())
        coupler::mark_point_cell<D>(grid, x, points);
    }
  }
  const auto walls = coupler::cells_outside_box<D>(grid, lower, upper);
  const auto s = band_settings();

  const auto first = coupler::run_oracle<D>(grid, volume, points, walls, {}, {}, s);
  EXPECT_EQ(coupler::zone_counts(first.zones)[coupler::kContinuum], 0u);  // needs a hybrid step first
  EXPECT_GT(coupler::zone_counts(first.zones)[coupler::kHybrid], 0u);
  const auto second = coupler::run_oracle<D>(grid, volume, points, walls, first.zones, {}, s);

  std::array<std::size_t, 3> seen{0, 0, 0};
  for (std::size_t c = 0; c < n; ++c) {
    const Vec<D> x = coupler::cell_center(grid, coupler::cell_coords(grid, c));
    const bool inside = (x.array() > lower.array()).all() && (x.array() < extent.array()).all();
    // Depth below the free top or from the nearest wall; distances are (k + 1/2) dx, away from lo/hi.
    const double depth = std::min({top - x[D - 1], (x - lower).minCoeff(), (upper - x).minCoeff()});
    int want = coupler::kDiscrete;
    if (inside) {
      EXPECT_NEAR(second.distance[c], depth, 1e-9);
      if (depth > 0.4) want = coupler::kContinuum;
      else if (depth >= 0.2) want = coupler::kHybrid;
    } else {
      EXPECT_LT(second.distance[c], 0);
    }
    EXPECT_EQ(second.zones[c], want) << "cell at " << x.transpose() << " depth " << depth;
    ++seen[want];
  }
  for (auto k : seen) EXPECT_GT(k, 0u);

  // Spot checks on the vertical centre line: the top layers are discrete, then hybrid, then continuum.
  Vec<D> x = (lower + upper) / 2;
  const auto zone_at = [&](double height) {
    x[D - 1] = height;
    return second.zones[coupler::cell_index(grid, coupler::cell_of(grid, x))];
  };
  EXPECT_EQ(zone_at(top - 0.05), coupler::kDiscrete);
  EXPECT_EQ(zone_at(top - 0.15), coupler::kDiscrete);
  EXPECT_EQ(zone_at(top - 0.25), coupler::kHybrid);
  EXPECT_EQ(zone_at(top - 0.35), coupler::kHybrid);
  EXPECT_EQ(zone_at(top - 0.45), coupler::kContinuum);
  EXPECT_EQ(zone_at(top + 0.05), coupler::kDiscrete);
}

TEST(coupler_oracle, ColumnIsDiscreteNearTopAndWallsAndContinuumDeepInside2D) { check_column<2>(true); }
TEST(coupler_oracle, ColumnIsDiscreteNearTopAndWallsAndContinuumDeepInside3D) { check_column<3>(false); }

// ------------------------------------------------------------------------------ touched faces

TEST(coupler_oracle, BoxCellsSplitTouchedFromSurfaceFaces) {
  const Vec<2> lower(0, 0), upper(1.0, 0.6);
  const auto grid = coupler::padded_grid<2>(lower, upper, 0.1);
  const auto floor_touched = coupler::box_cells<2>(grid, lower, upper, coupler::face_bit(1, 0));
  const auto untouched = coupler::box_cells<2>(grid, lower, upper, 0);
  EXPECT_EQ(untouched.boundary, coupler::cells_outside_box<2>(grid, lower, upper));
  EXPECT_EQ(std::count(untouched.solid.begin(), untouched.solid.end(), 1), 0);
  const auto at = [&](const coupler::BoxCells& b, double x, double y) {
    const std::size_t c = coupler::cell_index(grid, coupler::cell_of(grid, Vec<2>(x, y)));
    return std::array<int, 2>{b.boundary[c], b.solid[c]};
  };
  using Kind = std::array<int, 2>;
  EXPECT_EQ(at(floor_touched, 0.55, 0.25), (Kind{0, 0}));    // inside
  EXPECT_EQ(at(floor_touched, 0.55, -0.05), (Kind{0, 1}));   // below the touched floor: solid
  EXPECT_EQ(at(floor_touched, 0.55, -0.25), (Kind{0, 1}));
  EXPECT_EQ(at(floor_touched, -0.05, 0.25), (Kind{1, 0}));   // beyond the untouched side wall
  EXPECT_EQ(at(floor_touched, -0.05, -0.05), (Kind{1, 0}));  // the corner: the untouched face wins
  EXPECT_EQ(at(floor_touched, 0.55, 0.65), (Kind{1, 0}));    // above the untouched top
  EXPECT_EQ(at(untouched, 0.55, -0.05), (Kind{1, 0}));

  // 3D: the z faces are bits 4 and 5; touching every face leaves no boundary cell at all
  const Vec<3> lo3(0, 0, 0), hi3(0.4, 0.3, 0.5);
  const auto g3 = coupler::padded_grid<3>(lo3, hi3, 0.1);
  const auto zlo = coupler::box_cells<3>(g3, lo3, hi3, coupler::face_bit(2, 0));
  const auto at3 = [&](const coupler::BoxCells& b, const Vec<3>& x) {
    const std::size_t c = coupler::cell_index(g3, coupler::cell_of(g3, x));
    return Kind{b.boundary[c], b.solid[c]};
  };
  EXPECT_EQ(at3(zlo, Vec<3>(0.15, 0.15, -0.05)), (Kind{0, 1}));
  EXPECT_EQ(at3(zlo, Vec<3>(0.15, 0.15, 0.55)), (Kind{1, 0}));
  EXPECT_EQ(at3(zlo, Vec<3>(0.15, -0.05, -0.05)), (Kind{1, 0}));
  const auto all = coupler::box_cells<3>(g3, lo3, hi3, 0x3f);
  EXPECT_EQ(std::count(all.boundary.begin(), all.boundary.end(), 1), 0);
  EXPECT_EQ(static_cast<std::size_t>(std::count(all.solid.begin(), all.solid.end(), 1)),
            coupler::num_cells(g3) - 4 * 3 * 5);
}

/// A box of material (points in every cell of x in [0, 3], y in [0, 1.2]) in a container
/// [0, 3] x [0, 2], the oracle run to its fixed point, with the floor (ylo) touched or not and
/// optionally a discrete region (an orifice column) over x in [1.4, 1.6], y < 0.4, the cells below
/// the floor too. Depth 0.3, band 0.1: continuum where the distance exceeds 0.4 (below the free
/// top: surface_depth + 0.1 where surface_depth > 0).
struct TouchedFloor {
  coupler::GridGeometry<2> grid;
  coupler::OracleResult result;
  std::vector<std::uint8_t> region;
  std::int8_t zone_at(double x, double y) const {
    return result.zones[coupler::cell_index(grid, coupler::cell_of(grid, Vec<2>(x, y)))];
  }
};

TouchedFloor touched_floor(bool touched, bool orifice, double top = 1.2, double surface_depth = 0) {
  TouchedFloor t;
  const Vec<2> lower(0, 0), upper(3.0, 2.0);
  t.grid = coupler::padded_grid<2>(lower, upper, 0.1);
  const std::size_t n = coupler::num_cells(t.grid);
  std::vector<std::uint8_t> points;
  t.region.assign(n, 0);
  for (std::size_t c = 0; c < n; ++c) {
    const Vec<2> x = coupler::cell_center(t.grid, coupler::cell_coords(t.grid, c));
    if ((x.array() > lower.array()).all() && x[0] < upper[0] && x[1] < top) coupler::mark_point_cell<2>(t.grid, x, points);
    t.region[c] = orifice && x[0] > 1.4 && x[0] < 1.6 && x[1] < 0.4;
  }
  coupler::BoxCells box = coupler::box_cells<2>(t.grid, lower, upper, touched ? coupler::face_bit(1, 0) : 0u);
  for (std::size_t c = 0; c < n; ++c)
    if (t.region[c]) box.add_boundary(c);
  auto s = band_settings();
  s.surface_depth = surface_depth;
  std::vector<std::int8_t> zones;
  for (int k = 0; k < 4; ++k) {
    t.result = coupler::run_oracle<2>(t.grid, {}, points, box.boundary, zones, {}, s, box.solid);
    zones = t.result.zones;
  }
  // solid cells never hold anything: always discrete, and no distance for the zones
  for (std::size_t c = 0; c < n; ++c)
    if (box.solid[c]) {
      EXPECT_EQ(t.result.zones[c], coupler::kDiscrete);
      EXPECT_LT(t.result.distance[c], 0);
    }
  return t;
}

TEST(coupler_oracle, ContinuumReachesTouchedFloorAndStaysAwayFromUntouchedOne) {
  const double hi = 0.4;  // depth + band
  for (bool touched : {false, true}) {
    const TouchedFloor t = touched_floor(touched, false);
    double lowest = 1e9;
    std::size_t continuum = 0;
    for (std::size_t c = 0; c < t.result.zones.size(); ++c) {
      if (t.result.zones[c] != coupler::kContinuum) continue;
      const Vec<2> x = coupler::cell_center(t.grid, coupler::cell_coords(t.grid, c));
      lowest = std::min(lowest, x[1]);
      ++continuum;
      // the other faces and the free top stay surfaces
      EXPECT_GT(std::min({x[0], 3.0 - x[0], 1.2 - x[1]}), hi) << "touched " << touched << " at " << x.transpose();
    }
    if (touched) {
      EXPECT_NEAR(lowest, 0.05, 1e-9);  // the floor row
      EXPECT_EQ(t.zone_at(1.5, 0.05), coupler::kContinuum);
      EXPECT_EQ(t.zone_at(0.45, 0.05), coupler::kContinuum);
      EXPECT_EQ(t.zone_at(0.35, 0.05), coupler::kHybrid);  // still away from the untouched side wall
      EXPECT_NEAR(t.result.distance[coupler::cell_index(t.grid, coupler::cell_of(t.grid, Vec<2>(1.5, 0.05)))],
                  1.15, 1e-9);  // to the free top, not to the floor
    } else {
      EXPECT_NEAR(lowest, 0.45, 1e-9);  // depth + band above the floor
      EXPECT_EQ(t.zone_at(1.5, 0.05), coupler::kDiscrete);
      EXPECT_EQ(t.zone_at(1.5, 0.25), coupler::kHybrid);
    }
    EXPECT_EQ(continuum, touched ? 22u * 8u : 22u * 4u);  // x in (0.4, 2.6), y up to 0.8
  }
}

TEST(coupler_oracle, DiscreteRegionOverTouchedFloorStillKeepsContinuumAway) {
  const TouchedFloor t = touched_floor(true, true);
  std::size_t floor_continuum = 0;
  for (std::size_t c = 0; c < t.result.zones.size(); ++c) {
    const Vec<2> x = coupler::cell_center(t.grid, coupler::cell_coords(t.grid, c));
    if (t.region[c]) EXPECT_EQ(t.result.zones[c], coupler::kDiscrete);
    if (t.result.zones[c] != coupler::kContinuum) continue;
    // nearest region cell centre, minus half a cell: more than depth + band
    double nearest = 1e9;
    for (std::size_t r = 0; r < t.region.size(); ++r)
      if (t.region[r])
        nearest = std::min(nearest, (coupler::cell_center(t.grid, coupler::cell_coords(t.grid, r)) - x).norm());
    EXPECT_GT(nearest - 0.05, 0.4) << "continuum cell at " << x.transpose();
    floor_continuum += x[1] < 0.1;
  }
  EXPECT_GT(floor_continuum, 10u);  // away from the orifice the floor row is still continuum
  EXPECT_EQ(t.zone_at(1.5, 0.05), coupler::kDiscrete);
  EXPECT_EQ(t.zone_at(1.25, 0.05), coupler::kDiscrete);  // 0.15 from the region
  EXPECT_EQ(t.zone_at(1.15, 0.05), coupler::kHybrid);    // 0.25
  EXPECT_EQ(t.zone_at(1.5, -0.05), coupler::kDiscrete);  // the region below the floor: a boundary
  EXPECT_LT(t.result.distance[coupler::cell_index(t.grid, coupler::cell_of(t.grid, Vec<2>(1.5, -0.05)))], 0);
  EXPECT_EQ(t.zone_at(0.85, 0.05), coupler::kContinuum);
}

TEST(coupler_oracle, SurfaceDepthMovesTheContinuumUnderAFreeSurfaceOnly) {
  // surface_depth equal to the depth is the default, to the last bit
  const TouchedFloor same = touched_floor(true, true, 1.2, 0.3), plain = touched_floor(true, true);
  EXPECT_EQ(same.result.distance, plain.result.distance);
  EXPECT_EQ(same.result.zones, plain.result.zones);
  // 0.16 below the free top at 1.2 (instead of 0.3): continuum from 0.26 below it, not 0.4,
  // discrete above 0.06
  const TouchedFloor t = touched_floor(true, true, 1.2, 0.16);
  EXPECT_EQ(plain.zone_at(1.0, 0.85), coupler::kHybrid);  // 0.35 below the top
  EXPECT_EQ(t.zone_at(1.0, 0.85), coupler::kContinuum);
  EXPECT_EQ(t.zone_at(1.0, 0.95), coupler::kHybrid);      // 0.25
  EXPECT_EQ(t.zone_at(1.0, 1.15), coupler::kDiscrete);    // 0.05
  // the untouched side walls and the orifice's region keep the continuum depth + band away
  EXPECT_EQ(t.zone_at(0.35, 0.55), coupler::kHybrid);
  EXPECT_EQ(t.zone_at(0.45, 0.55), coupler::kContinuum);
  EXPECT_EQ(t.zone_at(1.25, 0.05), coupler::kDiscrete);
  EXPECT_EQ(t.zone_at(1.15, 0.05), coupler::kHybrid);
  for (std::size_t c = 0; c < t.result.zones.size(); ++c) {
    if (t.result.zones[c] != coupler::kContinuum) continue;
    const Vec<2> x = coupler::cell_center(t.grid, coupler::cell_coords(t.grid, c));
    EXPECT_GT(std::min(x[0], 3.0 - x[0]), 0.4) << x.transpose();
    EXPECT_GT(1.2 - x[1] - 0.05, 0.26) << x.transpose();  // the cell's distance to the top
  }
  // a deeper surface layer than the walls' margin works the other way
  const TouchedFloor deep = touched_floor(true, false, 1.2, 0.5);
  EXPECT_EQ(deep.zone_at(1.5, 0.65), coupler::kHybrid);     // 0.55 below the top, under 0.6
  EXPECT_EQ(deep.zone_at(1.5, 0.55), coupler::kContinuum);  // 0.65
}

TEST(coupler_oracle, ThinLayerOnTouchedFloorStaysDiscrete) {
  // A runout thinner than depth + band on a touched floor: its floor row lies in the band (0.25
  // below the free top) but no cell wants continuum, so it is discrete too (next_zones). The
  // solid cells below the floor lie deeper than depth + band below the top, and must not count
  // as continuum nearby.
  const TouchedFloor t = touched_floor(true, false, 0.3);
  EXPECT_EQ(coupler::zone_counts(t.result.zones)[coupler::kContinuum], 0u);
  EXPECT_EQ(coupler::zone_counts(t.result.zones)[coupler::kHybrid], 0u);
  EXPECT_EQ(t.zone_at(1.5, 0.05), coupler::kDiscrete);
}

TEST(coupler_oracle, OneUpdateFromAllDiscreteNeverYieldsContinuum) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> dist(-1, 3);
  std::vector<double> d(500);
  for (double& v : d) v = dist(rng);
  const auto s = band_settings();
  for (const auto& prev : {std::vector<std::int8_t>{}, std::vector<std::int8_t>(d.size(), coupler::kDiscrete)}) {
    const auto z = coupler::update_zones(prev, d, {}, {}, s);
    EXPECT_EQ(coupler::zone_counts(z)[coupler::kContinuum], 0u);
    for (std::size_t c = 0; c < d.size(); ++c) EXPECT_EQ(z[c], d[c] < 0.2 ? coupler::kDiscrete : coupler::kHybrid);
  }
}

TEST(coupler_oracle, ZonesNeverJumpBetweenDiscreteAndContinuum) {
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> dist(-0.5, 1.0);
  const auto s = band_settings();
  std::vector<std::int8_t> z(300, coupler::kDiscrete);
  std::vector<double> d(z.size());
  std::array<int, 3> reached{0, 0, 0};
  for (int step = 0; step < 200; ++step) {
    for (double& v : d) v = dist(rng);
    const auto next = coupler::update_zones(z, d, {}, {}, s);
    for (std::size_t c = 0; c < z.size(); ++c) {
      ASSERT_LE(std::abs(next[c] - z[c]), 1) << "cell " << c << " step " << step;
      ++reached[next[c]];
    }
    z = next;
  }
  for (int k : reached) EXPECT_GT(k, 0);
  // Continuum whose distance drops below lo: hybrid first, then discrete.
  const std::vector<double> shallow{0.1};
  auto one = coupler::update_zones({coupler::kContinuum}, shallow, {}, {}, s);
  EXPECT_EQ(one[0], coupler::kHybrid);
  EXPECT_EQ(coupler::update_zones(one, shallow, {}, {}, s)[0], coupler::kDiscrete);
}

TEST(coupler_oracle, DistanceOscillatingInsideBandKeepsZones) {
  const auto s = band_settings();
  // Cells that settled in the band (hybrid), and continuum / discrete cells outside it.
  const std::vector<std::int8_t> start{coupler::kHybrid, coupler::kHybrid, coupler::kContinuum, coupler::kDiscrete};
  const std::vector<double> a{0.21, 0.39, 0.9, -0.3}, b{0.39, 0.21, 0.41, 0.19};
  std::vector<std::int8_t> z = start;
  for (int step = 0; step < 20; ++step) {
    z = coupler::update_zones(z, step % 2 ? a : b, {}, {}, s);
    EXPECT_EQ(z, start) << "step " << step;
  }
  // A discrete cell entering the band becomes hybrid once and then stays hybrid.
  z = {coupler::kDiscrete};
  for (int step = 0; step < 10; ++step) {
    z = coupler::update_zones(z, {step % 2 ? 0.2 : 0.4}, {}, {}, s);
    EXPECT_EQ(z[0], coupler::kHybrid);
  }
}

TEST(coupler_oracle, DiluteAndShearCriteriaForceDiscrete) {
  auto s = band_settings();
  s.dilute_packing = 0.5;
  s.max_shear_rate = 10;
  const std::vector<double> deep(4, 5.0);
  const std::vector<double> phi{0.9, 0.4, 0.9, 0.5}, shear{1, 1, 11, 10};  // cells 1 dilute, 2 sheared
  std::vector<std::int8_t> z(4, coupler::kContinuum);
  z = coupler::update_zones(z, deep, phi, shear, s);
  using Z = std::vector<std::int8_t>;
  EXPECT_EQ(z, (Z{coupler::kContinuum, coupler::kHybrid, coupler::kHybrid, coupler::kContinuum}));
  z = coupler::update_zones(z, deep, phi, shear, s);
  EXPECT_EQ(z, (Z{coupler::kContinuum, coupler::kDiscrete, coupler::kDiscrete, coupler::kContinuum}));
  // Off by default: the same inputs leave everything continuum.
  z = coupler::update_zones(std::vector<std::int8_t>(4, coupler::kContinuum), deep, phi, shear, band_settings());
  EXPECT_EQ(coupler::zone_counts(z)[coupler::kContinuum], 4u);
  // Inputs a criterion needs must be given.
  EXPECT_THROW(coupler::update_zones(z, deep, {}, shear, s), std::invalid_argument);
}

}  // namespace

TEST(coupler_oracle, HybridCellsNeedAContinuumWithinTheBand) {
  // A layer of material on a floor: deep enough for continuum, hybrid cells border it; too thin
  // for any continuum, its would-be hybrid cells are discrete (their points would rest on
  // nothing but the agreement with the grains).
  const auto s = band_settings();    // L = 0.3, h = 0.1, dx = 0.1
  const auto grid = grid_of<2>(IVec<2>(20, 20), 0.1);
  const std::size_t n = coupler::num_cells(grid);
  for (const double top : {1.2, 0.75}) {
    std::vector<std::uint8_t> points(n, 0), walls(n, 0);
    for (std::size_t c = 0; c < n; ++c) {
      const Vec<2> x = coupler::cell_center(grid, coupler::cell_coords(grid, c));
      if (x[1] < top) coupler::mark_point_cell<2>(grid, x, points);
      walls[c] = x[1] < 0.1;    // the floor's row is a wall
    }
    std::vector<std::int8_t> zones;
    coupler::OracleResult r;
    for (int k = 0; k < 3; ++k) {
      r = coupler::run_oracle<2>(grid, {}, points, walls, zones, {}, s);
      zones = r.zones;
    }
    const auto count = coupler::zone_counts(zones);
    double deepest = 0;
    for (double d : r.distance) deepest = std::max(deepest, d);
    if (deepest > s.continuum_depth + s.band) {
      EXPECT_GT(count[coupler::kContinuum], 0u) << "top " << top;
      EXPECT_GT(count[coupler::kHybrid], 0u) << "top " << top;
    } else {
      EXPECT_EQ(count[coupler::kContinuum], 0u) << "top " << top;
      EXPECT_EQ(count[coupler::kHybrid], 0u) << "top " << top;
    }
  }
}

TEST(coupler_oracle, MaterialAtRestNeedsTheCellAndItsNeighboursStill) {
  const auto grid = grid_of<2>(IVec<2>(6, 6), 0.1);
  const std::size_t n = coupler::num_cells(grid);
  const double rest_speed = 0.01;
  std::vector<double> mass(n, 2.0), kinetic(n, 0.4 * 0.5 * rest_speed * rest_speed * 2.0);  // 0.4 of the limit
  const auto moving = coupler::cell_index<2>(grid, IVec<2>(3, 3));
  kinetic[moving] = 1.1 * 0.5 * rest_speed * rest_speed * 2.0;                                // just above it
  const auto empty = coupler::cell_index<2>(grid, IVec<2>(0, 0));
  mass[empty] = 0, kinetic[empty] = 0;
  const auto at_rest = coupler::material_at_rest<2>(grid, kinetic, mass, rest_speed);
  for (std::size_t c = 0; c < n; ++c) {
    const IVec<2> k = coupler::cell_coords<2>(grid, c);
    const bool near_moving = (k - IVec<2>(3, 3)).cwiseAbs().maxCoeff() <= 1;
    EXPECT_EQ(at_rest[c] != 0, !near_moving) << "cell " << k.transpose();
  }
  // without a rest speed (no gravity) nothing with material is at rest; empty cells always are
  const auto none = coupler::material_at_rest<2>(grid, kinetic, mass, 0.0);
  EXPECT_EQ(std::count(none.begin(), none.end(), std::uint8_t{1}), 0);
  EXPECT_THROW(coupler::material_at_rest<2>(grid, {}, mass, rest_speed), std::invalid_argument);
}

TEST(coupler_oracle, ZonesOfMaterialAtRestAreHeldUnlessABoundaryOrTheSurfaceClaimsThem) {
  const auto s = band_settings();  // lo = 0.2, hi = 0.4, h = 0.1
  using Z = std::vector<std::int8_t>;
  const double far = std::numeric_limits<double>::infinity();
  const auto C = coupler::kContinuum, H = coupler::kHybrid, X = coupler::kDiscrete;
  // 0 continuum -> hybrid, a flicker (within 2h of hi)     1 the same, a boundary within hi
  // 2 hybrid -> continuum                                   3 hybrid -> discrete, within 2h of lo
  // 4 the same, a boundary within lo                        5 continuum, the surface came 2.5h below hi
  // 6 hybrid, the surface came 2.5h below lo
  const Z previous{C, C, H, H, H, C, H};
  const std::vector<double> distance{0.35, 0.35, 0.5, 0.1, 0.1, 0.15, -0.05};
  const std::vector<double> boundary{far, 0.35, far, 0.25, 0.15, far, far};
  const Z oracle = coupler::update_zones(previous, distance, {}, {}, s);
  ASSERT_EQ(oracle, (Z{H, H, C, X, X, H, X}));
  Z held = oracle;
  coupler::hold_zones_at_rest(previous, std::vector<std::uint8_t>(7, 1), distance, boundary, s, held);
  EXPECT_EQ(held, (Z{C, H, H, H, X, H, X}));
  // material that moves is not held
  Z moving = oracle;
  coupler::hold_zones_at_rest(previous, std::vector<std::uint8_t>(7, 0), distance, boundary, s, moving);
  EXPECT_EQ(moving, oracle);
  // no boundaries: only the surface limits the hold
  Z free = oracle;
  coupler::hold_zones_at_rest(previous, std::vector<std::uint8_t>(7, 1), distance, {}, s, free);
  EXPECT_EQ(free, (Z{C, C, H, H, H, H, X}));
  EXPECT_THROW(coupler::hold_zones_at_rest(previous, {1}, distance, {}, s, free), std::invalid_argument);
}

TEST(coupler_oracle, DepositAtRestKeepsItsZonesWhileTheSurfaceFlickers) {
  // A continuum cell under a free-surface cell whose packing flips across surface_packing: its
  // distance alternates across L + h (a deeper continuum cell beside it). Moving, it flickers
  // between continuum and hybrid (each return to hybrid makes grains); at rest it stays
  // continuum. A start (no previous zones) is never held.
  const auto s = band_settings();
  const auto grid = grid_of<2>(IVec<2>(2, 1), 0.1);
  const std::vector<double> deep{1.0, 0.45}, shallow{1.0, 0.35};
  for (const bool rest : {false, true}) {
    coupler::RestHold hold;
    hold.at_rest.assign(2, static_cast<std::uint8_t>(rest));
    std::vector<std::int8_t> z(2, coupler::kContinuum);
    int changes = 0;
    for (int step = 0; step < 10; ++step) {
      const auto next = coupler::next_zones<2>(grid, z, step % 2 ? deep : shallow, {}, {}, s, &hold);
      changes += next != z;
      z = next;
    }
    EXPECT_EQ(changes, rest ? 0 : 10) << (rest ? "at rest" : "moving");
  }
  coupler::RestHold hold;
  hold.at_rest.assign(2, 1);
  EXPECT_EQ(coupler::next_zones<2>(grid, {}, deep, {}, {}, s, &hold),
            std::vector<std::int8_t>(2, coupler::kHybrid));
}

// ------------------------------------------------------------------- the oracle's window

/// A random scene on a grid of `cells`: blobs of grains (some dense, some dilute) and points,
/// container faces inside the grid (random ones touched), cells of discrete regions, previous
/// zones from the whole-grid oracle on another scene (material moved away leaves zones without
/// material), random motion (some cells at rest) and shear.
template <int D>
coupler::OracleInputs<D> random_oracle_scene(const coupler::GridGeometry<D>& grid, std::mt19937& rng,
                                             const coupler::OracleSettings& s, bool with_previous) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const std::size_t n = coupler::num_cells(grid);
  const IVec<D> cells = grid.dims.array() - 1;
  auto scene = [&] {
    coupler::OracleInputs<D> in;
    in.grain_volume.assign(n, 0.0);
    in.has_points.assign(n, 0);
    // the material keeps to the middle of the grid, so that the window is smaller than it
    const int blobs = 1 + static_cast<int>(u(rng) * 3);
    for (int b = 0; b < blobs; ++b) {
      Vec<D> centre;
      for (int a = 0; a < D; ++a) centre[a] = cells[a] * (0.3 + 0.4 * u(rng));
      const double radius = 2.0 + 0.08 * cells.minCoeff() * u(rng), phi = u(rng) < 0.2 ? 0.2 : 0.5 + 0.4 * u(rng);
      const bool points = u(rng) < 0.6;
      for (std::size_t c = 0; c < n; ++c) {
        const Vec<D> x = coupler::cell_coords<D>(grid, c).template cast<double>().array() + 0.5;
        if ((x - centre).norm() > radius) continue;
        in.grain_volume[c] = phi * std::pow(grid.dx, D) * (0.8 + 0.4 * u(rng));
        if (points && (x - centre).norm() < 0.7 * radius) in.has_points[c] = 1;
      }
    }
    for (int k = 0; k < 5; ++k) {  // a few stray grains
      IVec<D> c;
      for (int a = 0; a < D; ++a) c[a] = static_cast<int>(cells[a] * (0.25 + 0.5 * u(rng)));
      in.grain_volume[coupler::cell_index<D>(grid, c)] += 0.05 * std::pow(grid.dx, D);
    }
    for (int a = 0; a < D; ++a) {
      in.container_lo[a] = grid.dx * (cells[a] * (0.1 + 0.15 * u(rng)));
      in.container_hi[a] = grid.dx * (cells[a] * (0.75 + 0.15 * u(rng)));
    }
    in.touched_faces = static_cast<std::uint32_t>(u(rng) * (1u << (2 * D)));
    const int regions = static_cast<int>(u(rng) * 3);
    for (int r = 0; r < regions; ++r) {
      const std::size_t c0 = static_cast<std::size_t>(u(rng) * n) % n;
      coupler::for_each_cell_within<D>(grid, coupler::cell_coords<D>(grid, c0), 1,
                                       [&](std::uint64_t c) { in.discrete_cells.push_back(c); });
    }
    if (s.max_shear_rate > 0) {  // as the MPM process gives it: whenever the criterion is on
      in.shear_rate.assign(n, 0.0);
      for (double& r : in.shear_rate) r = u(rng) < 0.05 ? 2.0 * s.max_shear_rate : 0.5 * s.max_shear_rate;
    }
    in.rest_speed = 0.1;
    if (u(rng) < 0.7) {
      in.kinetic.assign(n, 0.0);
      in.mass.assign(n, 0.0);
      for (std::size_t c = 0; c < n; ++c) {
        in.mass[c] = in.grain_volume[c] + in.has_points[c];
        in.kinetic[c] = in.mass[c] * (u(rng) < 0.7 ? 1e-4 : 1.0);
      }
    }
    return in;
  };
  coupler::OracleInputs<D> in = scene();
  if (with_previous) {
    coupler::OracleInputs<D> before = scene();
    before.kinetic.clear(), before.mass.clear();
    in.previous = coupler::oracle_detail::zones_on<D>(grid, before, s);
    for (int step = 0; step < 2; ++step) {  // a few updates of it, as a run makes
      before.previous = in.previous;
      in.previous = coupler::oracle_detail::zones_on<D>(grid, before, s);
    }
  }
  return in;
}

template <int D>
void check_window_gives_the_whole_grids_zones(const IVec<D>& cells, int trials) {
  const auto grid = grid_of<D>(cells, 0.1);
  const double dx = grid.dx;
  std::vector<coupler::OracleSettings> settings(5);
  settings[0].continuum_depth = 1.5 * dx, settings[0].band = dx;
  settings[1].continuum_depth = 1.5 * dx, settings[1].band = dx, settings[1].surface_depth = 3.2 * dx;
  settings[2].continuum_depth = dx, settings[2].band = 2 * dx;  // a band wider than the depth
  settings[3].continuum_depth = 3 * dx, settings[3].band = 0.6 * dx, settings[3].surface_depth = dx;
  settings[4].continuum_depth = 2 * dx, settings[4].band = dx, settings[4].dilute_packing = 0.25;
  settings[4].max_shear_rate = 1.0;
  std::mt19937 rng(20261207);
  int smaller = 0, tight_differs = 0, changed = 0;
  for (int t = 0; t < trials; ++t)
    for (const auto& s : settings) {
      const auto in = random_oracle_scene<D>(grid, rng, s, t % 4 != 0);
      const auto whole = coupler::oracle_detail::zones_on<D>(grid, in, s);
      ASSERT_EQ(coupler::oracle_zones<D>(grid, in, s), whole) << "trial " << t;
      std::vector<std::uint8_t> active(whole.size(), 0);
      for (std::size_t c = 0; c < whole.size(); ++c) active[c] = in.grain_volume[c] > 0 || in.has_points[c];
      smaller += coupler::cell_window<D>(grid, active, coupler::oracle_margin(s, dx)).cells.size() < whole.size();
      tight_differs += coupler::oracle_zones<D>(grid, in, s, 0) != whole;
      changed += !in.previous.empty() && whole != in.previous;
    }
  const int runs = trials * static_cast<int>(settings.size());
  EXPECT_GT(smaller, runs / 2) << "the scenes should leave most windows smaller than the grid";
  EXPECT_GT(tight_differs, 0) << "a window without margin should miss some zones (else this test proves nothing)";
  EXPECT_GT(changed, runs / 4);
}

TEST(coupler_oracle, WindowAroundTheMaterialGivesTheWholeGridsZones2D) {
  check_window_gives_the_whole_grids_zones<2>(IVec<2>(90, 70), 40);
}

TEST(coupler_oracle, WindowAroundTheMaterialGivesTheWholeGridsZones3D) {
  check_window_gives_the_whole_grids_zones<3>(IVec<3>(56, 48, 44), 4);
}

TEST(coupler_oracle, WindowOfNoMaterialIsEmptyAndClippedToTheGrid) {
  const auto grid = grid_of<2>(IVec<2>(10, 8), 0.1);
  std::vector<std::uint8_t> active(80, 0);
  EXPECT_TRUE(coupler::cell_window<2>(grid, active, 3).cells.empty());
  active[coupler::cell_index<2>(grid, IVec<2>(1, 6))] = 1;
  const auto w = coupler::cell_window<2>(grid, active, 3);
  EXPECT_EQ(w.grid.dims, IVec<2>(6, 6));  // cells 0..4 by 3..7: 5 x 5 cells, 6 x 6 nodes
  ASSERT_EQ(w.cells.size(), 25u);
  EXPECT_EQ(w.cells.front(), coupler::cell_index<2>(grid, IVec<2>(0, 3)));
  EXPECT_EQ(w.cells.back(), coupler::cell_index<2>(grid, IVec<2>(4, 7)));
  EXPECT_TRUE(w.grid.origin.isApprox(grid.node_position(IVec<2>(0, 3))));
  for (std::size_t k = 0; k < w.cells.size(); ++k) EXPECT_EQ(w.slot_of(grid, w.cells[k]), static_cast<std::int64_t>(k));
  EXPECT_EQ(w.slot_of(grid, coupler::cell_index<2>(grid, IVec<2>(5, 3))), -1);
  EXPECT_EQ(w.slot_of(grid, coupler::cell_index<2>(grid, IVec<2>(2, 2))), -1);
}
