#pragma once
// The zone oracle of the adaptive hybrid method (docs/design.md section 5): from the grains and
// material points it decides, per grid cell, which cells are discrete, hybrid or continuum.
//
//   1. packing fraction phi per cell: grain volumes summed per cell (additive, so partial
//      sums of several DEM ranks can be added), 1 in cells holding material points;
//   2. material = phi >= surface_packing; signed distance of each cell centre to the free
//      surface (and to walls / intruders, passed as boundary cells), by an exact Euclidean
//      distance transform; faces of the container the continuum may touch are no surface
//      (the cells beyond them count as material and stay discrete: box_cells); below a free
//      surface the depth may differ from the margin at walls and discrete regions (zone_distance);
//   3. zones from the distance with the band [L - h, L + h] and the previous zones, so that a
//      cell always passes through hybrid and does not flicker; hybrid only near a continuum.
//
// Cells are numbered as in conversion.hpp (num_cells, cell_index, ...). No LAMMPS types.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include "coupler/conversion.hpp"
#include "coupler/grid_geometry.hpp"
#include "coupler/zones.hpp"

namespace coupler {

struct OracleSettings {
  double surface_packing = 0.3;  ///< free surface where phi crosses this (reference method: 0.3)
  double continuum_depth = 0;    ///< L: continuum where the distance to surface/walls exceeds L + h
  double band = 0;               ///< h: discrete below L - h, hybrid in between
  // Optional extra criteria, off when <= 0:
  double dilute_packing = 0;  ///< cells with phi below this are discrete
  double max_shear_rate = 0;  ///< cells whose shear rate exceeds this are discrete
  /// L_s: the depth below a free surface (not a wall or discrete region); <= 0: L (zone_distance)
  double surface_depth = 0;
  /// 1: cells whose material is at rest keep their zones (hold_zones_at_rest); 0: off
  double rest_hold = 1;
  /// The depth below free surfaces in use (L_s, or L where none is set).
  double free_surface_depth() const { return surface_depth > 0 ? surface_depth : continuum_depth; }
};
static_assert(std::is_trivially_copyable_v<OracleSettings>, "OracleSettings is sent over MPI as bytes");

// ---------------------------------------------------------------------------------------
// 1. Packing fraction

/// Volume of one grain: disk area in 2D (LAMMPS 2D spheres act as disks), ball volume in 3D.
template <int D>
double grain_volume(double radius) {
  static_assert(D == 2 || D == 3, "2D or 3D");
  constexpr double kPi = 3.14159265358979323846;
  return D == 2 ? kPi * radius * radius : 4.0 / 3.0 * kPi * radius * radius * radius;
}
/// The same for a dimension known at run time (a host's `domain->dimension`).
inline double grain_volume(int dimension, double radius) {
  return dimension == 2 ? grain_volume<2>(radius) : grain_volume<3>(radius);
}

/// Adds `volume` to the cell holding the grain centre x (the whole grain counts in the cell of
/// its centre: cheap, additive, and exact on average over a cell). cell_volume is sized on
/// first use. Returns false (adds nothing) if x is off the grid.
template <int D>
bool add_grain_volume(const GridGeometry<D>& grid, const Eigen::Matrix<double, D, 1>& x, double volume,
                      std::vector<double>& cell_volume) {
  const std::size_t n = num_cells(grid);
  if (cell_volume.empty()) cell_volume.assign(n, 0.0);
  if (cell_volume.size() != n) throw std::invalid_argument("add_grain_volume: cell_volume has the wrong size");
  const Eigen::Matrix<int, D, 1> c = cell_of(grid, x);
  if (!cell_on_grid(grid, c)) return false;
  cell_volume[cell_index(grid, c)] += volume;
  return true;
}

/// add_grain_volume for grains with centres x[i] and radii radius[i].
template <int D>
void add_grain_volumes(const GridGeometry<D>& grid, const std::vector<Eigen::Matrix<double, D, 1>>& x,
                       const std::vector<double>& radius, std::vector<double>& cell_volume) {
  if (x.size() != radius.size()) throw std::invalid_argument("add_grain_volumes: x and radius differ in size");
  if (cell_volume.empty()) cell_volume.assign(num_cells(grid), 0.0);
  for (std::size_t i = 0; i < x.size(); ++i) add_grain_volume<D>(grid, x[i], grain_volume<D>(radius[i]), cell_volume);
}

/// Flags the cell holding the material point at x (for packing_fraction). Sized on first use.
template <int D>
void mark_point_cell(const GridGeometry<D>& grid, const Eigen::Matrix<double, D, 1>& x,
                     std::vector<std::uint8_t>& has_points) {
  if (has_points.empty()) has_points.assign(num_cells(grid), 0);
  const Eigen::Matrix<int, D, 1> c = cell_of(grid, x);
  if (!cell_on_grid(grid, c)) return;
  has_points[cell_index(grid, c)] = 1;
}

/// phi per cell: summed grain volume over the cell volume, clamped to [0, 1]; 1 where the
/// cell holds material points (continuum material is dense by definition). Either input may
/// be empty (no grains / no points).
template <int D>
std::vector<double> packing_fraction(const GridGeometry<D>& grid, const std::vector<double>& grain_volume_per_cell,
                                     const std::vector<std::uint8_t>& has_points) {
  const std::size_t n = num_cells(grid);
  if ((!grain_volume_per_cell.empty() && grain_volume_per_cell.size() != n) ||
      (!has_points.empty() && has_points.size() != n))
    throw std::invalid_argument("packing_fraction: input of the wrong size");
  const double inv_cell = 1.0 / std::pow(grid.dx, D);
  std::vector<double> phi(n, 0.0);
  for (std::size_t c = 0; c < n; ++c) {
    if (!has_points.empty() && has_points[c])
      phi[c] = 1;
    else if (!grain_volume_per_cell.empty())
      phi[c] = std::clamp(grain_volume_per_cell[c] * inv_cell, 0.0, 1.0);
  }
  return phi;
}

// ---------------------------------------------------------------------------------------
// 2. Signed distance

namespace oracle_detail {
/// 1D squared distance transform (Felzenszwalb & Huttenlocher 2012): d[p] = min_q (p-q)^2 + f[q]
/// over the lower envelope of parabolas. f may hold +inf (no site); d is +inf if all are.
/// v, z: scratch of size n and n + 1.
inline void edt_1d(const double* f, double* d, int n, std::vector<int>& v, std::vector<double>& z) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  int k = -1;
  for (int q = 0; q < n; ++q) {
    if (f[q] == kInf) continue;  // skipping empty sites keeps inf out of the intersection formula
    if (k < 0) {
      k = 0, v[0] = q, z[0] = -kInf, z[1] = kInf;
      continue;
    }
    double s;
    for (;;) {  // pop parabolas hidden by the new one; z[0] = -inf stops at k = 0
      const int r = v[k];
      s = ((f[q] + double(q) * q) - (f[r] + double(r) * r)) / (2.0 * (q - r));
      if (s <= z[k]) --k; else break;
    }
    ++k, v[k] = q, z[k] = s, z[k + 1] = kInf;
  }
  if (k < 0) {
    std::fill(d, d + n, kInf);
    return;
  }
  k = 0;
  for (int p = 0; p < n; ++p) {
    while (z[k + 1] < p) ++k;
    const double dp = p - v[k];
    d[p] = dp * dp + f[v[k]];
  }
}
}  // namespace oracle_detail

