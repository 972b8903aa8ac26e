#pragma once
// Enrichment of one grid cell (docs/design.md section 5): the material points of a
// cell that turns discrete become grains carrying exactly the same mass,
// linear momentum and angular momentum. The opposite rule is conversion.hpp.
//
// Grains are cut from a PackingTemplate, a periodic, overlap-free, dense
// packing relaxed once in advance (make_packing_template). The template is
// tiled over the whole grid from grid.origin, so every cell cuts the same
// tiling and cells enriched together fit each other without overlaps. Grains
// already present nearby (neighbours) are respected by dropping the template
// grains that would overlap them: overlaps would inject elastic energy.
//
// Flow: the MPM side sums the cell's points into CellMoments
// (moments_of_points, APIC angular momentum), scales them by the share the
// grains take over, and calls grains_for_cell; an empty result means no grain
// fits and the caller keeps the points.
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <vector>

#include "coupler/conversion.hpp"
#include "coupler/grid_geometry.hpp"
#include "coupler/oracle.hpp"  // grain_volume

namespace coupler {

// ---------------------------------------------------------------------------------------
// 1. Packing template

/// A periodic packing of the box [0, side)^D, lengths in units of the mean
/// grain diameter (mean radius 0.5). Overlap-free including across the
/// periodic boundary, so it can be tiled.
template <int D>
struct PackingTemplate {
  using Vec = Eigen::Matrix<double, D, 1>;
  std::vector<Vec> x;          ///< centres, in [0, side)^D
  std::vector<double> radius;  ///< radii
  double side = 0;             ///< period per axis
};

/// Solid fraction the template is filled to: below random jamming of slightly
/// polydisperse disks (~0.84) and spheres (~0.64), so the relaxation below
/// finds an overlap-free state, and quickly (it slows sharply towards jamming).
template <int D>
constexpr double template_packing_fraction() {
  return D == 2 ? 0.82 : 0.60;
}
/// Minimum gap left between template grains, in mean diameters: survives
/// scaling and tiling round-off, so the tiled packing is strictly overlap-free.
inline constexpr double kTemplateGap = 1e-3;
/// Radius inflation while relaxing (> kTemplateGap / 2): the relaxation
/// converges only asymptotically, so it aims past the accepted gap.
inline constexpr double kTemplatePad = 2e-3;
/// Over-relaxation of the Gauss-Seidel pushes: about 5x fewer sweeps than 1 in
/// 3D; 1.9 and above oscillates.
inline constexpr double kTemplateOverRelaxation = 1.6;
/// Sweeps before a jammed relaxation drops a grain.
inline constexpr int kTemplateSweeps = 1000;

namespace detail {

/// Uniform in (0, 1) from mt19937 directly: std::uniform_real_distribution is
/// implementation-defined, and the template must be the same everywhere.
inline double unit_random(std::mt19937& rng) { return (static_cast<double>(rng()) + 0.5) / 4294967296.0; }

/// Minimum-image displacement in a periodic box (unique for |d| < side/2).
template <int D>
Eigen::Matrix<double, D, 1> periodic_delta(Eigen::Matrix<double, D, 1> d, double side) {
  for (int a = 0; a < D; ++a) d[a] -= side * std::round(d[a] / side);
  return d;
}

/// Periodic cell list: calls f(i, j) once for every pair i < j that may lie
/// closer than `cutoff` (all pairs if fewer than 3 cells fit per axis, since
/// then neighbour cells would repeat).
template <int D, class F>
void for_each_close_pair(const std::vector<Eigen::Matrix<double, D, 1>>& x, double side, double cutoff, F&& f) {
  const int n = static_cast<int>(x.size());
  int nc = static_cast<int>(std::floor(side / cutoff));
  if (nc < 3) {
    for (int i = 0; i < n; ++i)
      for (int j = i + 1; j < n; ++j) f(i, j);
    return;
  }
  int total = 1;
  for (int a = 0; a < D; ++a) total *= nc;
  std::vector<int> head(static_cast<std::size_t>(total), -1), next(static_cast<std::size_t>(n), -1);
  std::vector<Eigen::Matrix<int, D, 1>> cell(static_cast<std::size_t>(n));
  auto flat = [nc](const Eigen::Matrix<int, D, 1>& c) {
    int k = 0;
    for (int a = 0; a < D; ++a) k = k * nc + ((c[a] % nc) + nc) % nc;  // wraps periodically
    return k;
  };
  for (int i = 0; i < n; ++i) {
    for (int a = 0; a < D; ++a) cell[i][a] = std::min(nc - 1, std::max(0, static_cast<int>(x[i][a] / side * nc)));
    const int k = flat(cell[i]);
    next[i] = head[k];
    head[k] = i;
  }
  int offsets = 1;
  for (int a = 0; a < D; ++a) offsets *= 3;
  for (int i = 0; i < n; ++i)
    for (int o = 0; o < offsets; ++o) {
      Eigen::Matrix<int, D, 1> c = cell[i];
      for (int a = 0, r = o; a < D; ++a, r /= 3) c[a] += r % 3 - 1;
      for (int j = head[flat(c)]; j >= 0; j = next[j])
        if (j > i) f(i, j);
    }
}

}  // namespace detail

/// A dense periodic packing of side `side_in_diameters` (>= 3), radii uniform
/// in [0.5 (1 - p), 0.5 (1 + p)] with p = polydispersity in [0, 0.5),
/// deterministic in `seed` (also across platforms).
///
/// Method: radii are drawn until the grain volume reaches
/// template_packing_fraction() of the box, centres uniformly at random. The
/// overlaps are then removed by relaxing a soft repulsion (periodic, no
/// gravity) with Gauss-Seidel projection: each overlapping pair is pushed
/// apart along its line of centres, both grains by half the overlap times
/// kTemplateOverRelaxation. Radii are inflated by kTemplatePad while relaxing;
/// it stops when a fresh check finds no inflated overlap above
/// 2 kTemplatePad - kTemplateGap, so real gaps are >= kTemplateGap > 0.
/// Small boxes can jam (few grains cannot rearrange): after every
/// kTemplateSweeps sweeps without convergence the grain of the worst overlap
/// is dropped, which lowers the fraction slightly; it does not happen for the
/// 10x10 and 6x6x6 templates.
template <int D>
PackingTemplate<D> make_packing_template(double side_in_diameters, double polydispersity, std::uint32_t seed) {
  using Vec = Eigen::Matrix<double, D, 1>;
  static_assert(D == 2 || D == 3, "2D or 3D");
  const double side = side_in_diameters;
  // side >= 3 > 2 * largest diameter keeps the minimum image unique.
  if (!(side >= 3)) throw std::invalid_argument("make_packing_template: side must be >= 3 mean diameters");
  if (!(polydispersity >= 0 && polydispersity < 0.5))
    throw std::invalid_argument("make_packing_template: polydispersity must be in [0, 0.5)");

  PackingTemplate<D> t;
  t.side = side;
  std::mt19937 rng(seed);
  const double target = template_packing_fraction<D>() * std::pow(side, D);
  for (double volume = 0; volume < target;) {
    const double r = 0.5 * (1 + polydispersity * (2 * detail::unit_random(rng) - 1));
    Vec x;
    for (int a = 0; a < D; ++a) x[a] = side * detail::unit_random(rng);
    t.x.push_back(x);
    t.radius.push_back(r);
    volume += grain_volume<D>(r);
  }

  const double tol = 2 * kTemplatePad - kTemplateGap;  // accepted overlap of the inflated radii
  const double cutoff = 2 * (0.5 * (1 + polydispersity) + kTemplatePad);
  auto overlap = [&](int i, int j, Vec& n) {
    const Vec d = detail::periodic_delta<D>(t.x[j] - t.x[i], side);
    const double dist = d.norm();
    n = dist > 1e-12 ? Vec(d / dist) : Vec(Vec::Unit(0));  // coincident centres: any direction
    return t.radius[i] + t.radius[j] + 2 * kTemplatePad - dist;
  };
  auto wrap = [&](Vec& x) {
    for (int a = 0; a < D; ++a) {
      x[a] -= side * std::floor(x[a] / side);
      if (x[a] >= side) x[a] = 0;  // -tiny wraps to side after round-off
    }
  };
  for (int sweep = 1;; ++sweep) {
    double worst = 0;
    int worst_grain = -1;
    detail::for_each_close_pair<D>(t.x, side, cutoff, [&](int i, int j) {
      Vec n;
      const double ov = overlap(i, j, n);
      if (ov <= 0) return;
      if (ov > worst) worst = ov, worst_grain = i;
      const double push = 0.5 * kTemplateOverRelaxation * ov;
      t.x[i] -= push * n;
      t.x[j] += push * n;
    });
    for (Vec& x : t.x) wrap(x);
    if (worst < tol) {
      // The sweep moved grains after measuring: confirm on the final positions.
      double check = 0;
      detail::for_each_close_pair<D>(t.x, side, cutoff, [&](int i, int j) {
        Vec n;
        check = std::max(check, overlap(i, j, n));
      });
      if (check < tol) return t;
    }
    if (sweep % kTemplateSweeps == 0 && worst_grain >= 0) {  // jammed: make room
      t.x.erase(t.x.begin() + worst_grain);
      t.radius.erase(t.radius.begin() + worst_grain);
    }
  }
}

// ---------------------------------------------------------------------------------------
// 2. Grains for a cell

template <int D>
struct NewGrain {
  Eigen::Matrix<double, D, 1> x, v;
  Spin<D> omega;  ///< angular velocity (2D: z component)
  double radius, mass;
};

/// Where in a cell its material points are: the cell split into kOccupancyDivisions^D
/// sub-cells, one bit each (64 bits hold 4^3). New grains go only into occupied sub-cells,
/// so a half-full cell near the free surface is not filled up with light grains.
inline constexpr int kOccupancyDivisions = 4;
using Occupancy = std::uint64_t;

/// Bit of the sub-cell of cell c that holds x (x inside the cell).
template <int D>
Occupancy occupancy_bit(const GridGeometry<D>& grid, const Eigen::Matrix<int, D, 1>& c,
                        const Eigen::Matrix<double, D, 1>& x) {
  int bit = 0;
  for (int a = 0; a < D; ++a) {
    const int s = static_cast<int>(std::floor((grid.to_cell_units(x)[a] - c[a]) * kOccupancyDivisions));
    bit = bit * kOccupancyDivisions + std::clamp(s, 0, kOccupancyDivisions - 1);
  }
  return Occupancy{1} << bit;
}

/// Marks the sub-cells of cell c whose centres lie within the cube of side `side` centred
/// at x (a point's own volume, side = V^(1/D)).
template <int D>
Occupancy occupancy_of_point(const GridGeometry<D>& grid, const Eigen::Matrix<int, D, 1>& c,
                             const Eigen::Matrix<double, D, 1>& x, double side) {
  Occupancy mask = 0;
  const Eigen::Matrix<double, D, 1> lower = grid.node_position(c);
  const double sub = grid.dx / kOccupancyDivisions;
  int total = 1;
  for (int a = 0; a < D; ++a) total *= kOccupancyDivisions;
  for (int bit = 0; bit < total; ++bit) {
    bool inside = true;
    for (int a = D - 1, r = bit; a >= 0; --a, r /= kOccupancyDivisions) {
      const double centre = lower[a] + (r % kOccupancyDivisions + 0.5) * sub;
      inside = inside && std::abs(centre - x[a]) <= 0.5 * side;
    }
    if (inside) mask |= Occupancy{1} << bit;
  }
  return mask | occupancy_bit<D>(grid, c, x);  // at least its own sub-cell
}

/// The template grains, scaled by mean_diameter and tiled from grid.origin, whose centre lies
/// in cell `cell` (cell_of), at rest and massless. Every cell cuts the same tiling, so the
/// candidates of neighbouring cells never overlap each other.
template <int D>
std::vector<NewGrain<D>> template_candidates(std::size_t cell, const GridGeometry<D>& grid,
                                             const PackingTemplate<D>& tmpl, double mean_diameter) {
  using Vec = Eigen::Matrix<double, D, 1>;
  using IVec = Eigen::Matrix<int, D, 1>;
  if (!(mean_diameter > 0) || !(tmpl.side > 0))
    throw std::invalid_argument("template_candidates: diameter and side must be > 0");
  // Template tiles overlapping the cell: tile k covers origin + L [k, k + 1).
  const IVec c = cell_coords(grid, cell);
  const double L = tmpl.side * mean_diameter;
  IVec k_lo, k_hi;
  for (int a = 0; a < D; ++a) {
    k_lo[a] = static_cast<int>(std::floor(c[a] * grid.dx / L)) - 1;  // -1, +1: margin for round-off
    k_hi[a] = static_cast<int>(std::floor((c[a] + 1) * grid.dx / L)) + 1;
  }
  int tiles = 1;
  for (int a = 0; a < D; ++a) tiles *= k_hi[a] - k_lo[a] + 1;

  std::vector<NewGrain<D>> grains;
  for (int tile = 0; tile < tiles; ++tile) {
    IVec k;
    for (int a = D - 1, r = tile; a >= 0; --a) {
      const int n = k_hi[a] - k_lo[a] + 1;
      k[a] = k_lo[a] + r % n;
      r /= n;
    }
    const Vec shift = grid.origin + L * k.template cast<double>();
    for (std::size_t i = 0; i < tmpl.x.size(); ++i) {
      // The same expression in every cell, so neighbouring cells agree on the tiling.
      const Vec x = shift + mean_diameter * tmpl.x[i];
      if (cell_of(grid, x) != c) continue;
      NewGrain<D> g;
      g.x = x;
      g.v.setZero();
      g.omega.setZero();
      g.radius = mean_diameter * tmpl.radius[i];
      g.mass = 0;
      grains.push_back(g);
    }
  }
  return grains;
}

/// Gives `grains` (positions and radii set) masses and velocities that carry exactly
/// target's mass, linear momentum and angular momentum (about the origin, orbital + spin).
/// Masses m_g = f * solid_density * volume_g with one common f (written to *density_factor
/// if given): the kept grains' solid mass rarely equals the target's. Velocities: the prior
/// affine field `gradient` (e.g. the continuum's velocity gradient) about the grains' centre
/// of mass, then the rigid correction (conversion.hpp) onto the target, so that spin and
/// orbital parts add up exactly; spin inertia inertia_factor m r^2 (0.5 disk, 0.4 ball).
/// Empty input or target.mass <= 0: returns false and leaves grains unchanged.
template <int D>
bool set_grain_moments(std::vector<NewGrain<D>>& grains, const CellMoments<D>& target, const GridGeometry<D>& grid,
                       double solid_density, double inertia_factor,
                       const Eigen::Matrix<double, D, D>& gradient = Eigen::Matrix<double, D, D>::Zero(),
                       double* density_factor = nullptr) {
  using Vec = Eigen::Matrix<double, D, 1>;
  using Mat = Eigen::Matrix<double, D, D>;
  if (!(solid_density > 0) || !(inertia_factor > 0))
    throw std::invalid_argument("set_grain_moments: density and inertia factor must be > 0");
  if (density_factor) *density_factor = 0;
  if (grains.empty() || !(target.mass > 0)) return false;
  double M = 0;
  Vec first = Vec::Zero();
  for (NewGrain<D>& g : grains) {
    g.mass = solid_density * grain_volume<D>(g.radius);
    M += g.mass;
    first += g.mass * g.x;
  }
  const Vec centre = first / M;
  const Vec reference = cell_center(grid, cell_coords(grid, static_cast<std::size_t>(target.cell)));
  BodySums<D> sums;
  for (NewGrain<D>& g : grains) {
    g.v = gradient * (g.x - centre);
    g.omega.setZero();
    sums.add_body(g.x, g.v, g.mass, Spin<D>::Zero(), inertia_factor * g.radius * g.radius, Mat::Zero(), reference);
  }
  const RigidCorrection<D> fix = rigid_correction<D>(sums, target, reference);
  for (NewGrain<D>& g : grains) {
    g.mass *= fix.mass_factor;
    g.v += fix.increment(g.x);
    g.omega += fix.omega;
  }
  if (density_factor) *density_factor = fix.mass_factor;
  return true;
}

/// Grains for cell target.cell carrying exactly target's mass, linear momentum and angular
/// momentum: the template candidates of the cell that overlap none of the existing grains
/// (neighbour_x, neighbour_r; overlaps would inject elastic energy), with set_grain_moments
/// (no prior field: a rigid motion). Empty if target.mass <= 0 or no grain fits: the
/// caller then keeps the points. The centre of mass follows from the template, not from
/// target: it moves at most within the cell.
template <int D>
std::vector<NewGrain<D>> grains_for_cell(const CellMoments<D>& target, const GridGeometry<D>& grid,
                                         const PackingTemplate<D>& tmpl, double mean_diameter, double solid_density,
                                         const std::vector<Eigen::Matrix<double, D, 1>>& neighbour_x,
                                         const std::vector<double>& neighbour_r, double inertia_factor,
                                         double* density_factor = nullptr) {
  if (neighbour_x.size() != neighbour_r.size())
    throw std::invalid_argument("grains_for_cell: neighbour_x and neighbour_r differ in size");
  if (!(mean_diameter > 0) || !(solid_density > 0) || !(inertia_factor > 0) || !(tmpl.side > 0))
    throw std::invalid_argument("grains_for_cell: diameter, density, inertia factor and side must be > 0");
  if (density_factor) *density_factor = 0;
  if (!(target.mass > 0)) return {};
  std::vector<NewGrain<D>> grains;
  for (const NewGrain<D>& g : template_candidates<D>(static_cast<std::size_t>(target.cell), grid, tmpl, mean_diameter)) {
    bool free = true;
    for (std::size_t j = 0; j < neighbour_x.size() && free; ++j) {
      const double reach = g.radius + neighbour_r[j];
      free = (g.x - neighbour_x[j]).squaredNorm() >= reach * reach;
    }
    if (free) grains.push_back(g);
  }
  set_grain_moments<D>(grains, target, grid, solid_density, inertia_factor,
                       Eigen::Matrix<double, D, D>::Zero(), density_factor);
  return grains;
}

}  // namespace coupler
