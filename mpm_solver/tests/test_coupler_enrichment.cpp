// Enrichment of a cell's material points into grains: the packing template is
// overlap-free and dense; the grains carry mass, linear and angular momentum
// exactly, overlap neither their neighbours nor each other, and follow a rigid
// rotation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <random>

#include "coupler/conversion.hpp"
#include "coupler/enrichment.hpp"
#include "coupler/oracle.hpp"

namespace {

template <int D>
using Vec = Eigen::Matrix<double, D, 1>;
template <int D>
using Mat = Eigen::Matrix<double, D, D>;
template <int D>
using IVec = Eigen::Matrix<int, D, 1>;

constexpr double kDiameter = 0.0025;  // 4 mean diameters per cell
constexpr double kDensity = 2500;

template <int D>
constexpr double kappa() {
  return D == 2 ? 0.5 : 0.4;  // disk / ball
}

template <int D>
coupler::GridGeometry<D> test_grid() {
  coupler::GridGeometry<D> g;
  g.dx = 0.01;
  g.origin.setConstant(-0.03);
  for (int a = 0; a < D; ++a) g.dims[a] = 9 + 2 * a;  // unequal, so axis mix-ups show
  return g;
}

template <int D>
IVec<D> some_cell() {
  IVec<D> c;
  for (int a = 0; a < D; ++a) c[a] = 3 + a;
  return c;
}

/// The templates of the brief: 10x10 in 2D, 6x6x6 in 3D, 10% polydispersity.
template <int D>
const coupler::PackingTemplate<D>& the_template() {
  static const auto t = coupler::make_packing_template<D>(D == 2 ? 10 : 6, 0.1, 7);
  return t;
}

template <int D>
coupler::CellMoments<D> moments_of_grains(const std::vector<coupler::NewGrain<D>>& grains, double inertia_factor) {
  coupler::CellMoments<D> s;
  for (const auto& g : grains)
    s.add_grain(g.x, g.v, g.mass, inertia_factor * g.mass * g.radius * g.radius * g.omega, Mat<D>::Zero());
  return s;
}

/// Largest overlap (r_i + r_j - distance) among a set of grains; <= 0 if none.
template <int D>
double max_overlap(const std::vector<coupler::NewGrain<D>>& grains) {
  double worst = -1;
  for (std::size_t i = 0; i < grains.size(); ++i)
    for (std::size_t j = i + 1; j < grains.size(); ++j)
      worst = std::max(worst, grains[i].radius + grains[j].radius - (grains[i].x - grains[j].x).norm());
  return worst;
}

/// n random grains inside cell c: a random target.
template <int D>
coupler::CellMoments<D> random_target(const coupler::GridGeometry<D>& grid, const IVec<D>& c, unsigned seed, int n) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  coupler::CellMoments<D> m;
  m.cell = coupler::cell_index(grid, c);
  const Vec<D> lower = grid.node_position(c);
  for (int k = 0; k < n; ++k) {
    Vec<D> x, v;
    for (int a = 0; a < D; ++a) {
      x[a] = lower[a] + grid.dx * u(rng);
      v[a] = 2 * u(rng) - 1;
    }
    coupler::Spin<D> spin;
    for (int a = 0; a < spin.size(); ++a) spin[a] = 1e-9 * (2 * u(rng) - 1);
    m.add_grain(x, v, 1e-4 * (0.5 + u(rng)), spin, Mat<D>::Zero());
  }
  return m;
}

// ---------------------------------------------------------------------------------------
// Template

