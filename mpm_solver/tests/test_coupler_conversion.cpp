// Homogenisation of a cell's grains into material points conserves mass,
// linear and (APIC) angular momentum exactly and carries the stress across.
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "coupler/conversion.hpp"
#include "coupler/stencil.hpp"

namespace {

template <int D>
using Vec = Eigen::Matrix<double, D, 1>;
template <int D>
using Mat = Eigen::Matrix<double, D, D>;

template <int D>
coupler::GridGeometry<D> test_grid() {
  coupler::GridGeometry<D> g;
  g.dx = 0.01;
  g.origin.setConstant(-0.03);
  for (int a = 0; a < D; ++a) g.dims[a] = 9 + 2 * a;  // unequal, so axis mix-ups show
  return g;
}

/// Scale of a quantity for relative comparisons: never smaller than its parts.
template <class A, class B>
void expect_rel_near(const A& got, const B& want, double scale, double rel = 1e-12) {
  EXPECT_LE((got - want).norm(), rel * scale) << "got\n" << got << "\nwant\n" << want;
}

template <int D>
struct Grains {
  coupler::CellMoments<D> moments;
  double l_scale = 0, p_scale = 0, s_scale = 0;  // sums of magnitudes, for relative tolerances
};

/// n random grains inside cell c (random positions, velocities, masses, spins, stress).
template <int D>
Grains<D> random_grains(const coupler::GridGeometry<D>& grid, const Eigen::Matrix<int, D, 1>& c, unsigned seed,
                        int n) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  Grains<D> g;
  g.moments.cell = coupler::cell_index(grid, c);
  const Vec<D> lower = grid.node_position(c);
  for (int k = 0; k < n; ++k) {
    Vec<D> x, v;
    for (int a = 0; a < D; ++a) {
      x[a] = lower[a] + grid.dx * u(rng);
      v[a] = 2 * u(rng) - 1;
    }
    const double m = 1e-6 * (0.5 + u(rng));
    coupler::Spin<D> spin;
    for (int a = 0; a < spin.size(); ++a) spin[a] = 1e-12 * (2 * u(rng) - 1);
    Mat<D> s;
    for (int a = 0; a < D; ++a)
      for (int b = 0; b <= a; ++b) s(a, b) = s(b, a) = 1e-3 * (2 * u(rng) - 1);
    g.moments.add_grain(x, v, m, spin, s);
    g.l_scale += coupler::cross<D>(x, m * v).norm() + spin.norm();
    g.p_scale += m * v.norm();
    g.s_scale += s.norm();
  }
  return g;
}

template <int D>
Eigen::Matrix<int, D, 1> some_cell() {
  Eigen::Matrix<int, D, 1> c;
  for (int a = 0; a < D; ++a) c[a] = 3 + a;
  return c;
}

template <int D>
void conserves_mass_momentum_angular(int per_axis) {
  const auto grid = test_grid<D>();
  const Grains<D> g = random_grains<D>(grid, some_cell<D>(), 11 + per_axis, 17);
  const auto& m = g.moments;
  const auto points = coupler::points_from_moments<D>(m, grid, per_axis, 1.0);
  ASSERT_EQ(points.size(), static_cast<std::size_t>(std::pow(per_axis, D)));
  const auto s = coupler::moments_of_points<D>(points, grid.dx);
  EXPECT_NEAR(s.mass, m.mass, 1e-12 * m.mass);
  expect_rel_near(s.momentum(), m.momentum(), g.p_scale);
  expect_rel_near(s.angular(), m.angular(), g.l_scale);
  // All points inside the cell, equal masses.
  for (const auto& p : points) {
    EXPECT_EQ(coupler::cell_of(grid, p.x), some_cell<D>());
    EXPECT_DOUBLE_EQ(p.mass, m.mass / points.size());
  }
}

template <int D>
void share_scales_everything() {
  const auto grid = test_grid<D>();
  const Grains<D> g = random_grains<D>(grid, some_cell<D>(), 3, 12);
  const double share = 0.3;
  const auto points = coupler::points_from_moments<D>(g.moments.scaled(share), grid, 2, share);
  const auto s = coupler::moments_of_points<D>(points, grid.dx);
  EXPECT_NEAR(s.mass, share * g.moments.mass, 1e-12 * g.moments.mass);
  expect_rel_near(s.momentum(), share * g.moments.momentum(), g.p_scale);
  expect_rel_near(s.angular(), share * g.moments.angular(), g.l_scale);
  expect_rel_near(s.stress_volume(), share * g.moments.stress_volume(), g.s_scale);
  double volume = 0;
  for (const auto& p : points) volume += p.volume;
  EXPECT_NEAR(volume, share * std::pow(grid.dx, D), 1e-12 * std::pow(grid.dx, D));
  // Stress is intensive: the same as without a share.
  const auto full = coupler::points_from_moments<D>(g.moments, grid, 2, 1.0);
  expect_rel_near(points[0].stress, full[0].stress, full[0].stress.norm());
}

