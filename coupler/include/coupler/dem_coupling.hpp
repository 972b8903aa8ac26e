#pragma once
// The DEM side's two coupled steps as whole sequences, for every host's fix (LAMMPS's and
// LIGGGHTS's fix hybrid/mpm): a coupling exchange (grains -> nodes, the agreement, the grains'
// velocity updates and support accelerations) and a rezone (zones, the moving cells' grain
// sums, enrichment, the MPM process's corrections, deletions, the support force). The host
// supplies its atoms (coupler/dem_grains.hpp) and the few things only it can do (create and
// delete atoms); it turns a failed outcome into its own error. Collective over the DEM ranks.
#include <mpi.h>

#include <cstdint>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "coupler/dem_grains.hpp"
#include "coupler/dem_ledger.hpp"
#include "coupler/dem_rezone.hpp"
#include "coupler/dem_session.hpp"
#include "coupler/fix_options.hpp"
#include "coupler/rezone_log.hpp"
#include "coupler/transfer.hpp"

namespace coupler {

/// What an exchange did on this rank (and, `coupled`, on all DEM ranks).
struct ExchangeTally {
  std::int64_t coupled = 0;    ///< grains coupled, all ranks
  double applying = 0.0;       ///< s spent applying the velocity updates (inside the round trip)
  double framing = 0.0;        ///< s spent collecting the output frame's grains (inside the round trip)
  double kicked = 0.0;         ///< kinetic energy the agreement added to this rank's grains (energy ledger)
};

/// One coupling exchange. `index`: this rank's coupled grains (coupled_grains); `header` is
/// sent with n_grains set to their count over the ranks. The agreed velocities change g.v;
/// support[i] becomes each coupled grain's support acceleration (zero for the others that had
/// one) and `supported` lists the grains with a non-zero one. `pic`: the share of the field
/// rule at every node, or kPicRegime to take each node's from the MPM process's answer (the
/// flow regime there). Local outcome (settle it).
template <int D>
StepOutcome exchange_grains(DemSession &session, MPI_Comm comm, GrainTransfer<D> &transfer, const DemGrains &g,
                            const std::vector<int> &index, StepHeader header, double pic, double **support,
                            std::vector<int> &supported,
                            const std::function<std::vector<GrainRecord>()> &frame_grains, StepAck &ack,
                            ExchangeTally &tally);

/// What a rezone needs the host to do to its atoms.
template <int D>
struct RezoneAtoms {
  std::function<DemGrains()> grains;    ///< this rank's atoms now (creating atoms may move the arrays)
  /// Makes the planned grain if its position is in this rank's sub-domain (mass share times
  /// its solid mass, weight share, the group's mask and type); true if made.
  std::function<bool(const PlannedGrain<D> &)> make;
  /// Deletes the flagged local atoms (flags as apply_corrections returns them).
  std::function<void(const std::vector<char> &)> remove;
  /// Grid cells in the discrete regions now (adaptive runs).
  std::function<std::vector<std::uint64_t>()> discrete_cells;
};

/// What a rezone did, over all DEM ranks.
struct RezoneCounts {
  std::int64_t deleted = 0, made = 0;
  RezoneGrainEnergy energy;    ///< what it did to the grains' energy, summed over the ranks
};

/// Everything a rezone needs besides the host's atoms.
template <int D>
struct RezonePlan {
  const GridGeometry<D> *grid = nullptr;
  StepHeader header;                     ///< kind kStepRezone, its zone source
  const OracleSettings *oracle = nullptr;
  const PackingTemplate<D> *packing = nullptr;
  GrainRules rules;
  double grain_diameter = 0.0;
  double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};    ///< the continuum's container
  double gravity[3] = {0, 0, 0};                  ///< the grains' potential energy (the ledger's split)
};