template <int D>
void template_is_overlap_free_and_dense() {
  const auto& t = the_template<D>();
  ASSERT_EQ(t.x.size(), t.radius.size());
  ASSERT_GT(t.x.size(), 50u);
  double volume = 0;
  for (std::size_t i = 0; i < t.x.size(); ++i) {
    EXPECT_TRUE((t.x[i].array() >= 0).all() && (t.x[i].array() < t.side).all()) << t.x[i].transpose();
    EXPECT_GE(t.radius[i], 0.45);
    EXPECT_LE(t.radius[i], 0.55);
    volume += coupler::grain_volume<D>(t.radius[i]);
    // Every pair, with the periodic minimum image (brute force, independent of the cell list).
    for (std::size_t j = i + 1; j < t.x.size(); ++j) {
      Vec<D> d = t.x[j] - t.x[i];
      for (int a = 0; a < D; ++a) d[a] -= t.side * std::round(d[a] / t.side);
      EXPECT_GT(d.norm(), t.radius[i] + t.radius[j]) << "grains " << i << " and " << j << " overlap";
    }
  }
  const double fraction = volume / std::pow(t.side, D);
  EXPECT_GE(fraction, D == 2 ? 0.75 : 0.55);
}

TEST(coupler_enrichment, TemplateIsOverlapFreeAndDense2D) { template_is_overlap_free_and_dense<2>(); }
TEST(coupler_enrichment, TemplateIsOverlapFreeAndDense3D) { template_is_overlap_free_and_dense<3>(); }

TEST(coupler_enrichment, TemplateIsDeterministicInSeed) {
  const auto a = coupler::make_packing_template<2>(10, 0.1, 7);
  const auto b = coupler::make_packing_template<2>(10, 0.1, 7);
  const auto c = coupler::make_packing_template<2>(10, 0.1, 8);
  ASSERT_EQ(a.x.size(), b.x.size());
  for (std::size_t i = 0; i < a.x.size(); ++i) {
    EXPECT_EQ(a.x[i], b.x[i]);
    EXPECT_EQ(a.radius[i], b.radius[i]);
  }
  EXPECT_TRUE(a.x.size() != c.x.size() || a.x[0] != c.x[0]);
}

/// CPU time, not wall time, so a loaded machine does not fail the test; the
/// bound is the brief's 50 ms per template.
// ---------------------------------------------------------------------------------------
// Grains for a cell

template <int D>
void conserves_mass_momentum_angular() {
  const auto grid = test_grid<D>();
  const IVec<D> c = some_cell<D>();
  for (unsigned seed = 1; seed <= 6; ++seed) {
    // Odd seeds: random grains; even seeds: the APIC moments of material points.
    coupler::CellMoments<D> target = random_target<D>(grid, c, seed, 17);
    if (seed % 2 == 0) target = coupler::moments_of_points<D>(coupler::points_from_moments<D>(target, grid, 2, 1.0),
                                                               grid.dx, target.cell);
    double f = -1;
    const auto grains = coupler::grains_for_cell<D>(target, grid, the_template<D>(), kDiameter, kDensity, {}, {},
                                                    kappa<D>(), &f);
    ASSERT_GT(grains.size(), 5u);
    const auto got = moments_of_grains<D>(grains, kappa<D>());
    double p_scale = target.momentum().norm(), l_scale = target.angular().norm();
    for (const auto& g : grains) {
      EXPECT_EQ(coupler::cell_of(grid, g.x), c);
      EXPECT_NEAR(g.mass / (kDensity * coupler::grain_volume<D>(g.radius)), f, 1e-13 * f);  // one common factor
      p_scale += g.mass * g.v.norm();
      l_scale += coupler::cross<D>(g.x, g.mass * g.v).norm();
    }
    EXPECT_NEAR(got.mass, target.mass, 1e-12 * target.mass);
    EXPECT_LE((got.momentum() - target.momentum()).norm(), 1e-12 * p_scale) << "seed " << seed;
    EXPECT_LE((got.angular() - target.angular()).norm(), 1e-12 * l_scale) << "seed " << seed;
    EXPECT_LE(max_overlap<D>(grains), 0);
  }
}

TEST(coupler_enrichment, ConservesMassMomentumAngular2D) { conserves_mass_momentum_angular<2>(); }
TEST(coupler_enrichment, ConservesMassMomentumAngular3D) { conserves_mass_momentum_angular<3>(); }

