#pragma once
// Geometry of the background grid that both sides of a coupled run share:
// where node i sits and how nodes are numbered. The MPM grid stores fields on
// it; the DEM side uses it to transfer grains to the same nodes.
#include <Eigen/Core>
#include <cmath>
#include <cstddef>

namespace coupler {

template <int D>
struct GridGeometry {
  using Vec = Eigen::Matrix<double, D, 1>;
  using IVec = Eigen::Matrix<int, D, 1>;

  double dx = 0;
  Vec origin = Vec::Zero();  ///< position of node 0
  IVec dims = IVec::Zero();  ///< nodes per axis

  std::size_t num_nodes() const {
    std::size_t n = 1;
    for (int a = 0; a < D; ++a) n *= static_cast<std::size_t>(dims[a]);
    return n;
  }
  /// Row-major flat index, last axis fastest.
  std::size_t index(const IVec& i) const {
    std::size_t k = static_cast<std::size_t>(i[0]);
    for (int a = 1; a < D; ++a) k = k * static_cast<std::size_t>(dims[a]) + static_cast<std::size_t>(i[a]);
    return k;
  }
  /// Stride of one step along axis a in the flat index.
  std::size_t stride(int a) const {
    std::size_t s = 1;
    for (int b = D - 1; b > a; --b) s *= static_cast<std::size_t>(dims[b]);
    return s;
  }
  IVec node_of(std::size_t k) const {
    IVec i;
    for (int a = D - 1; a >= 0; --a) {
      i[a] = static_cast<int>(k % static_cast<std::size_t>(dims[a]));
      k /= static_cast<std::size_t>(dims[a]);
    }
    return i;
  }
  Vec node_position(const IVec& i) const { return origin + dx * i.template cast<double>(); }
  /// Position in cell units from the origin: the input of the transfer stencil.
  Vec to_cell_units(const Vec& x) const { return (x - origin) / dx; }
  /// True if the quadratic stencil of a point at x lies on the grid.
  bool stencil_on_grid(const Vec& x) const {
    const Vec xi = to_cell_units(x);
    return (xi.array() >= 0.5).all() && (xi.array() < dims.template cast<double>().array() - 1.5).all();
  }
};

/// Cells of padding past the domain on every side: the quadratic stencil of any point
/// within 1.5 cells outside the domain stays on the grid.
inline constexpr int kGridPad = 3;

/// The grid over the box [lower, upper] with cell size `cell`: node 0 sits kGridPad cells
/// below `lower`. Both sides of a coupled run build it from the DEM box, so their node
/// numbers agree.
template <int D>
GridGeometry<D> padded_grid(const Eigen::Matrix<double, D, 1>& lower, const Eigen::Matrix<double, D, 1>& upper,
                            double cell) {
  GridGeometry<D> g;
  g.dx = cell;
  g.origin = lower.array() - kGridPad * cell;
  for (int a = 0; a < D; ++a)
    g.dims[a] = static_cast<int>(std::ceil((upper[a] - lower[a]) / cell)) + 2 * kGridPad + 1;
  return g;
}

}  // namespace coupler