/// Exact squared Euclidean distance, in cell units, from each cell centre to the nearest
/// centre of a `source` cell (+inf if there is none), on a row-major grid of `cells` cells per
/// axis (last axis fastest). Separable: one 1D transform per axis, O(cells * D).
template <int D>
std::vector<double> squared_distance_transform(const Eigen::Matrix<int, D, 1>& cells,
                                               const std::vector<std::uint8_t>& source) {
  std::size_t n = 1;
  for (int a = 0; a < D; ++a) n *= static_cast<std::size_t>(cells[a]);
  if (source.size() != n) throw std::invalid_argument("squared_distance_transform: mask of the wrong size");
  std::vector<double> g(n);
  for (std::size_t c = 0; c < n; ++c) g[c] = source[c] ? 0.0 : std::numeric_limits<double>::infinity();
  const int longest = cells.maxCoeff();
  std::vector<double> line(longest), out(longest), z(longest + 1);
  std::vector<int> v(longest);
  for (int a = 0; a < D; ++a) {
    std::size_t stride = 1;
    for (int b = D - 1; b > a; --b) stride *= static_cast<std::size_t>(cells[b]);
    const int len = cells[a];
    // Lines along axis a start at every cell whose coordinate a is 0.
    for (std::size_t start = 0; start < n; ++start) {
      if ((start / stride) % static_cast<std::size_t>(len) != 0) continue;
      for (int i = 0; i < len; ++i) line[i] = g[start + i * stride];
      oracle_detail::edt_1d(line.data(), out.data(), len, v, z);
      for (int i = 0; i < len; ++i) g[start + i * stride] = out[i];
    }
  }
  return g;
}