/// A rezone's zones, its first round trip (coupler/protocol.hpp): the new zone map and the
/// cells whose material moves. When none moves, the rezone ended there with its acknowledgement:
/// the host's atoms stay as they are (no atom made or deleted, no neighbour lists rebuilt).
template <int D>
struct ZoneAnswer {
  std::vector<signed char> zones;
  std::vector<RezoneCell<D>> cells;
  StepAck ack;                 ///< the rezone's acknowledgement when no material moves
  double oracle_wait = 0.0;    ///< s this rank waited for the zone map (the oracle)
  bool moves_material() const { return !cells.empty(); }
};

/// The first round trip of a rezone: this rank's grain volumes per cell go to the MPM process
/// with the plan's header (and the previous `zones` where the fix gives the zones), the answer
/// comes back. Settled outcome: the same on all ranks.
template <int D>
StepOutcome ask_zones(DemSession &session, const RezonePlan<D> &plan, const std::vector<signed char> &zones,
                      RezoneAtoms<D> &atoms, ZoneAnswer<D> &answer);

/// The rest of a rezone whose answer moves material (coupler/protocol.hpp): the material of every
/// moving cell moves between grains and points, the grains' support force after it goes to the
/// MPM process. `support` is the host's per-atom support acceleration (read after the deletions).
/// Settled outcome: the same on all ranks; on a failure the rezone stopped at that message.
template <int D>
StepOutcome move_material(DemSession &session, MPI_Comm comm, const RezonePlan<D> &plan,
                          const std::vector<RezoneCell<D>> &cells, RezoneAtoms<D> &atoms, double *const *support,
                          StepAck &ack, RezoneCounts &counts);

/// After a rezone, over all DEM ranks: the carried masses' drift from their share of the solid
/// mass (drift[0] the lightest's, negated, drift[1] the heaviest's), the largest atom ID (from
/// this rank's `max_tag`; new atoms have ID 0 until the host numbers them) and the hybrid grains.
struct RezoneAftermath {
  double drift[2] = {0, 0};
  double share_sums[2] = {0, 0};    ///< mass_drift's sums over the ranks: carried, weight times solid
  std::int64_t max_tag = 0;
  std::int64_t hybrid_grains = 0;    ///< grains of the group with a weight below 1, all ranks
};
RezoneAftermath rezone_aftermath(const DemGrains &g, const GrainRules &rules, std::int64_t max_tag, MPI_Comm comm);

/// The rezone's report line fields from its counts, acknowledgement and aftermath.
RezoneReport rezone_report(std::int64_t step, const RezoneCounts &counts, const StepAck &ack, double weight,
                           const RezoneAftermath &after);

/// Whether the exchange at step `now` is its run's last: the next one would come after the run's
/// last step.
inline bool last_exchange_of_run(std::int64_t now, int every, std::int64_t last_step) {
  return now + every > last_step;
}

/// Whether an exchange sends an output frame: every output_every-th exchange (from the first,
/// exchange count `exchanges` before it) and the last exchange of every run; never for 0. The
/// run's last frame is that of an exchange of the coupling's own cadence, not an extra exchange
/// at the run's end: writing frames must not change the run (docs/design.md section 2.3).
inline bool output_frame_due(int output_every, std::int64_t exchanges, bool run_ends) {
  return output_every > 0 && (run_ends || exchanges % output_every == 0);
}

/// The warning at the end of a run of `run_steps` steps that had no exchange (none of its steps a
/// multiple of `every`), so wrote no output frame; "" when frames are off or it had one.
std::string frameless_run_warning(int output_every, std::int64_t run_exchanges, std::int64_t run_steps, int every);

/// Totals of grains plus points before and after a rezone (mass, momentum, angular momentum):
/// the grains' (summed over the ranks) with the continuum's from the acknowledgement.
void rezone_totals(const double grains_before[7], const double grains_after[7], const StepAck &ack, double before[7],
                   double after[7]);

