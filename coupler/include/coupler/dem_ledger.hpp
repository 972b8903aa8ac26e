#pragma once
// The DEM side's figures for thermo output: the grains' side of the energy ledger
// (docs/fix_hybrid_mpm.md, "Energy ledger") and the fix's global vector (entries 1-36, "Restart,
// fix_modify, output"). Host-neutral: the host sums its ranks' figures and prints the vector.

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include "coupler/protocol.hpp"
#include "coupler/zones.hpp"

namespace coupler {

/// Kinetic (translation and rotation) and potential energy of some grains (J; J/m in 2D).
struct GrainEnergy {
  double kinetic = 0, potential = 0;
  double total() const { return kinetic + potential; }
  GrainEnergy &operator+=(const GrainEnergy &o) {
    kinetic += o.kinetic, potential += o.potential;
    return *this;
  }
  GrainEnergy &operator-=(const GrainEnergy &o) {
    kinetic -= o.kinetic, potential -= o.potential;
    return *this;
  }
};

/// What rezones did to the grains' energy, by what they did to the grains: made from points
/// (enrichment), removed (homogenisation) and corrected (the kept and new grains' new share of
/// their cell's material and rigid velocity increment). The three sum to the ledger's rezone
/// term (EnergyLedger::rezone, entry 27), as the MPM process's split of the points' side sums to
/// entry 28. The same change again by the cells' RezoneMechanism (zones.hpp: enrichment,
/// homogenisation, repair), which the MPM process tallies for the points alike: the two sides'
/// sums per mechanism are what each mechanism did to grains and points together.
struct RezoneGrainEnergy {
  GrainEnergy made, removed, corrected;
  GrainEnergy by_mechanism[kMechanisms];
  double total() const { return made.total() + removed.total() + corrected.total(); }
  RezoneGrainEnergy &operator+=(const RezoneGrainEnergy &o) {
    made += o.made, removed += o.removed, corrected += o.corrected;
    for (int m = 0; m < kMechanisms; ++m) by_mechanism[m] += o.by_mechanism[m];
    return *this;
  }
  static constexpr int kSums = 2 * (3 + kMechanisms);    ///< the doubles the ranks sum (to_array, from_array)
  void to_array(double out[kSums]) const {
    const GrainEnergy *terms[] = {&made, &removed, &corrected, &by_mechanism[0], &by_mechanism[1], &by_mechanism[2]};
    for (int t = 0; t < kSums / 2; ++t) out[2 * t] = terms[t]->kinetic, out[2 * t + 1] = terms[t]->potential;
  }
  static RezoneGrainEnergy from_array(const double in[kSums]) {
    RezoneGrainEnergy e;
    GrainEnergy *terms[] = {&e.made, &e.removed, &e.corrected, &e.by_mechanism[0], &e.by_mechanism[1],
                            &e.by_mechanism[2]};
    for (int t = 0; t < kSums / 2; ++t) *terms[t] = {in[2 * t], in[2 * t + 1]};
    return e;
  }
};
static_assert(kMechanisms == 3, "RezoneGrainEnergy's arrays list the mechanisms one by one");

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
  kVecEnergyFill,
  // the energy guard's margin: the largest rise so far of entries 23-28 above their lowest, over the
  // scene's energy scale (EnergyGuard::largest_share; the run stops where it passes energy_guard)
  kVecGuardShare, kVecSize
};

/// The vector from the last acknowledgement of the MPM process (the continuum's figures, as of
/// the last exchange or rezone), the grains' totals (grain_totals, summed over the ranks), their
/// ledger's sums over the ranks and the continuum's energy when the ledger started.
void thermo_vector(const StepAck &ack, std::int64_t exchanges, std::int64_t coupled_grains,
                   const double grain_totals[7], const double ledger_sums[EnergyLedger::kSums],
                   double continuum_start, double out[kVecSize]);

/// Stops a run whose coupling makes energy (keyword `energy_guard`, docs/fix_hybrid_mpm.md
/// "Energy ledger"). Grains and points are two representations of one material: what the host's
/// own steps do (contacts, walls, inserted or deleted grains, driven bodies) aside, the rest of the
/// ledger (the continuum's steps, the agreements, the support force, the rezones: entries 23-28)
/// can only dissipate, up to the small step a rezone adds, and on the decks' runs with gravity its
/// rise above its lowest stays under 0.5 % of M |g| h. A support force that fed itself did 186 J/m of
/// work in 0.03 s on a deep silo holding 45 J/m, with the ledger closed and nothing said
/// (bench/results/adaptive_accuracy.md, 2026-12-03). The rezones count with the rest: the
/// continuum's steps are measured on the grid and a rezone on the points, so each alone shifts
/// energy to the other around a rezone, and a shrinking continuum's rezones are themselves a way
/// to blow up (the gravity-free test patches, whose whole regions flip zone, add up to 250 times
/// their energy and run unguarded).
class EnergyGuard {
public:
  /// `limit`: the largest rise allowed, as a share of the scene's energy scale (0: no guard);
  /// `gravity_height`: |g| times the box's extent along g (m^2/s^2), 0 without gravity.
  EnergyGuard(double limit, double gravity_height) : limit_(limit), gravity_height_(gravity_height) {}
  /// The guard of a box [lo, hi] under `gravity` (m/s^2) in `dimension` D: h is the box's
  /// extent along g.
  static EnergyGuard over_box(double limit, const double gravity[3], const double lo[3], const double hi[3],
                              int dimension) {
    double gravity_height = 0.0;
    for (int a = 0; a < dimension; a++) gravity_height += std::abs(gravity[a]) * (hi[a] - lo[a]);
    return EnergyGuard(limit, gravity_height);
  }

  /// The energy scale (J; J/m in 2D): the potential energy the largest mass seen so far could
  /// release across the box, M |g| h; without gravity the largest total energy seen.
  double scale() const { return gravity_height_ > 0 ? largest_mass_ * gravity_height_ : largest_energy_; }
  /// The largest rise above the lowest seen so far, over the scale at its time: how near the run
  /// came to the limit (tracked with or without one, so that a bench can report it).
  double largest_share() const { return largest_share_; }

  /// Look at the thermo vector at time `time` (s): an error message naming the energy made and
  /// the ledger's terms since their sum was lowest when it rose more than the limit, else "".
  std::string check(const double vec[kVecSize], double time);

private:
  static constexpr int kTerms = kVecEnergyRezoneContinuum - kVecEnergyContinuumSteps + 1;    // entries 23-28
  double limit_, gravity_height_;
  double largest_mass_ = 0, largest_energy_ = 0;
  double lowest_ = std::numeric_limits<double>::infinity();
  double lowest_time_ = 0;
  double largest_share_ = 0;
  double lowest_terms_[kTerms] = {};
};

}    // namespace coupler
