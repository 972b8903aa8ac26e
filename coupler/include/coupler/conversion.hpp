#pragma once
// Conversion rules of one grid cell between grains and material points, exact in mass,
// linear momentum and angular momentum (docs/design.md section 5): the cell sums, the rigid
// correction that every change of a cell's zone uses, and homogenisation (grains become
// points; enrichment.hpp is the other direction). The points' angular momentum is the APIC
// one, which includes the affine part C, so a cell's spin survives the conversion.
//
// Flow: each DEM rank sums the grains it owns into CellMoments (add_grain),
// the partial sums travel as bytes and are added (add), the MPM side scales
// them by the share of the material the points take over (scaled) and calls
// points_from_moments.
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Geometry>  // Vector3d::cross
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "coupler/bspline.hpp"
#include "coupler/grid_geometry.hpp"

namespace coupler {

/// Angular momentum: in 2D only its z component.
template <int D>
using Spin = std::conditional_t<D == 2, Eigen::Matrix<double, 1, 1>, Eigen::Vector3d>;

template <int D>
Spin<D> cross(const Eigen::Matrix<double, D, 1>& a, const Eigen::Matrix<double, D, 1>& b) {
  if constexpr (D == 2)
    return Spin<2>(a[0] * b[1] - a[1] * b[0]);
  else
    return a.cross(b);
}

/// Axial vector of the skew part of C, times 2: eps_abc C_cb.
template <int D>
Spin<D> axial(const Eigen::Matrix<double, D, D>& C) {
  if constexpr (D == 2)
    return Spin<2>(C(1, 0) - C(0, 1));
  else
    return Eigen::Vector3d(C(2, 1) - C(1, 2), C(0, 2) - C(2, 0), C(1, 0) - C(0, 1));
}

/// The rigid rotation rate with angular velocity w: skew(w) r = w x r.
template <int D>
Eigen::Matrix<double, D, D> skew(const Spin<D>& w) {
  Eigen::Matrix<double, D, D> S;
  if constexpr (D == 2)
    S << 0, -w[0], w[0], 0;
  else
    S << 0, -w[2], w[1], w[2], 0, -w[0], -w[1], w[0], 0;
  return S;
}

/// APIC angular momentum about the origin of a material point with quadratic
/// B-splines. P2G gives node i the momentum w_i m (v + C (x_i - x_p)); its
/// angular momentum sum_i x_i x (...) is x_p x m v plus m eps:(C D_p) with
/// D_p = sum_i w_i (x_i - x_p)(x_i - x_p)^T = dx^2/4 I, since sum_i w_i (x_i - x_p) = 0.
template <int D>
Spin<D> point_angular_momentum(const Eigen::Matrix<double, D, 1>& x, const Eigen::Matrix<double, D, 1>& v,
                               const Eigen::Matrix<double, D, D>& C, double mass, double dx) {
  return cross<D>(x, mass * v) + (mass * dx * dx / kQuadraticInverseInertia) * axial<D>(C);
}

/// Adds to J the inertia, for a rigid rotation about a centre, of mass m at offset r from it
/// that also holds m*extra_sq of isotropic inertia of its own (APIC's dx^2/2 for a point,
/// f r^2 for a spinning grain): the angular momentum about the centre is then J Omega.
/// 2D: J(0,0) holds the scalar, the rest is unused.
template <int D>
void add_rotational_inertia(Eigen::Matrix<double, D, D>& J, double m, const Eigen::Matrix<double, D, 1>& r,
                            double extra_sq) {
  const double s = r.squaredNorm() + extra_sq;
  if constexpr (D == 2)
    J(0, 0) += m * s;
  else
    J += m * (s * Eigen::Matrix<double, D, D>::Identity() - r * r.transpose());
}

/// The rigid rotation rate Omega with J Omega = L (J from add_rotational_inertia).
template <int D>
Spin<D> rotation_rate(const Eigen::Matrix<double, D, D>& J, const Spin<D>& L) {
  Spin<D> omega;
  if constexpr (D == 2)
    omega[0] = L[0] / J(0, 0);
  else
    omega = J.llt().solve(L);
  return omega;
}

/// Extensive moments of the grains of one cell, additive over grains and over
/// DEM ranks. Stored as plain double arrays (Eigen matrices are not trivially
/// copyable) because it is sent over MPI as bytes; use the accessors.
template <int D>
struct CellMoments {
  using Vec = Eigen::Matrix<double, D, 1>;
  using Mat = Eigen::Matrix<double, D, D>;
  static constexpr int kSpinSize = D == 2 ? 1 : 3;