/// Cells whose centre lies outside the box [lower, upper] (the padding of padded_grid, or the
/// part of the box beyond the continuum's container), by the faces they lie beyond:
///   boundary: beyond a face the oracle counts as a surface of the material (a discrete
///             boundary: an orifice's floor, a blade). Pass them to signed_distance as boundary
///             cells: the material is kept depth + band away from that face;
///   solid:    beyond faces the continuum may touch only (bits of `touched`, face_bit; a floor or
///             wall whose continuum wall law stands for the DEM wall). They count as material for
///             the distance, so that they do not pull it down (the continuum reaches the face),
///             and are always discrete: they hold nothing (solid_material, keep_solid_outside).
/// A cell beyond a touched and an untouched face (a corner) is a boundary cell.
struct BoxCells {
  std::vector<std::uint8_t> boundary, solid;
  /// Cell c is a boundary of the material whatever face it lies beyond (a cell of a discrete
  /// region: it wins over a touched face, e.g. the orifice in a silo floor the continuum touches).
  void add_boundary(std::size_t c) { boundary.at(c) = 1, solid.at(c) = 0; }
};

template <int D>
BoxCells box_cells(const GridGeometry<D>& grid, const Eigen::Matrix<double, D, 1>& lower,
                   const Eigen::Matrix<double, D, 1>& upper, std::uint32_t touched) {
  const std::size_t n = num_cells(grid);
  BoxCells out;
  out.boundary.assign(n, 0);
  out.solid.assign(n, 0);
  for (std::size_t c = 0; c < n; ++c) {
    const auto x = cell_center(grid, cell_coords(grid, c));
    bool beyond_touched = false, beyond_surface = false;
    for (int a = 0; a < D; ++a)
      for (int side = 0; side < 2; ++side) {
        if (!(side ? x[a] > upper[a] : x[a] < lower[a])) continue;
        (touched & face_bit(a, side) ? beyond_touched : beyond_surface) = true;
      }
    out.boundary[c] = beyond_surface;
    out.solid[c] = beyond_touched && !beyond_surface;
  }
  return out;
}

/// The boundary cells of box_cells with every face a surface: pass them to signed_distance so
/// that the walls of the box act as surfaces.
template <int D>
std::vector<std::uint8_t> cells_outside_box(const GridGeometry<D>& grid, const Eigen::Matrix<double, D, 1>& lower,
                                            const Eigen::Matrix<double, D, 1>& upper) {
  return box_cells<D>(grid, lower, upper, 0).boundary;
}

/// The material of the oracle: cells packed at least to surface_packing, and the solid cells
/// beyond faces the continuum may touch (may be empty: none).
inline std::vector<std::uint8_t> solid_material(const std::vector<double>& packing, double surface_packing,
                                                const std::vector<std::uint8_t>& solid) {
  if (!solid.empty() && solid.size() != packing.size())
    throw std::invalid_argument("solid_material: mask of the wrong size");
  std::vector<std::uint8_t> material(packing.size());
  for (std::size_t c = 0; c < material.size(); ++c)
    material[c] = packing[c] >= surface_packing || (!solid.empty() && solid[c]);
  return material;
}

/// Solid cells (beyond faces the continuum may touch) are no place for material, whatever their
/// distance: it is set to -inf after the distance transform, so that they are discrete zones
/// (they hold nothing: no points behind the wall, and grains that cross the face, e.g. under a
/// silo floor, stay grains) and want no continuum (a hybrid cell by a touched wall still needs a
/// real continuum near to stay hybrid, next_zones).
inline void keep_solid_outside(std::vector<double>& distance, const std::vector<std::uint8_t>& solid) {
  if (solid.empty()) return;
  if (solid.size() != distance.size()) throw std::invalid_argument("keep_solid_outside: mask of the wrong size");
  for (std::size_t c = 0; c < distance.size(); ++c)
    if (solid[c]) distance[c] = -std::numeric_limits<double>::infinity();
}

namespace oracle_detail {
/// Distance in length units from each cell centre to the nearest centre of a `source` cell,
/// less half a cell (the surface lies half way between centres); +inf if there is none.
template <int D>
std::vector<double> distance_to_cells(const GridGeometry<D>& grid, const std::vector<std::uint8_t>& source) {
  std::vector<double> d = squared_distance_transform<D>(grid.dims.array() - 1, source);
  for (double& v : d) v = (std::sqrt(v) - 0.5) * grid.dx;
  return d;
}
}  // namespace oracle_detail

