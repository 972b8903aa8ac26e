#pragma once
// Grain <-> grid transfers and the velocity agreement of the hybrid zone
// (docs/design.md section 5, after Yue et al. 2018). No LAMMPS types: grains come
// as strided arrays, so any DEM host (LAMMPS, LIGGGHTS) can call these.
//
// Conservation: a grain of mass m and hybrid weight w contributes w*m and
// w*m*v to its nodes; the agreement moves momentum lambda_i from the MPM side
// to the DEM side at every shared node, and the grain corrections add exactly
// sum_i lambda_i to the weighted grain momentum sum_g w_g m_g v_g. The
// weighted total of both sides is therefore unchanged to round-off.
#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "coupler/bspline.hpp"
#include "coupler/grid_geometry.hpp"
#include "coupler/stencil.hpp"

namespace coupler {

/// Grains as strided arrays (LAMMPS keeps x and v as n x 3 blocks, also in 2D).
struct GrainView {
  std::size_t count = 0;
  const double* x = nullptr;       ///< position of grain g at x[g * stride]
  const double* v = nullptr;       ///< velocity, same layout
  std::size_t stride = 3;
  const double* mass = nullptr;    ///< mass of grain g at mass[g]
  /// Hybrid weight w in [0, 1] of grain g (share of its material the grain carries); nullptr:
  /// the masses are already the carried masses (LAMMPS's rmass of a hybrid grain is w m).
  const double* weight = nullptr;
  double weight_of(std::size_t g) const { return weight != nullptr ? weight[g] : 1.0; }
};

/// Mass and momentum one side holds at a node.
template <int D>
struct NodeMomentum {
  std::size_t node = 0;
  double mass = 0;
  Eigen::Matrix<double, D, 1> momentum = Eigen::Matrix<double, D, 1>::Zero();
};

namespace detail {
template <int D>
Eigen::Matrix<double, D, 1> read(const double* base, std::size_t g, std::size_t stride) {
  return Eigen::Map<const Eigen::Matrix<double, D, 1>>(base + g * stride);
}

/// Calls f(node, weight) for the 3^D stencil nodes of x.
template <int D, class F>
void for_each_node(const GridGeometry<D>& grid, const Eigen::Matrix<double, D, 1>& x, F&& f) {
  for_each_stencil_node<D>(QuadraticStencil<D>(grid.to_cell_units(x)), grid,
                           [&](std::size_t node, double w, const auto&) { f(node, w); });
}
}  // namespace detail

/// The momentum lambda that moves from the MPM side to the DEM side at a node
/// so that both end with the common velocity (p_mpm + p_dem)/(m_mpm + m_dem).
template <int D>
Eigen::Matrix<double, D, 1> agreement_impulse(double m_mpm, const Eigen::Matrix<double, D, 1>& p_mpm, double m_dem,
                                              const Eigen::Matrix<double, D, 1>& p_dem) {
  return (m_dem * p_mpm - m_mpm * p_dem) / (m_mpm + m_dem);
}

/// What a node tells its grains after the agreement.
template <int D>
struct AgreedNode {
  Eigen::Matrix<double, D, 1> velocity = Eigen::Matrix<double, D, 1>::Zero();  ///< common node velocity
  Eigen::Matrix<double, D, 1> impulse_per_mass = Eigen::Matrix<double, D, 1>::Zero();  ///< lambda_i / m_dem_i
  Eigen::Matrix<double, D, 1> support = Eigen::Matrix<double, D, 1>::Zero();  ///< F_i / m_dem_i
  double field_share = 0;  ///< pi_i: share of the field rule in the update of the node's grains
};

/// Transfers between grains and the nodes of the shared grid, with per-node scratch kept
/// between calls (a dense node -> slot map, so each transfer costs O(grains), no sort of
/// grain-node pairs). One instance per DEM rank and grid.
template <int D>
class GrainTransfer {
 public:
  using V = Eigen::Matrix<double, D, 1>;