  std::uint64_t cell = 0;  ///< flat cell index (cell_index)
  double count = 0;        ///< number of grains
  double mass = 0;         ///< sum m
  double first_moment_[D] = {};           ///< sum m x
  double momentum_[D] = {};               ///< sum m v
  double angular_[kSpinSize] = {};        ///< sum x x m v + spin, about the origin
  double stress_volume_[D * D] = {};      ///< sum stress*volume, tension positive, column-major

  Eigen::Map<Vec> first_moment() { return Eigen::Map<Vec>(first_moment_); }
  Eigen::Map<const Vec> first_moment() const { return Eigen::Map<const Vec>(first_moment_); }
  Eigen::Map<Vec> momentum() { return Eigen::Map<Vec>(momentum_); }
  Eigen::Map<const Vec> momentum() const { return Eigen::Map<const Vec>(momentum_); }
  Eigen::Map<Spin<D>> angular() { return Eigen::Map<Spin<D>>(angular_); }
  Eigen::Map<const Spin<D>> angular() const { return Eigen::Map<const Spin<D>>(angular_); }
  Eigen::Map<Mat> stress_volume() { return Eigen::Map<Mat>(stress_volume_); }
  Eigen::Map<const Mat> stress_volume() const { return Eigen::Map<const Mat>(stress_volume_); }