/// An error message if `made` new atoms (and `deleted` deleted) would overflow a host's atom
/// count (natoms, largest allowed max_natoms) or its atom IDs (largest ID in use max_tag,
/// largest allowed max_id); "" if they fit. `id_hint` says how to get larger IDs on this host.
std::string new_atoms_problem(std::int64_t made, std::int64_t deleted, std::int64_t natoms, std::int64_t max_natoms,
                              std::int64_t max_tag, std::int64_t max_id, std::int64_t step,
                              const std::string &host, const std::string &id_hint);


/// The handshake a host's fix sends: its options, box, step and time; the continuum's
/// container from the options (an error message in `problem` if an edge lies outside the box).
/// Gravity and the agreement time must be in options.continuum already.
Hello make_hello(const FixOptions &options, const std::string &host, const std::string &units, int dimension,
                 double dt, const double box_lo[3], const double box_hi[3], std::int64_t step, double time,
                 std::string &problem);

/// The group's grains on all DEM ranks, for the defaults of the continuum (mean diameter,
/// solid density) and of the grains made from points (size spread, groups, type).
struct GroupGrains {
  std::int64_t count = 0;
  double diameter_sum = 0.0, solid_mass_sum = 0.0, volume_sum = 0.0;
  double dmin = 0.0, dmax = 0.0;
  /// the least and largest solid density of a grain (mass over weight, over pi r^2 in 2D,
  /// 4/3 pi r^3 in 3D); grains with a weight below 1 (`weighted`) are left out
  double density_min = 0.0, density_max = 0.0;
  std::int64_t weighted = 0;
  int common_mask = ~0;    ///< the group bits every grain of the group has
  int smallest_type = 0;
};
/// Collective over comm. `type`: the host's per-atom type array (ntypes + 1 where the group is empty).
GroupGrains group_grains(const DemGrains &g, const int *type, int ntypes, int dimension, MPI_Comm comm);
/// The options' defaults from the group's grains (mean diameter, solid density unless given,
/// the new grains' type unless given); returns the new grains' mask and sets `polydispersity`.
int apply_group_defaults(FixOptions &options, const GroupGrains &gg, int groupbit, double &polydispersity);
/// An error message if the group's grains do not share one solid density, or if the fix line's
/// grain_density is not theirs; "" if they agree. Grains and points convert at one solid
/// density (docs/design.md 5.6): a rezone gives every grain it touches that density's mass.
/// Checked only while no grain has a weight below 1 (the grains as the deck made them: a
/// coupled state's light grains are not a deck's mistake).
std::string density_problem(const FixOptions &options, const GroupGrains &gg, int dimension);

/// The index of the first of `n` regions that holds no cell centre of the box (match(k, x):
/// region k holds point x), -1 if every one holds one: such a region converts nothing and is a
/// mistake (smaller than a cell, or outside the box).
template <int D>
int first_empty_region(const GridGeometry<D> &grid, const double box_lo[3], const double box_hi[3], int n,
                       const std::function<bool(int, const double *)> &match);