template <int D>
void stress_is_stress_volume_over_cell_volume() {
  const auto grid = test_grid<D>();
  const Grains<D> g = random_grains<D>(grid, some_cell<D>(), 8, 9);
  const auto points = coupler::points_from_moments<D>(g.moments, grid, 3, 1.0);
  const Mat<D> want = g.moments.stress_volume() / std::pow(grid.dx, D);
  ASSERT_GT(want.norm(), 0);
  for (const auto& p : points) {
    expect_rel_near(p.stress, want, want.norm());
    EXPECT_NEAR(p.volume, std::pow(grid.dx, D) / points.size(), 1e-15 * std::pow(grid.dx, D));
  }
}

/// Grains spinning rigidly about the cell centre (velocity w x r, spin I_g w):
/// the points move rigidly too, v_p = P/M + Omega x r_p (r_p from the centre of mass)
/// with Omega = axial(C)/2,
/// C skew, and Omega . w > 0. Grains sitting on the lattice with the points'
/// masses and APIC-equivalent spins m dx^2/2 w, translating with V, give back
/// Omega = w exactly.
template <int D>
void rigid_rotation() {
  const auto grid = test_grid<D>();
  const auto c = some_cell<D>();
  const Vec<D> centre = coupler::cell_center(grid, c);
  coupler::Spin<D> w;
  for (int a = 0; a < w.size(); ++a) w[a] = 3.0 + a;
  const Mat<D> W = coupler::skew<D>(w);
  Vec<D> V;
  for (int a = 0; a < D; ++a) V[a] = 0.1 * (a + 1);

  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(0, 1);
  coupler::CellMoments<D> m;
  m.cell = coupler::cell_index(grid, c);
  for (int k = 0; k < 20; ++k) {
    Vec<D> x;
    for (int a = 0; a < D; ++a) x[a] = centre[a] + grid.dx * (u(rng) - 0.5);
    const double mass = 1e-6 * (0.5 + u(rng)), radius = 1e-3;
    const double inertia = (D == 2 ? 0.5 : 0.4) * mass * radius * radius;
    m.add_grain(x, W * (x - centre), mass, inertia * w, Mat<D>::Zero());
  }
  const auto points = coupler::points_from_moments<D>(m, grid, 2, 1.0);
  ASSERT_FALSE(points.empty());
  const Mat<D> C = points[0].C;
  expect_rel_near(C + C.transpose(), Mat<D>::Zero(), C.norm());
  const coupler::Spin<D> omega = coupler::axial<D>(C) / 2;
  EXPECT_GT(omega.dot(w), 0);
  const Vec<D> P_over_M = m.momentum() / m.mass, com = m.first_moment() / m.mass;  // (the lattice's centre)
  for (const auto& p : points) {
    EXPECT_EQ(p.C, C);
    expect_rel_near(p.v, P_over_M + coupler::skew<D>(omega) * (p.x - com), omega.norm() * grid.dx);
  }

  // Grains on the lattice itself.
  coupler::CellMoments<D> on;
  on.cell = m.cell;
  const double mp = 1e-6;
  for (const auto& p : points) on.add_grain(p.x, V + W * (p.x - centre), mp, mp * grid.dx * grid.dx / 2 * w, Mat<D>::Zero());
  const auto back = coupler::points_from_moments<D>(on, grid, 2, 1.0);
  for (const auto& p : back) {
    expect_rel_near(coupler::axial<D>(p.C) / 2, w, w.norm());
    expect_rel_near(p.v, V + W * (p.x - centre), V.norm() + w.norm() * grid.dx);
  }
}