/// Signed distance, in length units, from each cell centre to the surface of the material.
/// Sign convention: positive inside (cell is `material` and not a boundary cell), negative
/// outside; never zero. Boundary cells (walls, intruders, box padding; may be empty) count as
/// outside, so material next to them is near a surface: grains are wanted there too.
///
/// The surface is taken half way between an inside and an outside cell centre, so
///   inside:  d = (|nearest outside centre| - dx/2),   outside: d = -(|nearest inside centre| - dx/2),
/// exact for surfaces on cell faces and within about half a cell otherwise. +inf if there is
/// no outside cell at all (-inf if no inside cell); the grid edge itself is not a surface.
template <int D>
std::vector<double> signed_distance(const GridGeometry<D>& grid, const std::vector<std::uint8_t>& material,
                                    const std::vector<std::uint8_t>& boundary_cells) {
  const std::size_t n = num_cells(grid);
  if (material.size() != n || (!boundary_cells.empty() && boundary_cells.size() != n))
    throw std::invalid_argument("signed_distance: mask of the wrong size");
  std::vector<std::uint8_t> inside(n), outside(n);
  for (std::size_t c = 0; c < n; ++c) {
    inside[c] = material[c] && (boundary_cells.empty() || !boundary_cells[c]);
    outside[c] = !inside[c];
  }
  const std::vector<double> to_outside = oracle_detail::distance_to_cells<D>(grid, outside);
  const std::vector<double> to_inside = oracle_detail::distance_to_cells<D>(grid, inside);
  std::vector<double> d(n);
  for (std::size_t c = 0; c < n; ++c) d[c] = inside[c] ? to_outside[c] : -to_inside[c];
  return d;
}

/// The distance the zones are taken from (update_zones' thresholds L -+ h): signed_distance of
/// the material (packing at least surface_packing, and the solid cells beyond faces the
/// continuum may touch) with boundary cells as outside, solid cells at -inf (keep_solid_outside).
/// With a surface depth L_s other than L (OracleSettings::surface_depth), a free surface
/// (material next to a cell that is neither material nor boundary) wants the continuum L_s + h
/// below it while walls and discrete regions keep it L + h away: inside cells take
///   min(d_free + L - L_s, d_boundary),
/// which is signed_distance where L_s = L (min of the distances to the two kinds of outside
/// cell). A silo's surface descends slowly, while the orifice's converging flow needs its margin.
template <int D>
std::vector<double> zone_distance(const GridGeometry<D>& grid, const std::vector<double>& packing,
                                  const std::vector<std::uint8_t>& boundary_cells,
                                  const std::vector<std::uint8_t>& solid_cells, const OracleSettings& s) {
  const auto material = solid_material(packing, s.surface_packing, solid_cells);
  std::vector<double> d = signed_distance<D>(grid, material, boundary_cells);
  const double shift = s.continuum_depth - s.free_surface_depth();
  if (shift != 0.0) {
    const std::size_t n = d.size();
    std::vector<std::uint8_t> free(n), boundary(n, 0);
    for (std::size_t c = 0; c < n; ++c) {
      boundary[c] = !boundary_cells.empty() && boundary_cells[c];
      free[c] = !material[c] && !boundary[c];
    }
    const std::vector<double> to_free = oracle_detail::distance_to_cells<D>(grid, free);
    const std::vector<double> to_boundary = oracle_detail::distance_to_cells<D>(grid, boundary);
    for (std::size_t c = 0; c < n; ++c)
      if (d[c] > 0) d[c] = std::min(to_free[c] + shift, to_boundary[c]);
  }
  keep_solid_outside(d, solid_cells);
  return d;
}

// ---------------------------------------------------------------------------------------
// 3. Zones

