#include "coupler/dem_ledger.hpp"

namespace coupler {

void thermo_vector(const StepAck &a, std::int64_t exchanges, std::int64_t coupled_grains,
                   const double grain_totals[7], const double sum[EnergyLedger::kSums], double continuum_start,
                   double out[kVecSize]) {
  out[kVecExchanges] = static_cast<double>(exchanges);
  out[kVecCoupledGrains] = static_cast<double>(coupled_grains);
  out[kVecPoints] = static_cast<double>(a.points);
  out[kVecSharedNodes] = static_cast<double>(a.shared_nodes);
  out[kVecMismatch] = a.mismatch;
  out[kVecSubsteps] = a.substeps;
  out[kVecMpmDt] = a.mpm_dt;
  out[kVecMass] = grain_totals[0] + a.mass;
  for (int d = 0; d < 3; d++) {
    out[kVecPx + d] = grain_totals[1 + d] + a.momentum[d];
    out[kVecLx + d] = grain_totals[4 + d] + a.angular[d];
  }
  out[kVecContinuumKE] = a.kinetic_energy;
  out[kVecContinuumCells] = static_cast<double>(a.zone_cells[kContinuum]);
  out[kVecHybridCells] = static_cast<double>(a.zone_cells[kHybrid]);
  out[kVecDiscreteCells] = static_cast<double>(a.zone_cells[kDiscrete]);

  out[kVecEnergyGrains] = sum[1];
  out[kVecEnergyContinuum] = a.energy;
  out[kVecEnergy] = sum[1] + a.energy;
  out[kVecEnergyDem] = sum[2];
  out[kVecEnergyContinuumSteps] = a.energy_physics;
  out[kVecEnergyAgreementGrains] = sum[3];
  out[kVecEnergyAgreementContinuum] = a.energy_agreement;
  out[kVecEnergySupport] = sum[4];
  out[kVecEnergyRezoneGrains] = sum[5];
  out[kVecEnergyRezoneContinuum] = a.energy_rezone;
  double changes = 0.0;
  for (int k = kVecEnergyDem; k <= kVecEnergyRezoneContinuum; k++) changes += out[k];
  out[kVecEnergyResidual] = out[kVecEnergy] - (sum[0] + continuum_start) - changes;
  // the timing entries are the host's (its wall clock)
  for (int k = kVecTimeCoupling; k <= kVecTimeShare; k++) out[k] = 0.0;
  out[kVecOverlap] = a.overlap;
  out[kVecEnergyFill] = a.energy_fill;
}

}    // namespace coupler
