#pragma once
// Dense background grid of nodes. The grid extends kPad cells past the user's
// domain on every side so that the quadratic stencil of any point inside the
// domain stays on the grid.
#include <array>
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
  /// Node velocity of the transfer alone, without forces (the FLIP part of G2P, docs/design.md
  /// section 4.2); sized on the first step that keeps some of the points' own velocity.
  std::vector<Vec<D>> transfer_velocity;

  Grid() = default;
  Grid(const Vec<D>& lower, const Vec<D>& upper, double cell)
      : Grid(lower, upper, cell, coupler::kNoWalls) {}
  /// The grid over the domain [lower, upper]; on each axis with a finite node_plane[a] its
  /// nodes lie on that plane (coupler::padded_grid).
  Grid(const Vec<D>& lower, const Vec<D>& upper, double cell, const std::array<double, 3>& node_plane)
      : coupler::GridGeometry<D>(coupler::padded_grid<D>(lower, upper, cell, node_plane)),
        domain_lower(lower),
        domain_upper(upper) {
    mass.assign(this->num_nodes(), 0.0);
    momentum.assign(this->num_nodes(), Vec<D>::Zero());
  }

  bool in_domain(const Vec<D>& x) const {
    return (x.array() >= domain_lower.array()).all() && (x.array() <= domain_upper.array()).all();
  }
};

}  // namespace mpm