/// New zone per cell from the previous zones (empty: all discrete, the start of a run), the
/// signed distance, and optionally the packing (needed if dilute_packing > 0) and shear rate
/// per cell (needed if max_shear_rate > 0; may be empty otherwise).
///
/// Target zone, with lo = L - h, hi = L + h ("forced": an extra criterion fires):
///   forced or d < lo -> discrete;  lo <= d <= hi -> hybrid;  d > hi -> continuum.
/// A cell moves at most one step towards its target per update:
///
///   previous \ target | discrete   hybrid   continuum
///   discrete          | discrete   hybrid   hybrid      (never discrete -> continuum)
///   hybrid            | discrete   hybrid   continuum
///   continuum         | hybrid     hybrid   continuum   (never continuum -> discrete)
///
/// The hybrid band is the hysteresis: going from discrete to continuum takes d > hi, going
/// back takes d < lo, so a distance oscillating inside [lo, hi] leaves hybrid cells hybrid,
/// and (as continuum needs d > hi, discrete d < lo or forcing) a continuum cell is never
/// next to a discrete one when 2h exceeds the distance between neighbouring centres
/// (h > sqrt(D)/2 dx), except next to cells forced discrete by the extra criteria.
inline std::vector<std::int8_t> update_zones(const std::vector<std::int8_t>& previous,
                                             const std::vector<double>& distance, const std::vector<double>& packing,
                                             const std::vector<double>& shear_rate, const OracleSettings& s) {
  const std::size_t n = distance.size();
  const bool dilute = s.dilute_packing > 0, shear = s.max_shear_rate > 0;
  if ((!previous.empty() && previous.size() != n) || (dilute && packing.size() != n) ||
      (shear && shear_rate.size() != n))
    throw std::invalid_argument("update_zones: input of the wrong size");
  const double lo = s.continuum_depth - s.band, hi = s.continuum_depth + s.band;
  std::vector<std::int8_t> zones(n);
  for (std::size_t c = 0; c < n; ++c) {
    const bool forced = (dilute && packing[c] < s.dilute_packing) || (shear && shear_rate[c] > s.max_shear_rate);
    const int target =
        (forced || distance[c] < lo) ? int{kDiscrete} : (distance[c] > hi ? int{kContinuum} : int{kHybrid});
    const int prev = previous.empty() ? int{kDiscrete} : int{previous[c]};
    zones[c] = static_cast<std::int8_t>(std::clamp(target, prev - 1, prev + 1));  // one step at most
  }
  return zones;
}

/// Hybrid cells with no cell wanting continuum (distance > L + h) within the band's width
/// 2h + sqrt(D) dx turn discrete. The hybrid band blends grains into a continuum; where the
/// material is too thin for any continuum (a deposit come to rest, the end of a discharge) a
/// hybrid cell's points rest on nothing but the velocity agreement with the grains, and they
/// creep down through them (measured in a collapse: points sinking 4 mm/s faster than the grains
/// after the DEM's rest time, the creep holding the deposit at 50x the rest threshold).
template <int D>
void drop_hybrid_without_continuum(const GridGeometry<D>& grid, const std::vector<double>& distance,
                                   const OracleSettings& s, std::vector<std::int8_t>& zones) {
  const std::size_t n = zones.size();
  if (distance.size() != n) throw std::invalid_argument("drop_hybrid_without_continuum: input of the wrong size");
  const double hi = s.continuum_depth + s.band;
  std::vector<std::uint8_t> wants_continuum(n);
  bool any = false;
  for (std::size_t c = 0; c < n; ++c) any |= (wants_continuum[c] = distance[c] > hi) != 0;
  const double reach = 2.0 * s.band / grid.dx + std::sqrt(static_cast<double>(D));  // in cells
  std::vector<double> to_continuum;
  if (any) to_continuum = squared_distance_transform<D>(grid.dims.array() - 1, wants_continuum);
  for (std::size_t c = 0; c < n; ++c)
    if (zones[c] == kHybrid && (!any || to_continuum[c] > reach * reach)) zones[c] = kDiscrete;
}

/// Per cell: no material, or material moving with a mean square speed (kinetic energy over mass,
/// grains and points together) below rest_speed^2.
inline std::vector<std::uint8_t> material_still(const std::vector<double>& kinetic, const std::vector<double>& mass,
                                                double rest_speed) {
  if (kinetic.size() != mass.size()) throw std::invalid_argument("material_still: input of the wrong size");
  const double limit = 0.5 * rest_speed * rest_speed;  // kinetic energy per unit mass
  std::vector<std::uint8_t> still(mass.size());
  for (std::size_t c = 0; c < mass.size(); ++c) still[c] = mass[c] <= 0 || kinetic[c] < limit * mass[c];
  return still;
}

/// Whether the material of cell `c` is at rest: it and each of its 3^D neighbours are still
/// (material_still). The neighbours count so that material about to arrive (an avalanche reaching
/// a resting cell) keeps a cell from being held.
template <int D>
bool still_around(const GridGeometry<D>& grid, const std::vector<std::uint8_t>& still, std::uint64_t c) {
  bool all = still[c] != 0;
  if (all) for_each_cell_within<D>(grid, cell_coords<D>(grid, c), 1, [&](std::uint64_t k) { all = all && still[k]; });
  return all;
}