  /// spin_L: the grain's own angular momentum (I omega); stress_volume as
  /// LAMMPS compute stress/atom gives it.
  void add_grain(const Vec& x, const Vec& v, double m, const Spin<D>& spin_L, const Mat& grain_stress_volume) {
    count += 1;
    mass += m;
    first_moment() += m * x;
    momentum() += m * v;
    angular() += cross<D>(x, m * v) + spin_L;
    stress_volume() += grain_stress_volume;
  }
  /// Adds another partial sum of the same cell.
  void add(const CellMoments& o) {
    count += o.count;
    mass += o.mass;
    first_moment() += o.first_moment();
    momentum() += o.momentum();
    angular() += o.angular();
    stress_volume() += o.stress_volume();
  }
  /// The share of the cell's material that one representation takes over.
  CellMoments scaled(double share) const {
    CellMoments s = *this;
    s.mass *= share;
    s.first_moment() *= share;
    s.momentum() *= share;
    s.angular() *= share;
    s.stress_volume() *= share;
    return s;
  }
};
static_assert(std::is_trivially_copyable_v<CellMoments<2>> && std::is_trivially_copyable_v<CellMoments<3>>,
              "CellMoments is sent over MPI as bytes");

// ---------------------------------------------------------------------------------------
// Moving a cell's material between its two representations (docs/design.md section 5, adaptive
// zones). One rule serves every direction: a set of bodies - the grains or the material
// points of one cell - is scaled in mass and given a rigid velocity increment (translation
// plus rotation about its centre of mass), so that it carries exactly a target mass, linear
// momentum and angular momentum. New bodies are made at rest (or with a prior velocity
// field) and corrected onto their share; existing bodies are corrected onto a new share.
//
// Derivation. Bodies i with masses m_i at x_i, own isotropic inertia m_i e_i (a grain's
// spin inertia k r^2, APIC's dx^2/2 for a point), sums M, P, L (about the origin). Scale all
// masses by f = M_t / M and add dv_i = a + w x r_i, dspin_i = w, r_i = x_i - X_c, X_c the
// centre of mass (unchanged by the scaling). As sum m_i r_i = 0:
//   P' = f P + M_t a                               -> a = (P_t - f P) / M_t
//   L' = f L + X_c x M_t a + J w,  J = f sum m_i ((|r_i|^2 + e_i) I - r_i r_i^T)
//                                                  -> J w = L_t - f L - X_c x M_t a.
// For points "spin += w" is "C += skew(w)" (axial(skew(w)) = 2 w, APIC spin m dx^2/4 axial(C)).

/// A rezone makes new grains in a hybrid cell whose material (grains' and points' mass) is more
/// than this times its grains' solid mass. Grains and points of a hybrid cell can overlap in
/// space (the agreement aligns their velocities, not their positions), so a cell may hold more
/// material than its grains; its points take a smaller surplus.
inline constexpr double kHeaviestGrains = 1.2;

/// A hybrid cell whose grains carry less than this share of what its zone gives them (its weight
/// times the cell's material) has had its grains drain out: a rezone remakes them. Where grains
/// leave a hybrid band downwards and points come in from above (the band over a silo's orifice)
/// the band otherwise empties of grains, its points have nothing left to agree with, and the
/// continuum falls through the band into the discrete region (docs/design.md 5.6).
inline constexpr double kStarvedGrains = 0.5;

/// A discrete cell whose grains carry less than this share of their solid mass holds grains that
/// were hybrid (weight < 1) and moved into it: a rezone gives them their full mass from the points
/// nearby. Nothing else does, since the cell keeps its zone: over a silo's orifice grains made in
/// the hybrid band flowed down through the discrete region at half weight and left the silo light
/// (the 90 d 2D silo after 2 s: grains leaving at 0.989 of their solid mass, 1.000 with this;
/// docs/design.md 5.6). One grain of half weight among the 30 or so of a cell is under it.
inline constexpr double kLightGrains = 0.99;

/// How far (in cells, any axis) a cell's rest of material may go to the points of other cells;
/// beyond it the cell keeps its rest (docs/design.md 5.6). A discrete cell of light grains
/// (kLightGrains) with no points that could give their missing mass within it is not rezoned:
/// the rezone could only keep the deficit, and would again at every oracle step (a collapse
/// whose continuum was gone replanned about 5 cells at every oracle step to its end).
inline constexpr int kRestReach = 3;
/// Points lighter than this share of a point's mass at the packing lend no deficit to a rest
/// (mpm::CoupledContinuum::complete_rezone): deficits of at most half their mass each, taken
/// again and again from the points behind a flow's front, drained them to slivers.
inline constexpr double kLightestDebtor = 0.1;

/// The heaviest a rezone makes grains, as a multiple of their solid share, where a cell's surplus
/// of material finds no points near to take it (the continuum is nearly gone).
inline constexpr double kHeaviestKept = 2.0;

/// The mass-weighted least-squares velocity gradient G of bodies, minimising
/// sum m |v - V - G (x - X_c)|^2, from additive sums: mass M, sum m x, sum m v, and about
/// `reference` sum m v r^T and sum m r r^T (r = x - reference). Zero when the bodies do not
/// span the space (one body, a row).
template <int D>
Eigen::Matrix<double, D, D> velocity_gradient(double mass, const Eigen::Matrix<double, D, 1>& first_moment,
                                              const Eigen::Matrix<double, D, 1>& momentum,
                                              const Eigen::Matrix<double, D, D>& velocity_moment,
                                              const Eigen::Matrix<double, D, D>& position_moment,
                                              const Eigen::Matrix<double, D, 1>& reference) {
  using Mat = Eigen::Matrix<double, D, D>;
  if (!(mass > 0)) return Mat::Zero();
  const Eigen::Matrix<double, D, 1> R = first_moment / mass - reference, V = momentum / mass;
  const Mat A = velocity_moment - mass * V * R.transpose();
  const Mat B = position_moment - mass * R * R.transpose();
  const double scale = B.trace() / D;
  if (!(scale > 0) || B.determinant() < 1e-6 * std::pow(scale, D)) return Mat::Zero();
  return A * B.inverse();
}

/// A material's affine motion as new points take it over: its bodies' velocity gradient and the
/// kinetic energy per unit mass that gradient carries at the bodies (about their centre of mass).
/// points_from_moments gives the points the gradient with at most that energy: on a lattice over
/// the whole cell, with APIC's inertia dx^2/4 per mass, the same gradient carries 3.75x the energy
/// of grains filling the cell, and without bound where the bodies span little of it (a few grains
/// nearly in a row at a cell's corner: a 100 d collapse made points at 150 m/s in a flow of 1 m/s).
template <int D>
struct AffineMotion {
  Eigen::Matrix<double, D, D> gradient = Eigen::Matrix<double, D, D>::Zero();
  double energy_per_mass = HUGE_VAL;  ///< J/kg; the default: no bound
};

/// Kinetic energy per unit mass of the affine field G over bodies of mass M whose second moment
/// about their centre of mass is B (sum m r r^T): tr(G B G^T) / (2 M).
template <int D>
double affine_energy_per_mass(const Eigen::Matrix<double, D, D>& G, const Eigen::Matrix<double, D, D>& B,
                              double mass) {
  return mass > 0 ? 0.5 * (G * B * G.transpose()).trace() / mass : 0.0;
}

/// Shear rate of a velocity gradient: sqrt(2 D:D), D its symmetric part.
template <int D>
double shear_rate(const Eigen::Matrix<double, D, D>& gradient) {
  return std::sqrt(2.0) * (0.5 * (gradient + gradient.transpose())).norm();
}

/// Sums over a set of bodies that the rigid correction needs: the cell moments and the
/// inertia about a reference point (the cell centre, so that the parallel-axis shift to the
/// centre of mass cancels little). Additive over bodies and over ranks; sent as bytes.
template <int D>
struct BodySums {
  using Vec = Eigen::Matrix<double, D, 1>;
  using Mat = Eigen::Matrix<double, D, D>;

