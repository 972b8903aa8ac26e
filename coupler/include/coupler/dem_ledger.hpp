#pragma once
// The DEM side's figures for thermo output: the grains' side of the energy ledger
// (docs/fix_hybrid_mpm.md, "Energy ledger") and the fix's global vector (entries 1-35, "Restart,
// fix_modify, output"). Host-neutral: the host sums its ranks' figures and prints the vector.

#include <cstdint>

#include "coupler/protocol.hpp"

namespace coupler {

/// The grains' side of the energy ledger: brackets that follow each other without a gap, each
/// closed at an exchange or a rezone. Sums over one rank's grains; only their sum over the ranks
/// means anything (atoms change ranks).
struct EnergyLedger {
  double start = 0;        ///< the grains' energy when the ledger started
  double energy = 0;       ///< their energy when the last bracket closed
  double dem = 0;          ///< the host's own steps: contacts, walls, grains leaving
  double agreement = 0;    ///< the velocity agreements' updates of the grains
  double support = 0;      ///< the support force's kicks
  double support_open = 0; ///< those kicks since the last bracket closed
  double rezone = 0;       ///< grains deleted, made and corrected by rezones

  /// The bracket of the host's own steps ends with the grains' energy `now` (the support
  /// force's kicks in it are measured apart).
  void close_dem_bracket(double now) {
    dem += now - energy - support_open;
    support += support_open;
    support_open = 0.0;
    energy = now;
  }
  /// A rezone left the grains with energy `after`.
  void close_rezone(double after) {
    rezone += after - energy;
    energy = after;
  }
  /// The agreement's velocity updates added `kicked` to the grains' kinetic energy.
  void add_agreement(double kicked) {
    agreement += kicked;
    energy += kicked;
  }
  /// What the ranks sum for the vector: start, energy, dem, agreement, support, rezone.
  static constexpr int kSums = 6;
  void sums(double out[kSums]) const {
    out[0] = start, out[1] = energy, out[2] = dem, out[3] = agreement, out[4] = support, out[5] = rezone;
  }
};

/// Entries of the fix's global vector (0-based; the docs count from 1).
enum ThermoEntry {
  kVecExchanges, kVecCoupledGrains, kVecPoints, kVecSharedNodes, kVecMismatch, kVecSubsteps, kVecMpmDt,
  kVecMass, kVecPx, kVecPy, kVecPz, kVecLx, kVecLy, kVecLz, kVecContinuumKE, kVecContinuumCells, kVecHybridCells,
  kVecDiscreteCells,
  // the energy ledger (J, J/m in 2D), as of the last exchange or rezone
  kVecEnergy, kVecEnergyGrains, kVecEnergyContinuum, kVecEnergyDem, kVecEnergyContinuumSteps, kVecEnergyAgreementGrains,
  kVecEnergyAgreementContinuum, kVecEnergySupport, kVecEnergyRezoneGrains, kVecEnergyRezoneContinuum,
  kVecEnergyResidual,
  // where the coupling's wall time went (coupler/coupling_timer.hpp), the ranks' mean (s): all of
  // it, waiting for the MPM process, rezones (with the oracle), all runs; then the coupling's share
  // of this run's wall time so far (%)
  kVecTimeCoupling, kVecTimeMpmWait, kVecTimeRezone, kVecTimeShare,
  // the shared nodes' mass above the packing's over their mass (StepAck::overlap)
  kVecOverlap,
  // of kVecEnergyContinuumSteps, the fill pressure's work (StepAck::energy_fill; not a term of the sum)
  kVecEnergyFill, kVecSize
};

/// The vector from the last acknowledgement of the MPM process (the continuum's figures, as of
/// the last exchange or rezone), the grains' totals (grain_totals, summed over the ranks), their
/// ledger's sums over the ranks and the continuum's energy when the ledger started.
void thermo_vector(const StepAck &ack, std::int64_t exchanges, std::int64_t coupled_grains,
                   const double grain_totals[7], const double ledger_sums[EnergyLedger::kSums],
                   double continuum_start, double out[kVecSize]);

}    // namespace coupler