/// Material at rest, per cell (still_around of material_still).
template <int D>
std::vector<std::uint8_t> material_at_rest(const GridGeometry<D>& grid, const std::vector<double>& kinetic,
                                           const std::vector<double>& mass, double rest_speed) {
  const std::size_t n = num_cells(grid);
  if (kinetic.size() != n || mass.size() != n) throw std::invalid_argument("material_at_rest: input of the wrong size");
  const std::vector<std::uint8_t> still = material_still(kinetic, mass, rest_speed);
  std::vector<std::uint8_t> at_rest(n, 0);
  for (std::size_t c = 0; c < n; ++c) at_rest[c] = still_around<D>(grid, still, c);
  return at_rest;
}

/// Zones of material at rest stay as they were. In a deposit at rest the packing of a free-surface
/// cell near surface_packing flips with the grains' rattling, and with it the distance of the
/// cells below across L + h: a continuum cell turned hybrid made about 20 grains in the resting
/// deposit and set it moving again (docs/design.md 5.5). A change is held where the cell's material
/// is at rest (`at_rest`, material_at_rest): always towards continuum (the cell keeps more grains
/// than the oracle asks for); towards discrete only while the cell's distance is within 2h of the
/// threshold it crossed (a flicker, not a surface that came near: a material creeping slower than
/// the rest speed still gets its grains at the surface) and where the distance to the boundaries
/// alone (`boundary_distance`: walls, intruders, discrete regions; empty: none) would keep the
/// previous zone, so that a blade or intruder moving into a bed at rest still has its grains.
inline void hold_zones_at_rest(const std::vector<std::int8_t>& previous, const std::vector<std::uint8_t>& at_rest,
                               const std::vector<double>& distance, const std::vector<double>& boundary_distance,
                               const OracleSettings& s, std::vector<std::int8_t>& zones) {
  const std::size_t n = zones.size();
  if (previous.size() != n || at_rest.size() != n || distance.size() != n ||
      (!boundary_distance.empty() && boundary_distance.size() != n))
    throw std::invalid_argument("hold_zones_at_rest: input of the wrong size");
  const double lo = s.continuum_depth - s.band, hi = s.continuum_depth + s.band;
  for (std::size_t c = 0; c < n; ++c) {
    if (!at_rest[c] || zones[c] == previous[c]) continue;
    if (zones[c] > previous[c]) {
      zones[c] = previous[c];
      continue;
    }
    const double crossed = previous[c] == kContinuum ? hi : lo;  // the threshold the cell fell below
    const double b = boundary_distance.empty() ? std::numeric_limits<double>::infinity() : boundary_distance[c];
    if (distance[c] >= crossed - 2.0 * s.band && b >= crossed) zones[c] = previous[c];
  }
}

/// What hold_zones_at_rest needs; no `at_rest` (empty): nothing is held.
struct RestHold {
  std::vector<std::uint8_t> at_rest;
  std::vector<double> boundary_distance;
};

/// The zones of one oracle step: update_zones, the zones of material at rest held (`hold`, may be
/// null), then hybrid only near a continuum.
template <int D>
std::vector<std::int8_t> next_zones(const GridGeometry<D>& grid, const std::vector<std::int8_t>& previous,
                                    const std::vector<double>& distance, const std::vector<double>& packing,
                                    const std::vector<double>& shear_rate, const OracleSettings& s,
                                    const RestHold* hold = nullptr) {
  auto zones = update_zones(previous, distance, packing, shear_rate, s);
  if (hold && !hold->at_rest.empty() && !previous.empty())
    hold_zones_at_rest(previous, hold->at_rest, distance, hold->boundary_distance, s, zones);
  drop_hybrid_without_continuum<D>(grid, distance, s, zones);
  return zones;
}

// ---------------------------------------------------------------------------------------
// All three steps

struct OracleResult {
  std::vector<double> packing;   ///< phi per cell
  std::vector<double> distance;  ///< zone_distance per cell (signed distance, positive inside)
  std::vector<std::int8_t> zones;
};