/// The APIC angular momentum of one point equals the angular momentum of the
/// momenta its P2G puts on the nodes, sum_i x_i x w_i m (v + C (x_i - x_p)).
template <int D>
void apic_angular_momentum_matches_grid() {
  const auto grid = test_grid<D>();
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 20; ++trial) {
    Vec<D> x, v;
    Mat<D> C;
    for (int a = 0; a < D; ++a) {
      x[a] = grid.origin[a] + grid.dx * (1 + (grid.dims[a] - 3) * u(rng));
      v[a] = 2 * u(rng) - 1;
      for (int b = 0; b < D; ++b) C(a, b) = 100 * (2 * u(rng) - 1);  // general, not skew
    }
    ASSERT_TRUE(grid.stencil_on_grid(x));
    const double m = 1e-6 * (0.5 + u(rng));
    coupler::Spin<D> L = coupler::Spin<D>::Zero(), scale = coupler::Spin<D>::Zero();
    coupler::for_each_stencil_node<D>(
        coupler::QuadraticStencil<D>(grid.to_cell_units(x)), grid, [&](std::size_t node, double w, const auto&) {
          const Vec<D> xi = grid.node_position(grid.node_of(node));
          const coupler::Spin<D> l = coupler::cross<D>(xi, w * m * (v + C * (xi - x)));
          L += l;
          scale += l.cwiseAbs();
        });
    expect_rel_near(coupler::point_angular_momentum<D>(x, v, C, m, grid.dx), L, scale.norm());
    // Without the dx^2/4 term it would not match (C is large enough to show).
    EXPECT_GT((coupler::cross<D>(x, m * v) - L).norm(), 1e-6 * scale.norm());
  }
}

template <int D>
void cell_index_round_trip() {
  const auto grid = test_grid<D>();
  std::size_t want = 1;
  for (int a = 0; a < D; ++a) want *= grid.dims[a] - 1;
  ASSERT_EQ(coupler::num_cells(grid), want);
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(0, 1);
  for (std::size_t k = 0; k < coupler::num_cells(grid); ++k) {
    const auto c = coupler::cell_coords(grid, k);
    for (int a = 0; a < D; ++a) {
      EXPECT_GE(c[a], 0);
      EXPECT_LT(c[a], grid.dims[a] - 1);
    }
    EXPECT_EQ(coupler::cell_index(grid, c), k);
    EXPECT_EQ(coupler::cell_of(grid, coupler::cell_center(grid, c)), c);
    Vec<D> x = grid.node_position(c);
    for (int a = 0; a < D; ++a) x[a] += grid.dx * 0.999 * u(rng);
    EXPECT_EQ(coupler::cell_of(grid, x), c);
  }
  // Last axis fastest, like GridGeometry::index.
  Eigen::Matrix<int, D, 1> c = Eigen::Matrix<int, D, 1>::Zero();
  c[D - 1] = 1;
  EXPECT_EQ(coupler::cell_index(grid, c), 1u);
}

/// Partial sums from two DEM ranks, sent as bytes and added, equal the sum over all grains.
template <int D>
void partial_sums_add_up() {
  const auto grid = test_grid<D>();
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(0, 1);
  coupler::CellMoments<D> a, b, sum;
  for (int k = 0; k < 6; ++k) {
    Vec<D> x = Vec<D>::Constant(u(rng)), v = Vec<D>::Constant(u(rng) - 0.5);
    Mat<D> s = Mat<D>::Identity() * u(rng);
    coupler::Spin<D> spin = coupler::Spin<D>::Constant(1e-9 * u(rng));
    (k % 2 ? a : b).add_grain(x, v, 1 + k, spin, s);
    sum.add_grain(x, v, 1 + k, spin, s);
  }
  coupler::CellMoments<D> received;
  std::memcpy(static_cast<void*>(&received), &b, sizeof received);
  a.add(received);
  EXPECT_EQ(a.count, 6);
  EXPECT_NEAR(a.mass, sum.mass, 1e-12 * sum.mass);
  expect_rel_near(a.first_moment(), sum.first_moment(), sum.first_moment().norm());
  expect_rel_near(a.momentum(), sum.momentum(), sum.momentum().norm());
  expect_rel_near(a.angular(), sum.angular(), sum.angular().norm());
  expect_rel_near(a.stress_volume(), sum.stress_volume(), sum.stress_volume().norm());
  // scaled keeps the count and the cell.
  const auto all = random_grains<D>(grid, some_cell<D>(), 5, 10).moments;
  const auto half = all.scaled(0.5);
  EXPECT_EQ(half.count, all.count);
  EXPECT_EQ(half.cell, all.cell);
  EXPECT_DOUBLE_EQ(half.mass, 0.5 * all.mass);
  // No mass, no points.
  EXPECT_TRUE(coupler::points_from_moments<D>(coupler::CellMoments<D>{}, grid, 2, 1.0).empty());
}

}  // namespace

