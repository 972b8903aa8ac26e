#pragma once
// Zones of the grid cells in a coupled run (docs/design.md section 5): discrete cells hold grains
// only, continuum cells material points only, hybrid cells both, each with a share of the
// mass. The zone map is one byte per cell, computed once and shared by both sides.
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "coupler/conversion.hpp"
#include "coupler/grid_geometry.hpp"

namespace coupler {

enum Zone : std::int8_t { kDiscrete = 0, kHybrid = 1, kContinuum = 2 };

/// What a rezone does to a cell, by its zone change: enrichment (towards discrete: the grains'
/// share of its material rises), homogenisation (towards continuum: it falls), or a repair (the
/// zone stays; the cell held material of the wrong kind, or starved or light grains). Both sides
/// tally the rezones' energy by it (docs/fix_hybrid_mpm.md, "Energy ledger").
enum RezoneMechanism : std::int32_t { kRepair = 0, kEnrichment = 1, kHomogenisation = 2 };
inline constexpr int kMechanisms = 3;

inline RezoneMechanism rezone_mechanism(int zone_before, int zone_after) {
  return zone_after < zone_before ? kEnrichment : zone_after > zone_before ? kHomogenisation : kRepair;
}

inline const char* mechanism_name(int mechanism) {
  switch (mechanism) {
    case kRepair: return "repair";
    case kEnrichment: return "enrichment";
    case kHomogenisation: return "homogenisation";
    default: return "unknown";
  }
}

/// "by the cells' zone change: enrichment ..., homogenisation ..., repair ...", each term as
/// `term(name, parts)` writes it: the part of both sides' rezone energy lines that
/// hgtools.logs.rezone_energy reads by name.
template <class Parts, class Term>
std::string mechanism_terms(const Parts (&by_mechanism)[kMechanisms], Term&& term) {
  std::string text = "by the cells' zone change: ";
  for (const int m : {kEnrichment, kHomogenisation, kRepair})
    text += term(mechanism_name(m), by_mechanism[m]) + (m == kRepair ? "" : ", ");
  return text;
}

inline const char* zone_name(int zone) {
  switch (zone) {
    case kDiscrete: return "discrete";
    case kHybrid: return "hybrid";
    case kContinuum: return "continuum";
    default: return "unknown";
  }
}

/// Zone map from user-given continuum regions: a cell whose centre is inside them (`inside`)
/// is continuum, unless a cell within `hybrid_width` cells (Chebyshev distance) is not - then
/// it is hybrid. Cells wholly outside the box [lower, upper] count as inside, so that the
/// faces of the box (walls) do not make hybrid layers; a cell straddling a face is judged at
/// the point of the box nearest its centre (a face off the cell lattice, e.g. a thin slab's
/// side wall, must not turn the grains of its last cell layer into points).
template <int D, class Inside>
std::vector<std::int8_t> zones_from_regions(const GridGeometry<D>& grid, const Eigen::Matrix<double, D, 1>& lower,
                                            const Eigen::Matrix<double, D, 1>& upper, int hybrid_width,
                                            Inside&& inside) {
  using IVec = Eigen::Matrix<int, D, 1>;
  const std::size_t n = num_cells(grid);
  IVec cells = grid.dims.array() - 1;
  // outside[c]: a discrete cell; dilated by the hybrid width one axis at a time
  // (a Chebyshev ball is the product of 1D intervals).
  std::vector<std::uint8_t> outside(n);
  for (std::size_t c = 0; c < n; ++c) {
    const auto x = cell_center(grid, cell_coords(grid, c));
    const double half = 0.5 * grid.dx;
    const bool overlaps_box = ((x.array() + half) > lower.array()).all() && ((x.array() - half) < upper.array()).all();
    const Eigen::Matrix<double, D, 1> nearest = x.cwiseMax(lower).cwiseMin(upper);
    outside[c] = overlaps_box && !inside(nearest);
  }
  std::vector<std::uint8_t> near = outside;
  for (int a = 0; a < D; ++a) {
    std::vector<std::uint8_t> next(n, 0);
    for (std::size_t c = 0; c < n; ++c) {
      if (!near[c]) continue;
      IVec i = cell_coords(grid, c);
      const int centre = i[a];
      for (int k = std::max(0, centre - hybrid_width); k <= std::min(cells[a] - 1, centre + hybrid_width); ++k) {
        i[a] = k;
        next[cell_index(grid, i)] = 1;
      }
    }
    near.swap(next);
  }
  std::vector<std::int8_t> zones(n);
  for (std::size_t c = 0; c < n; ++c) zones[c] = outside[c] ? kDiscrete : (near[c] ? kHybrid : kContinuum);
  return zones;
}

/// Counts of cells per zone (index by Zone).
inline std::array<std::size_t, 3> zone_counts(const std::vector<std::int8_t>& zones) {
  std::array<std::size_t, 3> n{0, 0, 0};
  for (auto z : zones) ++n[static_cast<std::size_t>(z)];
  return n;
}

/// The grid cells a wall made of triangles passes through (LIGGGHTS's mesh walls, `fix
/// mesh/surface`): `vertices` holds 9 coordinates per triangle. Each triangle is sampled at under
/// a quarter of a cell, so a cell it only clips by less than that may be left out (the oracle's
/// band keeps the continuum farther away than that); cells off the grid are left out. Sorted,
/// each cell once. The oracle keeps them discrete, as it keeps the cells of discrete regions.
inline std::vector<std::uint64_t> cells_of_triangles(const GridGeometry<3>& grid, const std::vector<double>& vertices) {
  using Vec3 = Eigen::Vector3d;
  std::vector<std::uint64_t> cells;
  for (std::size_t t = 0; t + 9 <= vertices.size(); t += 9) {
    const Vec3 a(vertices[t], vertices[t + 1], vertices[t + 2]), b(vertices[t + 3], vertices[t + 4], vertices[t + 5]),
        c(vertices[t + 6], vertices[t + 7], vertices[t + 8]);
    if (!a.allFinite() || !b.allFinite() || !c.allFinite()) continue;
    const double longest = std::max({(b - a).norm(), (c - a).norm(), (c - b).norm()});
    const int n = 1 + static_cast<int>(std::ceil(longest / (0.25 * grid.dx)));
    for (int i = 0; i <= n; ++i)
      for (int j = 0; i + j <= n; ++j) {
        const Vec3 x = a + (b - a) * (static_cast<double>(i) / n) + (c - a) * (static_cast<double>(j) / n);
        const Eigen::Vector3i cell = cell_of<3>(grid, x);
        if (cell_on_grid<3>(grid, cell)) cells.push_back(cell_index<3>(grid, cell));
      }
  }
  std::sort(cells.begin(), cells.end());
  cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
  return cells;
}

}  // namespace coupler