/// One oracle update from the summed grain volumes per cell (all ranks added), the cells
/// holding material points, the boundary cells (walls/intruders/box_cells' boundary; may be
/// empty), the previous zones (empty: all discrete), the shear rate (may be empty) and the
/// solid cells beyond faces the continuum may touch (box_cells' solid; may be empty).
template <int D>
OracleResult run_oracle(const GridGeometry<D>& grid, const std::vector<double>& grain_volume_per_cell,
                        const std::vector<std::uint8_t>& has_points, const std::vector<std::uint8_t>& boundary_cells,
                        const std::vector<std::int8_t>& previous, const std::vector<double>& shear_rate,
                        const OracleSettings& settings, const std::vector<std::uint8_t>& solid_cells = {}) {
  OracleResult r;
  r.packing = packing_fraction<D>(grid, grain_volume_per_cell, has_points);
  r.distance = zone_distance<D>(grid, r.packing, boundary_cells, solid_cells, settings);
  r.zones = next_zones<D>(grid, previous, r.distance, r.packing, shear_rate, settings);
  return r;
}

// ---------------------------------------------------------------------------------------
// The oracle on the material's window of the grid

/// A box of cells of a grid, as a grid of its own (its cells numbered as any grid's), with the
/// whole grid's index of each of its cells in its own order.
template <int D>
struct CellWindow {
  GridGeometry<D> grid;
  Eigen::Matrix<int, D, 1> first = Eigen::Matrix<int, D, 1>::Zero();  ///< its first cell on the whole grid
  std::vector<std::size_t> cells;  ///< whole-grid index of window cell k
  /// The window's index of whole-grid cell c, or -1 if the window does not hold it.
  std::int64_t slot_of(const GridGeometry<D>& whole, std::size_t c) const {
    const Eigen::Matrix<int, D, 1> k = cell_coords<D>(whole, c) - first;
    return cell_on_grid<D>(grid, k) ? static_cast<std::int64_t>(cell_index<D>(grid, k)) : -1;
  }
  /// The values of a whole-grid field on the window's cells (empty stays empty).
  template <class T>
  std::vector<T> take(const std::vector<T>& whole) const {
    if (whole.empty()) return {};
    std::vector<T> part(cells.size());
    for (std::size_t k = 0; k < cells.size(); ++k) part[k] = whole[cells[k]];
    return part;
  }
};

/// The cells within `margin` cells (per axis) of the box around the `active` cells, clipped to
/// the grid; no cell if none is active.
template <int D>
CellWindow<D> cell_window(const GridGeometry<D>& grid, const std::vector<std::uint8_t>& active, int margin) {
  using IVec = Eigen::Matrix<int, D, 1>;
  const IVec cells_per_axis = grid.dims.array() - 1;
  IVec lo = cells_per_axis, hi = IVec::Constant(-1);
  for (std::size_t c = 0; c < active.size(); ++c)
    if (active[c]) {
      const IVec k = cell_coords<D>(grid, c);
      lo = lo.cwiseMin(k), hi = hi.cwiseMax(k);
    }
  CellWindow<D> w;
  if ((hi.array() < 0).any()) return w;
  lo = (lo.array() - margin).max(0);
  hi = (hi.array() + margin).min(cells_per_axis.array() - 1);
  w.grid = grid;
  w.first = lo;
  w.grid.origin = grid.node_position(lo);
  w.grid.dims = hi - lo + IVec::Constant(2);  // nodes: cells + 1
  const std::size_t n = num_cells<D>(w.grid);
  w.cells.resize(n);
  for (std::size_t k = 0; k < n; ++k) w.cells[k] = cell_index<D>(grid, IVec(lo + cell_coords<D>(w.grid, k)));
  return w;
}

/// What one oracle step reads, per cell of the whole grid.
template <int D>
struct OracleInputs {
  std::vector<double> grain_volume;           ///< the grains' volume (all DEM ranks summed)
  std::vector<std::uint8_t> has_points;       ///< cells holding material points
  std::vector<double> shear_rate;             ///< the fastest shearing point's; empty: no shear criterion
  std::vector<std::uint64_t> discrete_cells;  ///< cells of discrete regions: boundaries of the material
  Eigen::Matrix<double, D, 1> container_lo, container_hi;
  std::uint32_t touched_faces = 0;            ///< faces the continuum may touch (box_cells)
  /// Rest hold (hold_zones_at_rest): kinetic energy and mass of grains and points; empty: none held
  std::vector<double> kinetic, mass;
  double rest_speed = 0;
  /// The zones before; empty: the start of a run, which goes to the oracle's fixed point
  std::vector<std::int8_t> previous;
};