/// A row (3D: a layer) of large grains along the cell's lower x face, reaching
/// 0.4 diameters into the cell: the template alone overlaps them, the
/// enrichment must not.
template <int D>
void no_overlap_with_neighbour_row() {
  const auto grid = test_grid<D>();
  const IVec<D> c = some_cell<D>();
  const Vec<D> lower = grid.node_position(c);
  const double rn = 0.6 * kDiameter, spacing = 1.2 * kDiameter;
  const int per_axis = static_cast<int>(grid.dx / spacing) + 3;
  std::vector<Vec<D>> nx;
  std::vector<double> nr;
  int rows = 1;
  for (int a = 1; a < D; ++a) rows *= per_axis;
  for (int k = 0; k < rows; ++k) {
    Vec<D> x = lower;
    x[0] -= rn - 0.4 * kDiameter;
    for (int a = D - 1, r = k; a >= 1; --a, r /= per_axis) x[a] += (r % per_axis - 1) * spacing;
    nx.push_back(x);
    nr.push_back(rn);
  }
  auto overlaps_row = [&](const std::vector<coupler::NewGrain<D>>& grains) {
    int n = 0;
    for (const auto& g : grains)
      for (std::size_t j = 0; j < nx.size(); ++j) n += (g.x - nx[j]).norm() < g.radius + nr[j];
    return n;
  };
  const auto target = random_target<D>(grid, c, 5, 9);
  const auto free = coupler::grains_for_cell<D>(target, grid, the_template<D>(), kDiameter, kDensity, {}, {}, kappa<D>());
  ASSERT_GT(overlaps_row(free), 0) << "the row must be in the way, or the test shows nothing";
  const auto grains =
      coupler::grains_for_cell<D>(target, grid, the_template<D>(), kDiameter, kDensity, nx, nr, kappa<D>());
  ASSERT_FALSE(grains.empty());
  EXPECT_LT(grains.size(), free.size());
  EXPECT_EQ(overlaps_row(grains), 0);
  EXPECT_NEAR(moments_of_grains<D>(grains, kappa<D>()).mass, target.mass, 1e-12 * target.mass);
}

TEST(coupler_enrichment, NoOverlapWithNeighbourRow2D) { no_overlap_with_neighbour_row<2>(); }
TEST(coupler_enrichment, NoOverlapWithNeighbourRow3D) { no_overlap_with_neighbour_row<3>(); }

/// Two adjacent cells enriched from the same template fit each other: the
/// tiling is anchored at the grid origin.
template <int D>
void adjacent_cells_fit_together() {
  const auto grid = test_grid<D>();
  for (int axis = 0; axis < D; ++axis) {
    IVec<D> c2 = some_cell<D>();
    c2[axis] += 1;
    auto a = coupler::grains_for_cell<D>(random_target<D>(grid, some_cell<D>(), 1, 5), grid, the_template<D>(),
                                         kDiameter, kDensity, {}, {}, kappa<D>());
    const auto b = coupler::grains_for_cell<D>(random_target<D>(grid, c2, 2, 5), grid, the_template<D>(), kDiameter,
                                               kDensity, {}, {}, kappa<D>());
    ASSERT_FALSE(a.empty() || b.empty());
    a.insert(a.end(), b.begin(), b.end());
    EXPECT_LE(max_overlap<D>(a), 0) << "axis " << axis;
  }
}

TEST(coupler_enrichment, AdjacentCellsFitTogether2D) { adjacent_cells_fit_together<2>(); }
TEST(coupler_enrichment, AdjacentCellsFitTogether3D) { adjacent_cells_fit_together<3>(); }

