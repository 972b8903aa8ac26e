#pragma once
// Dense background grid of nodes. Nodes sit at origin + index * dx; the grid
// extends kPad cells past the user's domain on every side so that the
// quadratic stencil of any point inside the domain stays on the grid.
#include <cmath>
#include <vector>

#include "mpm/types.hpp"

namespace mpm {

template <int D>
struct Grid {
  static constexpr int kPad = 3;

  double dx = 0;
  Vec<D> origin = Vec<D>::Zero();     ///< position of node 0
  Vec<D> domain_lower = Vec<D>::Zero(), domain_upper = Vec<D>::Zero();
  IVec<D> dims = IVec<D>::Zero();     ///< nodes per axis
  std::vector<double> mass;           ///< node mass
  std::vector<Vec<D>> momentum;       ///< node momentum; velocity after the grid update

  Grid() = default;
  Grid(const Vec<D>& lower, const Vec<D>& upper, double cell) : dx(cell), domain_lower(lower), domain_upper(upper) {
    origin = lower.array() - kPad * dx;
    for (int a = 0; a < D; ++a) dims[a] = static_cast<int>(std::ceil((upper[a] - lower[a]) / dx)) + 2 * kPad + 1;
    mass.assign(num_nodes(), 0.0);
    momentum.assign(num_nodes(), Vec<D>::Zero());
  }

  std::size_t num_nodes() const {
    std::size_t n = 1;
    for (int a = 0; a < D; ++a) n *= static_cast<std::size_t>(dims[a]);
    return n;
  }
  /// Row-major flat index, last axis fastest.
  std::size_t index(const IVec<D>& i) const {
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
  Vec<D> node_position(const IVec<D>& i) const { return origin + dx * i.template cast<double>(); }
  IVec<D> node_of(std::size_t k) const {
    IVec<D> i;
    for (int a = D - 1; a >= 0; --a) {
      i[a] = static_cast<int>(k % static_cast<std::size_t>(dims[a]));
      k /= static_cast<std::size_t>(dims[a]);
    }
    return i;
  }
  /// Point position in cell units from the origin, the input of the transfer stencil.
  Vec<D> to_cell_units(const Vec<D>& x) const { return (x - origin) / dx; }
  bool in_domain(const Vec<D>& x) const {
    return (x.array() >= domain_lower.array()).all() && (x.array() <= domain_upper.array()).all();
  }
};

}  // namespace mpm