  CellMoments<D> moments;
  double inertia_[D * D] = {};          ///< sum m ((|r|^2 + e) I - r r^T), r = x - reference; 2D: [0] only
  double velocity_moment_[D * D] = {};  ///< sum m v r^T (for the bodies' velocity gradient)
  double position_moment_[D * D] = {};  ///< sum m r r^T

  Eigen::Map<Mat> inertia() { return Eigen::Map<Mat>(inertia_); }
  Eigen::Map<const Mat> inertia() const { return Eigen::Map<const Mat>(inertia_); }
  Eigen::Map<Mat> velocity_moment() { return Eigen::Map<Mat>(velocity_moment_); }
  Eigen::Map<const Mat> velocity_moment() const { return Eigen::Map<const Mat>(velocity_moment_); }
  Eigen::Map<Mat> position_moment() { return Eigen::Map<Mat>(position_moment_); }
  Eigen::Map<const Mat> position_moment() const { return Eigen::Map<const Mat>(position_moment_); }

  /// One body: spin_L its own angular momentum, extra_sq its own inertia per mass (e).
  void add_body(const Vec& x, const Vec& v, double m, const Spin<D>& spin_L, double extra_sq,
                const Mat& stress_volume, const Vec& reference) {
    moments.add_grain(x, v, m, spin_L, stress_volume);
    const Vec r = x - reference;
    Mat J = Mat::Zero();
    add_rotational_inertia<D>(J, m, r, extra_sq);
    inertia() += J;
    velocity_moment() += m * v * r.transpose();
    position_moment() += m * r * r.transpose();
  }
  void add(const BodySums& o) {
    moments.add(o.moments);
    inertia() += o.inertia();
    velocity_moment() += o.velocity_moment();
    position_moment() += o.position_moment();
  }
  /// The bodies' mass-weighted least-squares velocity gradient (velocity_gradient below).
  Mat velocity_gradient(const Vec& reference) const {
    return coupler::velocity_gradient<D>(moments.mass, moments.first_moment(), moments.momentum(), velocity_moment(),
                                         position_moment(), reference);
  }
  /// That gradient with the energy it carries at the bodies (AffineMotion); `reference` as above.
  AffineMotion<D> affine_motion(const Vec& reference) const {
    AffineMotion<D> a;
    a.gradient = velocity_gradient(reference);
    a.energy_per_mass = 0;
    if (!(moments.mass > 0)) return a;
    const Vec R = moments.first_moment() / moments.mass - reference;
    a.energy_per_mass = affine_energy_per_mass<D>(a.gradient, Mat(position_moment() - moments.mass * R * R.transpose()),
                                                  moments.mass);
    return a;
  }
};
static_assert(std::is_trivially_copyable_v<BodySums<2>> && std::is_trivially_copyable_v<BodySums<3>>,
              "BodySums is sent over MPI as bytes");

/// Number of doubles in a BodySums besides the cell index: what a sum over ranks adds up.
template <int D>
inline constexpr std::size_t kBodySumsValues = 2 + 2 * D + CellMoments<D>::kSpinSize + 4 * D * D;
// A field added to CellMoments or BodySums changes the size: add it to for_each_summed_field too.
static_assert(sizeof(BodySums<2>) == sizeof(std::uint64_t) + kBodySumsValues<2> * sizeof(double) &&
                  sizeof(BodySums<3>) == sizeof(std::uint64_t) + kBodySumsValues<3> * sizeof(double),
              "BodySums changed: list the new field in for_each_summed_field");

/// Calls f(pointer, count) on every summable field of `s` (all but the cell index), in a fixed
/// order, field by field: no assumption about where the fields sit in memory.
template <int D, class Sums, class F>
void for_each_summed_field(Sums& s, F&& f) {
  auto& m = s.moments;
  f(&m.count, 1);
  f(&m.mass, 1);
  f(m.first_moment_, D);
  f(m.momentum_, D);
  f(m.angular_, CellMoments<D>::kSpinSize);
  f(m.stress_volume_, D * D);
  f(s.inertia_, D * D);
  f(s.velocity_moment_, D * D);
  f(s.position_moment_, D * D);
}

/// Copies the summable fields of `s` to out[0, kBodySumsValues<D>).
template <int D>
void pack_summed_fields(const BodySums<D>& s, double* out) {
  for_each_summed_field<D>(s, [&out](const double* p, int n) {
    for (int i = 0; i < n; ++i) *out++ = p[i];
  });
}

/// Sets the summable fields of `s` from in[0, kBodySumsValues<D>); the cell index stays.
template <int D>
void unpack_summed_fields(const double* in, BodySums<D>& s) {
  for_each_summed_field<D>(s, [&in](double* p, int n) {
    for (int i = 0; i < n; ++i) p[i] = *in++;
  });
}

/// The mass factor and rigid velocity increment that carry a set of bodies onto a target.
template <int D>
struct RigidCorrection {
  using Vec = Eigen::Matrix<double, D, 1>;
  double mass_factor = 1;
  Vec velocity = Vec::Zero();        ///< a: added to every body's velocity
  Spin<D> omega = Spin<D>::Zero();   ///< w: rotation rate added about `centre` (and to each spin)
  Vec centre = Vec::Zero();          ///< X_c, the bodies' centre of mass