/// A region as the zone oracle sees it, whatever the host: `inside(x)` (x a 3-vector, z = 0 in
/// 2D) and, for a region fixed in space whose bounding box the host can compute, that box.
struct RegionShape {
  std::function<bool(const double *)> inside;
  bool bounded = false;
  double lo[3] = {0.0, 0.0, 0.0}, hi[3] = {0.0, 0.0, 0.0};
};
/// The RegionShape of a host's region (LAMMPS's and LIGGGHTS's Region alike: match, bboxflag,
/// extent_*, varshape, dynamic_check), after its prematch(); a moving or reshaping region's
/// bounding box is not kept up to date by its host, so only a fixed one is bounded.
template <class HostRegion>
RegionShape region_shape(HostRegion *r) {
  RegionShape s;
  s.inside = [r](const double *x) { return r->match(x[0], x[1], x[2]) != 0; };
  s.bounded = r->bboxflag && !r->varshape && !r->dynamic_check();
  if (s.bounded) {
    s.lo[0] = r->extent_xlo, s.lo[1] = r->extent_ylo, s.lo[2] = r->extent_zlo;
    s.hi[0] = r->extent_xhi, s.hi[1] = r->extent_yhi, s.hi[2] = r->extent_zhi;
  }
  return s;
}
/// Points per axis at which cells_touched samples a cell (offsets 1/6, 1/2, 5/6 of a cell).
inline constexpr int kCellSamplesPerAxis = 3;
/// The grid cells (ascending) that any of `regions` touches: a cell counts when any of
/// kCellSamplesPerAxis^D points spread evenly over it, its centre among them, lies in a region.
/// Cells are kept discrete where a region touches them: judged by their centres alone, a region
/// narrower than a cell may hold none (a 3D silo's outlet cylinder of the orifice's radius about
/// an axis on a node plane kept nothing discrete, and with the floor touched the continuum then
/// covered the orifice and nothing flowed out).
template <int D>
std::vector<std::uint64_t> cells_touched(const GridGeometry<D> &grid, const std::vector<RegionShape> &regions);
/// The index of the first region that touches no cell overlapping the box (cells_touched), -1 if
/// every one touches one: a discrete region smaller than a third of a cell, or outside the box,
/// keeps nothing discrete and is a mistake.
template <int D>
int first_untouching_region(const GridGeometry<D> &grid, const double box_lo[3], const double box_hi[3],
                            const std::vector<RegionShape> &regions);
/// Grid cells overlapping the box, per Zone (the padding cells around it are continuum by convention).
template <int D>
void zone_counts(const GridGeometry<D> &grid, const std::vector<signed char> &zones, const double box_lo[3],
                 const double box_hi[3], std::int64_t counts[3]);
/// "fix hybrid/mpm: N grid cells in the box: C continuum, H hybrid, D discrete"
std::string zone_counts_line(const std::int64_t counts[3]);

/// The fix's global record in a host's restart file: its cell, the exchanges so far, `every`,
/// whether the conversion happened (the MPM state then lives in the file written next to the
/// restart file), the coupling's clock.
struct RestartRecord {
  static constexpr int kValues = 6;
  double cell = 0.0;
  std::int64_t exchanges = 0;
  int every = 1;
  bool converted = false;
  double time = 0.0;
  std::int64_t step = 0;
  void write(double out[kValues]) const;
  static RestartRecord read(const double *in);
  /// The record as a fix writes it into its host's restart file (the size in bytes, then the
  /// values); the host calls it on its rank 0.
  void write_file(std::FILE *fp) const;
  /// The run's cell: a cell the grains chose (none on the input, `input_cell` <= 0) is the file's,
  /// the one the run started with (its grains have changed since); a given one is kept, with a
  /// warning if the file's differs ("" if not).
  std::string take_cell(double &input_cell) const;
  /// An error if the conversion happened and no MPM state is given ("" if fine).
  std::string state_problem(const std::string &mpm_state_path) const;
};
/// The coupling's clock: the simulated time the DEM side gives every step it sends the MPM
/// process. The host's own time at the first run, kept by the fix from then on (neither host keeps
/// the simulated time in its restart files: the fix's RestartRecord does), re-anchored when the
/// time step changes between runs. One expression for every step, so a time announced in advance
/// is the same bits as the time of that step when it comes.
struct CouplingClock {
  double time = 0.0;          ///< the time at `step`
  std::int64_t step = -1;     ///< -1 until the first run's setup
  double dt = 0.0;            ///< the step since then
  /// The time of `at`; before the first anchor, the host's: its time `host_time` at step
  /// `host_step` and its step `host_dt` (LAMMPS's update->atime, atimestep, dt).
  double time_of(std::int64_t at, double host_time, std::int64_t host_step, double host_dt) const {
    if (step < 0) return host_time + (at - host_step) * host_dt;
    return time + (at - step) * dt;
  }
  /// At every run's setup (step `now`): anchored at the first, again when the step changed.
  void start_run(std::int64_t now, double host_time, std::int64_t host_step, double host_dt) {
    if (step < 0 || dt != host_dt) {
      time = time_of(now, host_time, host_step, host_dt);
      step = now;
    }
    dt = host_dt;
  }
  /// From the fix's record in a restart file, at the host's step now.
  void restore(const RestartRecord &r, double host_dt) { time = r.time, step = r.step, dt = host_dt; }
};