static_assert(std::is_trivially_copyable_v<coupler::CellMoments<2>>);
static_assert(std::is_trivially_copyable_v<coupler::CellMoments<3>>);

/// Bodies moving with an affine field: velocity_gradient recovers its gradient; points made
/// with it carry that gradient in C (plus the rigid part that fits the angular momentum) and
/// the cell's mass, momentum and angular momentum exactly. A rigid correction onto another
/// target moves those sums onto the target exactly.
template <int D>
void affine_field_and_rigid_correction() {
  const auto grid = test_grid<D>();
  Eigen::Matrix<int, D, 1> c;
  for (int a = 0; a < D; ++a) c[a] = 3 + a;
  const Vec<D> centre = coupler::cell_center(grid, c);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  Mat<D> G;
  for (int a = 0; a < D; ++a)
    for (int b = 0; b < D; ++b) G(a, b) = 20 * (2 * u(rng) - 1);
  const Vec<D> V = Vec<D>::Constant(0.3);
  coupler::BodySums<D> bodies;
  bodies.moments.cell = coupler::cell_index(grid, c);
  std::vector<Vec<D>> xs, vs;
  std::vector<double> ms;
  const double e = 0.5 * 1e-3 * 1e-3;  // own inertia per mass (a disk of radius 1 mm)
  for (int k = 0; k < 12; ++k) {
    Vec<D> x;
    for (int a = 0; a < D; ++a) x[a] = grid.node_position(c)[a] + grid.dx * u(rng);
    xs.push_back(x), vs.push_back(V + G * (x - centre)), ms.push_back(1e-4 * (0.5 + u(rng)));
    bodies.add_body(x, vs.back(), ms.back(), coupler::Spin<D>::Zero(), e, Mat<D>::Zero(), centre);
  }
  EXPECT_LE((bodies.velocity_gradient(centre) - G).norm(), 1e-9 * G.norm());
  const auto& m = bodies.moments;
  const coupler::AffineMotion<D> affine = bodies.affine_motion(centre);
  // the energy the gradient carries at the bodies, sum 1/2 m |G (x - x_c)|^2 over their mass
  Vec<D> xc = Vec<D>::Zero();
  for (std::size_t k = 0; k < xs.size(); ++k) xc += ms[k] * xs[k] / m.mass;
  double at_bodies = 0;
  for (std::size_t k = 0; k < xs.size(); ++k) at_bodies += 0.5 * ms[k] * (G * (xs[k] - xc)).squaredNorm() / m.mass;
  EXPECT_NEAR(affine.energy_per_mass, at_bodies, 1e-9 * at_bodies);
  const auto points = coupler::points_from_moments<D>(m, grid, 2, 1.0, affine);
  const auto s = coupler::moments_of_points<D>(points, grid.dx);
  EXPECT_NEAR(s.mass, m.mass, 1e-14 * m.mass);
  const double p_scale = m.mass * (V.norm() + G.norm() * grid.dx);
  expect_rel_near(s.momentum(), m.momentum(), p_scale);
  expect_rel_near(s.angular(), m.angular(), p_scale * (centre.norm() + grid.dx));
  // C = a G + a rotation, 0 < a < 1: 12 bodies spread over the cell span less of it than the
  // lattice with APIC's inertia dx^2/4 per axis, so the gradient is scaled down until the points'
  // affine kinetic energy per mass (about their mean velocity) is the bodies'
  const Mat<D> sym_G = 0.5 * (G + G.transpose()), sym_C = 0.5 * (points[0].C + points[0].C.transpose());
  const double a = (sym_C.array() * sym_G.array()).sum() / sym_G.squaredNorm();
  EXPECT_GT(a, 0.0);
  EXPECT_LT(a, 1.0);
  EXPECT_LE((sym_C - a * sym_G).norm(), 1e-9 * G.norm());
  Vec<D> mean_v = Vec<D>::Zero();
  for (const auto& p : points) mean_v += p.v / points.size();
  double lattice_affine = 0;
  for (const auto& p : points)
    lattice_affine += 0.5 * ((p.v - mean_v).squaredNorm() + grid.dx * grid.dx / 4 * p.C.squaredNorm()) / points.size();
  EXPECT_NEAR(lattice_affine, at_bodies, 1e-9 * at_bodies);
  // without a bound on its energy the lattice takes the gradient itself
  const auto unbounded = coupler::points_from_moments<D>(m, grid, 2, 1.0, coupler::AffineMotion<D>{G});
  const Mat<D> sym_unbounded = 0.5 * (unbounded[0].C + unbounded[0].C.transpose()) - 0.5 * (G + G.transpose());
  EXPECT_LE(sym_unbounded.norm(), 1e-9 * G.norm());
  // rigid correction onto another target: scaled mass, new momentum, new angular momentum
  coupler::CellMoments<D> target = m.scaled(1.7);
  target.momentum() += Vec<D>::Constant(1e-5);
  target.angular() += coupler::Spin<D>::Constant(2e-8);
  const auto fix = coupler::rigid_correction<D>(bodies, target, centre);
  EXPECT_NEAR(fix.mass_factor, 1.7, 1e-14);
  coupler::CellMoments<D> after;
  for (std::size_t k = 0; k < xs.size(); ++k) {
    const double mk = fix.mass_factor * ms[k];
    after.add_grain(xs[k], Vec<D>(vs[k] + fix.increment(xs[k])), mk, coupler::Spin<D>(mk * e * fix.omega),
                    Mat<D>::Zero());
  }
  EXPECT_NEAR(after.mass, target.mass, 1e-14 * target.mass);
  expect_rel_near(after.momentum(), target.momentum(), 1.7 * p_scale);
  expect_rel_near(after.angular(), target.angular(), 1.7 * p_scale * (centre.norm() + grid.dx));
}