/// Target: the grains an enrichment would make, moving rigidly with
/// v = V0 + w x (x - a) and spinning with w. Enriching it again gives the same
/// grains (positions depend only on the cell), which must move the same way.
template <int D>
void rigid_rotation_is_reproduced() {
  const auto grid = test_grid<D>();
  const IVec<D> c = some_cell<D>();
  const auto first = coupler::grains_for_cell<D>(random_target<D>(grid, c, 4, 7), grid, the_template<D>(), kDiameter,
                                                 kDensity, {}, {}, kappa<D>());
  ASSERT_FALSE(first.empty());
  coupler::Spin<D> w;
  for (int a = 0; a < w.size(); ++a) w[a] = 3.0 + a;
  Vec<D> V0, a0 = coupler::cell_center(grid, c);
  for (int a = 0; a < D; ++a) {
    V0[a] = 0.1 * (a + 1);
    a0[a] += 0.3 * grid.dx * (a + 1);  // rotation axis off the centre of mass
  }
  auto rigid = [&](const Vec<D>& x) -> Vec<D> { return V0 + coupler::skew<D>(w) * (x - a0); };
  coupler::CellMoments<D> target;
  target.cell = coupler::cell_index(grid, c);
  for (const auto& g : first)
    target.add_grain(g.x, rigid(g.x), g.mass, kappa<D>() * g.mass * g.radius * g.radius * w, Mat<D>::Zero());

  const auto grains =
      coupler::grains_for_cell<D>(target, grid, the_template<D>(), kDiameter, kDensity, {}, {}, kappa<D>());
  ASSERT_EQ(grains.size(), first.size());
  const double v_scale = V0.norm() + w.norm() * 2 * grid.dx;
  for (std::size_t i = 0; i < grains.size(); ++i) {
    EXPECT_EQ(grains[i].x, first[i].x);
    EXPECT_LE((grains[i].v - rigid(grains[i].x)).norm(), 1e-12 * v_scale) << "grain " << i;
    EXPECT_LE((grains[i].omega - w).norm(), 1e-12 * w.norm()) << "grain " << i;
  }
}

TEST(coupler_enrichment, RigidRotationIsReproduced2D) { rigid_rotation_is_reproduced<2>(); }
TEST(coupler_enrichment, RigidRotationIsReproduced3D) { rigid_rotation_is_reproduced<3>(); }

/// Neighbours on a lattice of spacing d/2 and radius d/2 cover the cell: every
/// point lies within sqrt(D)/4 d < 0.45 d of one, so no grain fits.
template <int D>
void blocked_cell_gives_no_grains() {
  const auto grid = test_grid<D>();
  const IVec<D> c = some_cell<D>();
  const Vec<D> lower = grid.node_position(c);
  const double spacing = 0.5 * kDiameter;
  const int per_axis = static_cast<int>(grid.dx / spacing) + 3;
  int n = 1;
  for (int a = 0; a < D; ++a) n *= per_axis;
  std::vector<Vec<D>> nx;
  std::vector<double> nr;
  for (int k = 0; k < n; ++k) {
    Vec<D> x = lower;
    for (int a = D - 1, r = k; a >= 0; --a, r /= per_axis) x[a] += (r % per_axis - 1) * spacing;
    nx.push_back(x);
    nr.push_back(0.5 * kDiameter);
  }
  const auto target = random_target<D>(grid, c, 6, 5);
  double f = -1;
  EXPECT_TRUE(
      coupler::grains_for_cell<D>(target, grid, the_template<D>(), kDiameter, kDensity, nx, nr, kappa<D>(), &f).empty());
  EXPECT_EQ(f, 0);
  // Without the neighbours the same cell is filled, and a zero-mass target gives nothing.
  EXPECT_FALSE(
      coupler::grains_for_cell<D>(target, grid, the_template<D>(), kDiameter, kDensity, {}, {}, kappa<D>()).empty());
  EXPECT_TRUE(coupler::grains_for_cell<D>(target.scaled(0), grid, the_template<D>(), kDiameter, kDensity, {}, {},
                                          kappa<D>())
                  .empty());
}

TEST(coupler_enrichment, BlockedCellGivesNoGrains2D) { blocked_cell_gives_no_grains<2>(); }
TEST(coupler_enrichment, BlockedCellGivesNoGrains3D) { blocked_cell_gives_no_grains<3>(); }

}  // namespace