  explicit GrainTransfer(const GridGeometry<D>& grid) : grid_(grid), slot_(grid.num_nodes(), -1) {}

  const GridGeometry<D>& grid() const { return grid_; }

  /// Weighted grain mass and momentum on the nodes the grains touch, one entry per node,
  /// sorted by node index. Each node sums its grains in their input order, so the result
  /// depends on nothing but the input. Grains must lie where their stencil is on the grid
  /// (GridGeometry::stencil_on_grid).
  const std::vector<NodeMomentum<D>>& to_nodes(const GrainView& grains) {
    for (const auto& n : nodes_) slot_[n.node] = -1;
    nodes_.clear();
    for (std::size_t g = 0; g < grains.count; ++g) {
      const double m = grains.weight_of(g) * grains.mass[g];
      const V p = m * detail::read<D>(grains.v, g, grains.stride);
      detail::for_each_node<D>(grid_, detail::read<D>(grains.x, g, grains.stride), [&](std::size_t node, double w) {
        if (slot_[node] < 0) {
          slot_[node] = static_cast<std::int64_t>(nodes_.size());
          nodes_.push_back({node, 0.0, V::Zero()});  // {} would leave the momentum uninitialised
        }
        NodeMomentum<D>& n = nodes_[static_cast<std::size_t>(slot_[node])];
        n.mass += w * m;
        n.momentum += w * p;
      });
    }
    std::sort(nodes_.begin(), nodes_.end(), [](const auto& a, const auto& b) { return a.node < b.node; });
    for (std::size_t i = 0; i < nodes_.size(); ++i) slot_[nodes_[i].node] = static_cast<std::int64_t>(i);
    return nodes_;
  }

  /// Velocity change of each grain after the agreement, blending per node two updates that both
  /// add exactly lambda_i to the weighted grain momentum at node i:
  ///   impulse (pi_i = 0):  dv_g = sum_i N_ig lambda_i / m_dem_i   (docs/design.md section 5.3)
  ///   field   (pi_i = 1):  dv_g = sum_i N_ig (v_i - v_g)          (the grain takes the agreed field)
  /// with pi_i = AgreedNode::field_share. The field part conserves node by node because
  /// sum_g w_g m_g N_ig (v_i - v_g) = m_dem_i v_i - p_dem_i = lambda_i, so any pi_i does.
  /// `agreed` holds the answers for the nodes of the last to_nodes() in its order; m_dem_i in
  /// lambda_i / m_dem_i is the node's DEM mass over all DEM ranks. Writes grains.count * D
  /// values to dv and, if `support` is given, the acceleration sum_i N_ig F_i / m_dem_i each
  /// grain gets until the next exchange (whose impulse over the grains, sum_g w_g m_g a_g, is
  /// exactly sum_i F_i, as for lambda). The grains must be those of the last to_nodes().
  void velocity_updates(const GrainView& grains, const std::vector<AgreedNode<D>>& agreed, double* dv,
                        double* support = nullptr) const {
    for (std::size_t g = 0; g < grains.count; ++g) {
      V change = V::Zero(), accel = V::Zero();
      double field = 0;  // sum_i N_ig pi_i
      detail::for_each_node<D>(grid_, detail::read<D>(grains.x, g, grains.stride), [&](std::size_t node, double w) {
        const AgreedNode<D>& a = agreed[static_cast<std::size_t>(slot_[node])];
        change += w * ((1.0 - a.field_share) * a.impulse_per_mass + a.field_share * a.velocity);
        field += w * a.field_share;
        accel += w * a.support;
      });
      Eigen::Map<V>(dv + g * D) = change - field * detail::read<D>(grains.v, g, grains.stride);
      if (support != nullptr) Eigen::Map<V>(support + g * D) = accel;
    }
  }

 private:
  GridGeometry<D> grid_;
  std::vector<std::int64_t> slot_;  ///< node -> index in nodes_, -1 if the grains do not touch it
  std::vector<NodeMomentum<D>> nodes_;
};

}  // namespace coupler