/// D + 1 grains near a cell's corner, nearly in a row, with velocities that differ across it (the
/// few grains of a cell at a flow's surface): their least-squares gradient is huge (their spread
/// across the row is tiny), and points spread over the cell with it were made at 150 m/s from a flow
/// of 1 m/s. The points made carry no more kinetic energy than the grains (translation, spin and the
/// points' APIC part, 1/2 m dx^2/4 |C|^2), and their mass, momentum and angular momentum exactly.
template <int D>
void points_from_few_grains_make_no_energy() {
  const auto grid = test_grid<D>();
  const Eigen::Matrix<int, D, 1> c = some_cell<D>();
  const Vec<D> centre = coupler::cell_center(grid, c), corner = grid.node_position(c);
  const double r = 0.1 * grid.dx, m = 1e-3, e = 0.5 * r * r;  // disks' own inertia per mass
  coupler::BodySums<D> bodies;
  bodies.moments.cell = coupler::cell_index(grid, c);
  double energy = 0;
  for (int k = 0; k <= D; ++k) {
    Vec<D> x = corner + Vec<D>::Constant(1.5 * r), v = Vec<D>::Zero();  // (their centre of mass: not within
                                                                         // the lattice's margin of the faces)
    x[0] += 2 * r * k;                // a row along x ...
    if (k >= 2) x[k - 1] += (D == 2 ? 0.02 : 0.2) * r;  // ... nearly (in 3D the fit needs more)
    v[0] = 1.0, v[D - 1] = k % 2 == 0 ? 0.3 : -0.3;
    bodies.add_body(x, v, m, coupler::Spin<D>::Zero(), e, Mat<D>::Zero(), centre);
    energy += 0.5 * m * v.squaredNorm();
  }
  ASSERT_GT(bodies.velocity_gradient(centre).norm() * grid.dx, 30.0);  // the ill-posed fit: 30x the flow's speed
  const auto points = coupler::points_from_moments<D>(bodies.moments, grid, 2, 1.0, bodies.affine_motion(centre));
  double made = 0;
  for (const auto& p : points) made += 0.5 * p.mass * (p.v.squaredNorm() + grid.dx * grid.dx / 4 * p.C.squaredNorm());
  EXPECT_LE(made, energy * (1 + 1e-9));  // (the bound is reached: the three grains move affinely)
  const auto s = coupler::moments_of_points<D>(points, grid.dx);
  EXPECT_NEAR(s.mass, bodies.moments.mass, 1e-14 * s.mass);
  // the grains' centre of mass (about the cell's centre, the lattice's was a spin and potential
  // energy), the points inside the cell
  expect_rel_near(Vec<D>(s.first_moment() / s.mass), Vec<D>(bodies.moments.first_moment() / s.mass), centre.norm());
  for (const auto& p : points) EXPECT_EQ(coupler::cell_of(grid, p.x), c);
  expect_rel_near(s.momentum(), bodies.moments.momentum(), (D + 1) * m);
  expect_rel_near(s.angular(), bodies.moments.angular(), (D + 1) * m * (centre.norm() + grid.dx));
}

