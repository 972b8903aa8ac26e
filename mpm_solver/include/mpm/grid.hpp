#pragma once
// Dense background grid of nodes. The grid extends kPad cells past the user's
// domain on every side so that the quadratic stencil of any point inside the
// domain stays on the grid.
#include <cmath>
#include <vector>

#include "coupler/grid_geometry.hpp"
#include "mpm/types.hpp"

namespace mpm {

template <int D>
struct Grid : coupler::GridGeometry<D> {
  static constexpr int kPad = coupler::kGridPad;

  Vec<D> domain_lower = Vec<D>::Zero(), domain_upper = Vec<D>::Zero();
  std::vector<double> mass;      ///< node mass
  std::vector<Vec<D>> momentum;  ///< node momentum; velocity after the grid update

  Grid() = default;
  Grid(const Vec<D>& lower, const Vec<D>& upper, double cell)
      : coupler::GridGeometry<D>(coupler::padded_grid<D>(lower, upper, cell)), domain_lower(lower), domain_upper(upper) {
    mass.assign(this->num_nodes(), 0.0);
    momentum.assign(this->num_nodes(), Vec<D>::Zero());
  }

  bool in_domain(const Vec<D>& x) const {
    return (x.array() >= domain_lower.array()).all() && (x.array() <= domain_upper.array()).all();
  }
};

}  // namespace mpm
