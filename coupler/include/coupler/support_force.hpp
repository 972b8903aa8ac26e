#pragma once
// The support force of one shared node between exchanges (docs/design.md section 5.4): the
// steady force that lets grains and points rest on each other between two velocity
// agreements. Header-only and free of MPI and LAMMPS types: the MPM process applies it, the
// unit tests drive it directly.
#include <Eigen/Core>
#include <algorithm>

namespace coupler {

/// What a node's support force carries from one exchange to the next.
template <int D>
struct SupportNode {
  using Vec = Eigen::Matrix<double, D, 1>;
  Vec force = Vec::Zero();   ///< on the grains, N (N/m in 2D); the points feel -force
  double reduced_mass = 0;   ///< m_dem m_mpm / (m_dem + m_mpm) when the force was set; 0: no force
  /// Energy the coupling took out of the relative motion of the two sides at this node and has
  /// not given back (J; J/m in 2D): the most the force may still return to that motion.
  double budget = 0;
  Vec gap = Vec::Zero();     ///< v_dem - v_mpm that the agreement left at the node
};

/// The node's support force after an exchange.
///
/// `old`: its state from the last exchange (default-constructed if the node held no force);
/// `gap`: v_dem - v_mpm before this agreement; `reduced_mass`: the node's m_dem m_mpm /
/// (m_dem + m_mpm) now; `closing`: the share of the gap the agreement closes; `transfer`: the
/// momentum the agreement gave the grains at the node; `interval`: the time since the last
/// exchange; `gain`: the support gain (0: no force).
///
/// The force is an integral of the agreement's transfers, F <- F + gain * transfer / T, so it
/// holds a steady load with no relative motion: a leak (forgetting a share of F at every
/// exchange) had to be re-earned by slip, and a settled hybrid bed crept at twice the DEM's
/// rate (bench/results/settled_bed.md). What keeps it honest is passivity: the force may give
/// the relative motion of the two sides no more energy than the coupling took out of it at that
/// node (the agreement's dissipation, and the work the force itself did against the motion), and
/// no more than the force stores as a spring: an energy budget per node. A force that would
/// overdraw it is dropped: in a shearing flow, where material streams through a node's
/// force, a force carried regardless pumped the flow (a gravity-free patch gained 3x its kinetic
/// energy).
template <int D>
SupportNode<D> next_support(const SupportNode<D>& old, const Eigen::Matrix<double, D, 1>& gap, double reduced_mass,
                            double closing, const Eigen::Matrix<double, D, 1>& transfer, double interval, double gain) {
  SupportNode<D> next;
  next.reduced_mass = reduced_mass;
  next.gap = (1.0 - closing) * gap;
  // work of the old force on the relative motion over the interval (trapezoid of the gaps)
  double budget = old.budget - old.force.dot(0.5 * (old.gap + gap)) * interval;
  const bool keep = old.reduced_mass > 0 && budget >= 0;
  if (keep) {
    // a force set when the node held more mass would accelerate what is left there beyond
    // anything the agreement asked for: it scales with the reduced mass (never up)
    next.force = std::min(1.0, reduced_mass / old.reduced_mass) * old.force;
  } else {
    budget = 0;
  }
  // the agreement's dissipation: the relative kinetic energy 1/2 mu |gap|^2 less what it leaves
  next.budget = budget + 0.5 * reduced_mass * gap.squaredNorm() * closing * (2.0 - closing);
  if (interval > 0) next.force += (gain / interval) * transfer;
  // The force is a spring on the two sides' relative displacement (F <- F - k gap T with
  // k = gain closing mu / T^2): what it may give back is at most what that spring stores,
  // |F|^2 / 2k. The agreements' dissipation is gone; banked for a whole run it let forces wound
  // up at nodes holding a sliver of mass feed themselves (docs/design.md section 5.4).
  if (gain > 0 && closing > 0 && reduced_mass > 0)
    next.budget = std::min(next.budget, next.force.squaredNorm() * interval * interval /
                                            (2.0 * gain * closing * reduced_mass));
  return next;
}

}  // namespace coupler
