#pragma once
// Visiting the nodes of a point's quadratic B-spline stencil on the shared grid.
#include <cstddef>

#include "coupler/bspline.hpp"
#include "coupler/grid_geometry.hpp"

namespace coupler {

/// Calls f(flat node index, weight, node offset from the point in cell units)
/// for the 3^D nodes of the stencil `s` on `grid`.
template <int D, class F>
inline void for_each_stencil_node(const QuadraticStencil<D>& s, const GridGeometry<D>& grid, F&& f) {
  using V = Eigen::Matrix<double, D, 1>;
  const std::size_t base = grid.index(s.base);
  if constexpr (D == 2) {
    const std::size_t sx = static_cast<std::size_t>(grid.dims[1]);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) f(base + i * sx + j, s.w[0][i] * s.w[1][j], V(i - s.frac[0], j - s.frac[1]));
  } else {
    const std::size_t sy = static_cast<std::size_t>(grid.dims[2]);
    const std::size_t sx = sy * static_cast<std::size_t>(grid.dims[1]);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const double wij = s.w[0][i] * s.w[1][j];
        for (int k = 0; k < 3; ++k)
          f(base + i * sx + j * sy + k, wij * s.w[2][k], V(i - s.frac[0], j - s.frac[1], k - s.frac[2]));
      }
  }
}

}  // namespace coupler