TEST(coupler_conversion, PointsFromFewGrainsMakeNoEnergy2D) { points_from_few_grains_make_no_energy<2>(); }
TEST(coupler_conversion, PointsFromFewGrainsMakeNoEnergy3D) { points_from_few_grains_make_no_energy<3>(); }

TEST(coupler_conversion, AffineFieldAndRigidCorrection2D) { affine_field_and_rigid_correction<2>(); }
TEST(coupler_conversion, AffineFieldAndRigidCorrection3D) { affine_field_and_rigid_correction<3>(); }

TEST(coupler_conversion, ConservesMassMomentumAngular2D) {
  conserves_mass_momentum_angular<2>(2);
  conserves_mass_momentum_angular<2>(3);
}
TEST(coupler_conversion, ConservesMassMomentumAngular3D) {
  conserves_mass_momentum_angular<3>(2);
  conserves_mass_momentum_angular<3>(3);
}
TEST(coupler_conversion, ShareScalesEverything2D) { share_scales_everything<2>(); }
TEST(coupler_conversion, ShareScalesEverything3D) { share_scales_everything<3>(); }
TEST(coupler_conversion, StressIsStressVolumeOverCellVolume2D) { stress_is_stress_volume_over_cell_volume<2>(); }
TEST(coupler_conversion, StressIsStressVolumeOverCellVolume3D) { stress_is_stress_volume_over_cell_volume<3>(); }
TEST(coupler_conversion, RigidRotationStaysRigid2D) { rigid_rotation<2>(); }
TEST(coupler_conversion, RigidRotationStaysRigid3D) { rigid_rotation<3>(); }
TEST(coupler_conversion, ApicAngularMomentumMatchesGridMomenta2D) { apic_angular_momentum_matches_grid<2>(); }
TEST(coupler_conversion, ApicAngularMomentumMatchesGridMomenta3D) { apic_angular_momentum_matches_grid<3>(); }
TEST(coupler_conversion, CellIndexRoundTrip2D) { cell_index_round_trip<2>(); }
TEST(coupler_conversion, CellIndexRoundTrip3D) { cell_index_round_trip<3>(); }
TEST(coupler_conversion, PartialSumsAddUp2D) { partial_sums_add_up<2>(); }
TEST(coupler_conversion, PartialSumsAddUp3D) { partial_sums_add_up<3>(); }

namespace {
/// The sum over DEM ranks packs BodySums field by field: every summable value goes out and comes
/// back to its own field, the cell index is never touched.
template <int D>
void summed_fields_round_trip() {
  coupler::BodySums<D> s;
  s.moments.cell = 12345;
  double next = 1.0;
  std::size_t listed = 0;
  coupler::for_each_summed_field<D>(s, [&](double* p, int n) {
    for (int i = 0; i < n; ++i) p[i] = next++;
    listed += static_cast<std::size_t>(n);
  });
  ASSERT_EQ(listed, coupler::kBodySumsValues<D>);
  std::vector<double> packed(coupler::kBodySumsValues<D>, -1.0);
  coupler::pack_summed_fields<D>(s, packed.data());
  for (std::size_t i = 0; i < packed.size(); ++i) EXPECT_EQ(packed[i], 1.0 + static_cast<double>(i));
  // every field by name holds what the list put there
  EXPECT_EQ(s.moments.count, 1.0);
  EXPECT_EQ(s.moments.mass, 2.0);
  EXPECT_EQ(s.position_moment_[D * D - 1], static_cast<double>(coupler::kBodySumsValues<D>));
  coupler::BodySums<D> back;
  back.moments.cell = 7;
  coupler::unpack_summed_fields<D>(packed.data(), back);
  EXPECT_EQ(back.moments.cell, 7u);
  back.moments.cell = s.moments.cell;
  EXPECT_EQ(std::memcmp(&back, &s, sizeof s), 0) << "a field was not carried over";
}
}  // namespace

TEST(BodySums, SummedFieldsRoundTrip2D) { summed_fields_round_trip<2>(); }
TEST(BodySums, SummedFieldsRoundTrip3D) { summed_fields_round_trip<3>(); }
