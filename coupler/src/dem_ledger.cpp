#include "coupler/dem_ledger.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

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
  out[kVecGuardShare] = 0.0;    // the guard's (guarded_thermo_vector)
}

std::string EnergyGuard::check(const double vec[kVecSize], double time) {
  largest_mass_ = std::max(largest_mass_, vec[kVecMass]);
  largest_energy_ = std::max(largest_energy_, std::abs(vec[kVecEnergy]));
  // what everything but the host's own steps changed since the start
  double made = 0.0;
  for (int k = 0; k < kTerms; k++) made += vec[kVecEnergyContinuumSteps + k];
  if (made < lowest_) {
    lowest_ = made, lowest_time_ = time;
    std::copy(vec + kVecEnergyContinuumSteps, vec + kVecEnergyContinuumSteps + kTerms, lowest_terms_);
    return "";
  }
  const double rise = made - lowest_, scale = this->scale();
  if (scale > 0) largest_share_ = std::max(largest_share_, rise / scale);
  if (!(limit_ > 0) || !(scale > 0) || rise <= limit_ * scale) return "";
  double d[kTerms];
  for (int k = 0; k < kTerms; k++) d[k] = vec[kVecEnergyContinuumSteps + k] - lowest_terms_[k];
  char text[1024];
  std::snprintf(text, sizeof text,
                "the coupling made %.4g J (J/m in 2D) of energy between t = %.6g s and t = %.6g s, %.3g %% of the "
                "scene's energy scale %.4g J (M |g| h, or the largest energy without gravity), above the limit "
                "energy_guard %g. Since then (thermo entries 23-28): the continuum's own steps %+.4g, the agreements "
                "%+.4g on the grains and %+.4g on the nodes, the support force's kicks %+.4g, the rezones %+.4g on "
                "the grains and %+.4g on the points. Two representations of one material cannot make energy, so this "
                "is an instability of the coupling: where the support force fed itself, try a smaller gain (support "
                "0.5), exchanges more often (a smaller every) or no fill pressure (fill 0); where the rezones made it, "
                "coarser cells or a wider band; energy_guard 0 lets the run go on",
                rise, lowest_time_, time, 100.0 * rise / scale, scale, limit_, d[0], d[1], d[2], d[3], d[4], d[5]);
  return text;
}

}    // namespace coupler
