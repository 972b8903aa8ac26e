#pragma once
// The DEM side's part of a rezone (coupler/protocol.hpp, docs/fix_hybrid_mpm.md "Adaptive
// zones"): the sums of the grains in the cells that move, the new grains cut from the packing
// template where points become grains (enrichment), and what the MPM process's corrections do
// to each grain. Host-neutral: the host creates and deletes the atoms these functions name.
// Functions taking an MPI communicator are collective over the DEM ranks.

#include <mpi.h>

#include <cstdint>
#include <map>
#include <vector>

#include "coupler/dem_grains.hpp"
#include "coupler/enrichment.hpp"
#include "coupler/protocol.hpp"

namespace coupler {

/// Cells of a rezone by cell index: their slot in the list the MPM process sent.
using CellSlots = std::map<std::uint64_t, std::size_t>;

template <int D>
CellSlots cell_slots(const std::vector<RezoneCell<D>> &cells) {
  CellSlots slots;
  for (std::size_t k = 0; k < cells.size(); ++k) slots.emplace(cells[k].cell, k);
  return slots;
}

/// The slot of the cell holding position x; -1 off the grid or for a cell not listed.
template <int D>
std::int64_t slot_of_cell_at(const GridGeometry<D> &grid, const double *x, const CellSlots &slots);

/// Sums of this rank's grains of the group in the listed cells, by slot: what they carry (with
/// their stress * volume) and what they would at their solid mass (the MPM process rescales those).
template <int D>
std::map<std::size_t, GrainSums<D>> moving_grain_sums(const GridGeometry<D> &grid,
                                                      const std::vector<RezoneCell<D>> &cells,
                                                      const CellSlots &slots, const DemGrains &g,
                                                      const GrainRules &rules);

/// The same cells' sums over all DEM ranks (every field but the cell index).
template <int D>
void sum_over_ranks(std::vector<BodySums<D>> &sums, MPI_Comm comm);

/// A grain to make: where, how big, how fast (its mass is its solid mass), at which weight,
/// for the cell of which slot (centre: that cell's centre, the sums' reference point).
template <int D>
struct PlannedGrain {
  std::size_t slot = 0;
  NewGrain<D> grain;
  double share = 1.0;
  Eigen::Matrix<double, D, 1> centre;
};

/// Enrichment, in the listed cells that make grains: candidates cut from the packing template
/// where the points are and inside the container [lo, hi], fitted among the grains of every
/// rank (all of this rank's atoms, of any group, are obstacles): dropped where one overlaps
/// them by more than 1 - kSmallestShrink of their radius, else pushed off them and each other
/// by at most that much within their cell, shrunk (down to kSmallestShrink) only where still
/// overlapped; nearest the points' centre first, as many as the cell's material (its points
/// plus its old grains, whose sums `sums` holds on each rank) fills at their solid mass; each
/// moves with the continuum's affine field. The same list on every rank (collective).
template <int D>
std::vector<PlannedGrain<D>> plan_new_grains(const GridGeometry<D> &grid, const std::vector<RezoneCell<D>> &cells,
                                             const std::map<std::size_t, GrainSums<D>> &sums, const DemGrains &g,
                                             const PackingTemplate<D> &tmpl, const GrainRules &rules,
                                             double grain_diameter, const double lo[3], const double hi[3],
                                             MPI_Comm comm);

/// A made grain joins its cell's sums (at its solid mass: the MPM process corrects old and new
/// grains of the cell together).
template <int D>
void add_new_grain(std::map<std::size_t, GrainSums<D>> &sums, const std::vector<RezoneCell<D>> &cells,
                   const PlannedGrain<D> &p, const GrainRules &rules);

/// The MPM process's corrections applied to this rank's grains of the group: grains of removed
/// cells are flagged (the host deletes them), the others take their cell's rigid velocity
/// increment, their new mass (mass_factor times their solid mass) and weight. Returns the
/// flags (one per atom). With `mechanisms`, also each atom's cell's RezoneMechanism as the
/// correction names it (-1 where no correction reached the atom, or the name is none).
template <int D>
std::vector<char> apply_corrections(const GridGeometry<D> &grid, const std::vector<RezoneCell<D>> &cells,
                                    const CellSlots &slots, const std::vector<GrainCorrection<D>> &corrections,
                                    DemGrains &g, const GrainRules &rules,
                                    std::vector<signed char> *mechanisms = nullptr);

}    // namespace coupler