namespace oracle_detail {
/// One oracle step on `grid` (the whole grid or a window of it), `in` given on its cells.
template <int D>
std::vector<std::int8_t> zones_on(const GridGeometry<D>& grid, const OracleInputs<D>& in, const OracleSettings& s) {
  BoxCells box = box_cells<D>(grid, in.container_lo, in.container_hi, in.touched_faces);
  for (std::uint64_t c : in.discrete_cells) box.add_boundary(c);
  const auto packing = packing_fraction<D>(grid, in.grain_volume, in.has_points);
  const auto distance = zone_distance<D>(grid, packing, box.boundary, box.solid, s);
  RestHold hold;
  if (!in.kinetic.empty()) {
    hold.at_rest = material_at_rest<D>(grid, in.kinetic, in.mass, in.rest_speed);
    if (std::any_of(box.boundary.begin(), box.boundary.end(), [](std::uint8_t b) { return b != 0; }))
      hold.boundary_distance = distance_to_cells<D>(grid, box.boundary);
  }
  auto next = next_zones<D>(grid, in.previous, distance, packing, in.shear_rate, s, &hold);
  for (int k = 0; in.previous.empty() && k < 4; ++k) {  // the start: to the fixed point
    auto again = next_zones<D>(grid, next, distance, packing, in.shear_rate, s);
    if (again == next) break;
    next.swap(again);
  }
  return next;
}
}  // namespace oracle_detail

/// Cells of margin around the material that make the oracle's zones on a window those of the
/// whole grid. A cell with no material whose zone was discrete ends discrete unless a cell
/// wanting continuum is within the hybrid reach 2h + sqrt(D) dx (drop_hybrid_without_continuum),
/// so the zones can change only within `reach` cells of the material; there every distance the
/// zones compare is exact up to depth + |L - L_s| + 3h (the thresholds L -+ h, the rest hold's
/// L - 3h, the surface depth's shift), and a source beyond the margin is farther than that.
inline int oracle_margin(const OracleSettings& s, double dx) {
  const double reach = 2.0 * s.band / dx + std::sqrt(3.0) + 1.0;  // sqrt(3) >= sqrt(D), and a cell for the rounding
  const double depth = std::max(s.continuum_depth, s.free_surface_depth()) +
                       std::abs(s.continuum_depth - s.free_surface_depth()) + 3.0 * s.band;
  return static_cast<int>(std::ceil(reach) + std::ceil(depth / dx)) + 2;
}

/// One oracle step over the whole grid, computed on the window of it that holds the material
/// (grains, points, cells not discrete before) and oracle_margin() around it: the same zones as
/// oracle_detail::zones_on the whole grid (tests/test_coupler_oracle.cpp), at the cost of the
/// material's cells rather than the box's (a collapse's column fills a tenth of its box).
/// `margin` (cells; < 0: oracle_margin) is for the tests, which check that a smaller one is not enough.
template <int D>
std::vector<std::int8_t> oracle_zones(const GridGeometry<D>& grid, const OracleInputs<D>& in, const OracleSettings& s,
                                      int margin = -1) {
  const std::size_t n = num_cells<D>(grid);
  std::vector<std::uint8_t> active(n, 0);
  for (std::size_t c = 0; c < n; ++c)
    active[c] = (!in.grain_volume.empty() && in.grain_volume[c] > 0) || (!in.has_points.empty() && in.has_points[c]) ||
                (!in.previous.empty() && in.previous[c] != kDiscrete);
  std::vector<std::int8_t> zones = in.previous.empty() ? std::vector<std::int8_t>(n, kDiscrete) : in.previous;
  const CellWindow<D> w = cell_window<D>(grid, active, margin < 0 ? oracle_margin(s, grid.dx) : margin);
  if (w.cells.empty()) return zones;
  OracleInputs<D> part;
  part.grain_volume = w.take(in.grain_volume), part.has_points = w.take(in.has_points);
  part.shear_rate = w.take(in.shear_rate), part.kinetic = w.take(in.kinetic), part.mass = w.take(in.mass);
  part.previous = w.take(in.previous);
  part.container_lo = in.container_lo, part.container_hi = in.container_hi, part.touched_faces = in.touched_faces;
  part.rest_speed = in.rest_speed;
  for (std::uint64_t c : in.discrete_cells) {
    if (c >= n) throw std::invalid_argument("oracle_zones: a discrete cell off the grid");
    if (const std::int64_t k = w.slot_of(grid, c); k >= 0) part.discrete_cells.push_back(static_cast<std::uint64_t>(k));
  }
  const auto inside = oracle_detail::zones_on<D>(w.grid, part, s);
  for (std::size_t k = 0; k < w.cells.size(); ++k) zones[w.cells[k]] = inside[k];
  return zones;
}

}  // namespace coupler