/// When an exchange at step `now` knows the next one: the MPM process advances to its time while
/// the host computes the steps up to it (docs/design.md section 2.3).
struct ExchangeOutlook {
  std::int64_t now = 0;
  std::int64_t last_step = 0;      ///< the run's last step
  int every = 1;                   ///< keyword every
  bool rezone_next = false;        ///< the oracle's rezone follows this exchange
  bool restart_file = false;       ///< a restart file is written at a step in [now, now + every)
};
/// The step of the next exchange if it is certain now, else -1: not with a rezone or a restart
/// file before it (the MPM state must then be that of this exchange), nor when the run ends first.
std::int64_t next_exchange_step(const ExchangeOutlook &o);

/// "fix hybrid/mpm: MPM state saved to|loaded from PATH (N material points)"
std::string state_line(int kind, const std::string &path, std::int64_t points);

/// The MPM process keeps the gravity of the handshake (and the energy ledger its potential
/// energy): an error message if `now` differs from `then` beyond round-off, "" if not.
std::string gravity_change_problem(const double then[3], const double now[3]);

/// The continuum's constants from the calibrated material (keyword material) for the deck's
/// contact law `deck` (its mean_mass from the grains' mean diameter and density): an error
/// message if the material was calibrated for another law, "" when the constants were set.
std::string apply_deck_material(FixOptions &options, DeckContact deck);
/// "fix hybrid/mpm: material NAME (PATH): Young's modulus ... Pa, ..., critical packing ..."
std::string material_line(const FixOptions &options);

/// The start of a DEM program of the coupled MPMD job (lmp_hybrid, liggghts_hybrid): MPI_Init,
/// MPI_COMM_WORLD split by colour (kDemColor; mpm_solver takes kMpmColor, so the host never
/// sees the MPM ranks; run alone the split is a no-op), the MPI_Finalize hook installed with
/// the end-of-job barrier left to it (the hosts' Error::all ends in MPI_Finalize + exit(1)).
/// Returns the DEM ranks' communicator; aborts the job naming `program` on a failure. `host`
/// names the DEM host to the MPM process ("LAMMPS", "LIGGGHTS").
MPI_Comm start_dem_job(int *argc, char ***argv, const char *program, const std::string &host);
/// Its normal end: the MPM process is told if no fix ever connected (`unconnected`: why), then
/// the end-of-job barrier (coupler/protocol.hpp) and MPI_Finalize.
void end_dem_job(MPI_Comm dem_comm, const std::string &unconnected);
/// The normal end of the coupled run when the fix is deleted (unfix, clear, end of input): the
/// MPM process exits 0 and the peer is forgotten. Returns the log line, or "" with the failure
/// to tell it in `warning`.
std::string finish_coupled_run(Link &link, std::int64_t last_step, std::string &warning);

/// The fix's vector (thermo_vector) with the ledger's sums over the DEM ranks, and the energy
/// guard's verdict on it at DEM time `time` (s): its error text when the coupling made more energy
/// than the guard allows, else "" (also without a guard, before the ledger started). Collective.
std::string guarded_thermo_vector(const EnergyLedger &ledger, MPI_Comm comm, const StepAck &ack,
                                  std::int64_t exchanges, std::int64_t coupled_grains, const double grain_totals[7],
                                  double continuum_start, EnergyGuard *guard, double time, double out[kVecSize]);

}    // namespace coupler