  /// The velocity increment of a body at x.
  Vec increment(const Vec& x) const { return velocity + skew<D>(omega) * (x - centre); }
};

/// The correction taking bodies with sums `current` (inertia about `reference`) to carry
/// exactly target's mass, momentum and angular momentum (derivation above). Needs
/// current and target masses > 0 and bodies with some inertia about their centre.
template <int D>
RigidCorrection<D> rigid_correction(const BodySums<D>& current, const CellMoments<D>& target,
                                    const Eigen::Matrix<double, D, 1>& reference) {
  using Vec = Eigen::Matrix<double, D, 1>;
  using Mat = Eigen::Matrix<double, D, D>;
  const CellMoments<D>& c = current.moments;
  RigidCorrection<D> r;
  r.mass_factor = target.mass / c.mass;
  r.centre = c.first_moment() / c.mass;
  // Inertia about the centre of mass (parallel axis), then scaled with the masses.
  const Vec d = r.centre - reference;
  Mat J = current.inertia();
  if constexpr (D == 2)
    J(0, 0) -= c.mass * d.squaredNorm();
  else
    J -= c.mass * (d.squaredNorm() * Mat::Identity() - d * d.transpose());
  J *= r.mass_factor;
  r.velocity = (target.momentum() - r.mass_factor * c.momentum()) / target.mass;
  const Spin<D> dL = target.angular() - r.mass_factor * c.angular() - cross<D>(r.centre, Vec(target.mass * r.velocity));
  r.omega = rotation_rate<D>(J, dL);
  return r;
}

template <int D>
struct NewPoint {
  Eigen::Matrix<double, D, 1> x, v;
  Eigen::Matrix<double, D, D> C;
  Eigen::Matrix<double, D, D> stress;
  double mass, volume;
};

// Cells: the cell with lower corner node c, c in [0, dims-1) per axis, is
// numbered row-major (last axis fastest) like GridGeometry::index.
template <int D>
std::size_t num_cells(const GridGeometry<D>& grid) {
  std::size_t n = 1;
  for (int a = 0; a < D; ++a) n *= static_cast<std::size_t>(grid.dims[a] - 1);
  return n;
}
template <int D>
std::size_t cell_index(const GridGeometry<D>& grid, const Eigen::Matrix<int, D, 1>& c) {
  std::size_t k = static_cast<std::size_t>(c[0]);
  for (int a = 1; a < D; ++a) k = k * static_cast<std::size_t>(grid.dims[a] - 1) + static_cast<std::size_t>(c[a]);
  return k;
}
template <int D>
Eigen::Matrix<int, D, 1> cell_of(const GridGeometry<D>& grid, const Eigen::Matrix<double, D, 1>& x) {
  return grid.to_cell_units(x).array().floor().template cast<int>().matrix();
}
/// Whether cell coordinates c (as cell_of gives) name a cell of the grid.
template <int D>
bool cell_on_grid(const GridGeometry<D>& grid, const Eigen::Matrix<int, D, 1>& c) {
  return (c.array() >= 0).all() && (c.array() < grid.dims.array() - 1).all();
}
template <int D>
Eigen::Matrix<int, D, 1> cell_coords(const GridGeometry<D>& grid, std::size_t k) {
  Eigen::Matrix<int, D, 1> c;
  for (int a = D - 1; a >= 0; --a) {
    const auto n = static_cast<std::size_t>(grid.dims[a] - 1);
    c[a] = static_cast<int>(k % n);
    k /= n;
  }
  return c;
}
/// Calls f(flat cell index) for every cell within `reach` cells of cell c along each axis
/// (c included), clipped to the grid.
template <int D, class F>
void for_each_cell_within(const GridGeometry<D>& grid, const Eigen::Matrix<int, D, 1>& c, int reach, F&& f) {
  const int side = 2 * reach + 1;
  int span = 1;
  for (int a = 0; a < D; ++a) span *= side;
  for (int o = 0; o < span; ++o) {
    Eigen::Matrix<int, D, 1> cj;
    for (int a = 0, r = o; a < D; ++a, r /= side) cj[a] = c[a] + r % side - reach;
    if (cell_on_grid<D>(grid, cj)) f(cell_index<D>(grid, cj));
  }
}
template <int D>
Eigen::Matrix<double, D, 1> cell_center(const GridGeometry<D>& grid, const Eigen::Matrix<int, D, 1>& c) {
  return grid.origin + grid.dx * (c.template cast<double>().array() + 0.5).matrix();
}

/// per_axis^D points on a regular lattice in cell m.cell with equal masses,
/// carrying m's mass, centre of mass, momentum and angular momentum exactly. volume_share in
/// [0, 1] is the share of the cell the points fill (m already scaled by it):
/// volume = share dx^D / n, stress = m.stress_volume / (share dx^D), so the
/// points' sum of stress*volume is m.stress_volume and their stress is the
/// unscaled cell stress S/dx^D. Empty if m.mass <= 0.
///
/// The lattice starts with the prior affine field (v = G r_p, C = G; e.g. the grains' velocity
/// gradient) and takes the rigid correction onto m (APIC points have their own inertia dx^2/2 per
/// mass): v_p = G r_p + a + Omega x r_p, C_p = G + skew(Omega). G is the prior's gradient scaled
/// down where the points would carry more affine kinetic energy per mass (APIC's dx^2/4 |C|^2
/// with it) than the prior's bound (AffineMotion) and than Omega alone gives them.
/// The lattice fills the part of the cell inside the box [within_lo, within_hi] (the continuum's
/// container: a wall off the cell lattice must not get points behind it).
template <int D>
std::vector<NewPoint<D>> points_from_moments(
    const CellMoments<D>& m, const GridGeometry<D>& grid, int per_axis, double volume_share,
    const AffineMotion<D>& prior = {},
    const Eigen::Matrix<double, D, 1>& within_lo = Eigen::Matrix<double, D, 1>::Constant(-HUGE_VAL),
    const Eigen::Matrix<double, D, 1>& within_hi = Eigen::Matrix<double, D, 1>::Constant(HUGE_VAL)) {
  using Vec = Eigen::Matrix<double, D, 1>;
  using Mat = Eigen::Matrix<double, D, D>;
  if (!(m.mass > 0) || per_axis < 1) return {};
  int n = 1;
  for (int a = 0; a < D; ++a) n *= per_axis;
  const double cell_volume = std::pow(grid.dx, D);
  const Eigen::Matrix<int, D, 1> c = cell_coords(grid, static_cast<std::size_t>(m.cell));
  const Vec centre = cell_center(grid, c);
  Vec lower = grid.node_position(c), span = Vec::Constant(grid.dx);
  for (int a = 0; a < D; ++a) {
    const double lo = std::max(lower[a], within_lo[a]), hi = std::min(lower[a] + grid.dx, within_hi[a]);
    if (hi > lo) lower[a] = lo, span[a] = hi - lo;  // (a cell wholly outside keeps its lattice)
  }
  const Mat stress = volume_share > 0 ? Mat(m.stress_volume() / (volume_share * cell_volume)) : Mat(Mat::Zero());

  // The lattice is centred on m's centre of mass, drawn in to stay within the cell (its part inside
  // the container): made about the cell's centre instead, the points moved the material's centre
  // of mass by up to half a cell (a cell of grains at a free surface holds them at its bottom),
  // which the exact angular momentum turned into a spin (M dX x V over the lattice's inertia) and
  // gravity into potential energy, at every conversion.
  // The points keep a quarter of their spacing from the faces (half the lattice's own margin):
  // drawn onto a face, a point at a wall crossed it by round-off.
  const Vec box_centre = lower + 0.5 * span;
  const Vec half = 0.5 * (1 - 0.5 / per_axis) * span;
  const Vec com = (m.first_moment() / m.mass).cwiseMax(box_centre - half).cwiseMin(box_centre + half);
  std::vector<NewPoint<D>> points(static_cast<std::size_t>(n));
  for (int a = 0; a < D; ++a) {
    const double reach = 0.5 * span[a] * (1.0 - 1.0 / per_axis);  // the lattice's farthest offset
    const double draw = reach > 0 ? std::min(1.0, (half[a] - std::abs(com[a] - box_centre[a])) / reach) : 0.0;
    for (int p = 0; p < n; ++p) {
      int k = p;
      for (int b = D - 1; b > a; --b) k /= per_axis;
      points[p].x[a] = com[a] + draw * ((k % per_axis + 0.5) / per_axis - 0.5) * span[a];
    }
  }
  const double inertia = grid.dx * grid.dx / kQuadraticInverseInertia;  // APIC's, per mass and axis
  // The lattice with the prior field scaled by `scale`, corrected rigidly onto m; returns its
  // affine kinetic energy per mass (about its mean velocity, with APIC's part).
  auto lay = [&](double scale) {
    const Mat G = scale * prior.gradient;
    BodySums<D> at_rest;
    for (NewPoint<D>& pt : points) {
      pt.mass = m.mass / n;
      pt.v = G * (pt.x - centre);  // the prior field (the rigid correction below makes the sums exact)
      const Spin<D> spin = (pt.mass * inertia) * axial<D>(G);
      at_rest.add_body(pt.x, pt.v, pt.mass, spin, grid.dx * grid.dx / 2, Mat::Zero(), centre);
    }
    const RigidCorrection<D> fix = rigid_correction<D>(at_rest, m, centre);
    Vec mean = Vec::Zero();
    for (NewPoint<D>& pt : points) {
      pt.v += fix.increment(pt.x);
      pt.C = G + skew<D>(fix.omega);
      pt.stress = stress;
      pt.mass *= fix.mass_factor;
      pt.volume = volume_share * cell_volume / n;
      mean += pt.v / n;
    }
    double energy = 0;
    for (const NewPoint<D>& pt : points) energy += 0.5 * ((pt.v - mean).squaredNorm() + inertia * pt.C.squaredNorm()) / n;
    return energy;
  };
  // That energy is quadratic in the scale. The points take the largest scale up to 1 whose energy is
  // at most the prior's, or than what the rigid correction alone gives them (the material's angular
  // momentum, which the lattice carries with at least the bodies' inertia).
  const double full = lay(1.0);
  if (!(full > prior.energy_per_mass)) return points;
  const double none = lay(0.0), midway = lay(0.5);
  const double a2 = 2 * (full + none - 2 * midway), a1 = full - none - a2;
  const double target = std::max(prior.energy_per_mass, none);
  // the largest root of a2 s^2 + a1 s + (none - target) = 0 in [0, 1) (full > target >= none)
  double scale = 0;
  if (a2 > 0) scale = (-a1 + std::sqrt(std::max(0.0, a1 * a1 - 4 * a2 * (none - target)))) / (2 * a2);
  else if (a1 > 0) scale = (target - none) / a1;
  lay(std::clamp(scale, 0.0, 1.0));
  return points;
}

/// Sums of a set of points, with the APIC angular momentum; count = number of points.
template <int D>
CellMoments<D> moments_of_points(const std::vector<NewPoint<D>>& points, double dx, std::uint64_t cell = 0) {
  CellMoments<D> s;
  s.cell = cell;
  for (const NewPoint<D>& p : points) {
    s.count += 1;
    s.mass += p.mass;
    s.first_moment() += p.mass * p.x;
    s.momentum() += p.mass * p.v;
    s.angular() += point_angular_momentum<D>(p.x, p.v, p.C, p.mass, dx);
    s.stress_volume() += p.volume * p.stress;
  }
  return s;
}

}  // namespace coupler
