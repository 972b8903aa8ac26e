#pragma once
// The DEM side's account of a coupled run, for every host's fix (LAMMPS's and LIGGGHTS's fix
// hybrid/mpm): where the coupling's wall time went (this run's and all runs'; docs/fix_hybrid_mpm.md,
// "Timing breakdown", and the thermo vector's entries 30-33) and the rezones since the last thermo
// output and since the run's start (keyword rezone_log). Host-neutral: the host calls it from its
// hooks, passes its own timers and prints the lines it returns (on its rank 0).

#include <mpi.h>

#include <cstdint>
#include <string>

#include "coupler/coupling_timer.hpp"
#include "coupler/dem_ledger.hpp"
#include "coupler/rezone_log.hpp"

namespace coupler {

/// A host's own timers of a run, wall time on this rank (s), for the breakdown's last line: its
/// pair, neighbour and communication times, and the one its fixes' time (the coupling's among it)
/// is part of, by the name the host's own breakdown gives it (LAMMPS's "Modify"; LIGGGHTS 3.8
/// times no fixes apart: its "Other", the loop less its timed sections).
struct HostTimers {
  double pair = 0, neigh = 0, comm = 0, modify = 0;
  const char *modify_name = "Modify";
};

class DemRunLog {
 public:
  /// A run starts (the host's setup, before the handshake of the first run): this run's timing
  /// and the rezone tallies start again; `first_step` is the run's first step.
  void start_run(std::int64_t first_step);

  /// Wall time spent in a section (this run's and all runs').
  void charge(CouplingSection section, double seconds);
  /// An exchange timed with MPI_Wtime: it started at `start`, sent its sums at `sent`, had the
  /// reply at `replied` and ended at `end`; inside the round trip it spent `applying` on the
  /// grains' updates and `framing` on the output frame's grains (coupler::ExchangeTally).
  void charge_exchange(double start, double sent, double replied, double end, double applying, double framing);
  /// A rezone, or its part, that started at `start` (MPI_Wtime) and ends now, `oracle_wait` of it
  /// waiting for the zone map; counted once, by the part that ends it (`ends`: the oracle's answer
  /// at post_integrate is a part when its rezone goes on at pre_exchange).
  void charge_rezone(double start, double oracle_wait, bool ends = true);

  /// A rezone happened (every rank calls this): counted in the summaries. Returns its two lines
  /// (each ending in a newline) where the log shows them: every rezone with `full`, the conversion
  /// (`conversion`: its zones are not the oracle's) also with `summary`; "" otherwise.
  std::string rezone(const RezoneReport &report, bool conversion, RezoneLog level, const double before[7],
                     const double after[7]);
  /// The summary line (ending in a newline) of the rezones since the last thermo output
  /// (`end_of_run` false; not with `quiet`) or of the run's (true, followed by the line of what
  /// they did to the grains' energy), "" if there were none or it is not shown; that tally starts
  /// again after `step`.
  std::string summary(bool end_of_run, RezoneLog level, std::int64_t step);

  /// The thermo vector's timing entries (kVecTimeCoupling..kVecTimeShare) into `out`: the ranks'
  /// means of all runs' coupling, MPM wait and rezone (with oracle) times, and this run's share.
  /// Collective over comm.
  void thermo_times(MPI_Comm comm, double out[kVecSize]) const;

  /// The run's breakdown in the columns of LAMMPS's "MPI task timing breakdown" and a last line
  /// with the host's own timers (`host` names it: "LAMMPS", "LIGGGHTS"). Collective over comm;
  /// the block on rank 0, "" on the others.
  std::string timing_breakdown(MPI_Comm comm, const std::string &host, const HostTimers &timers) const;

  const CouplingTimer &run_timing() const { return run_; }
  const CouplingTimer &all_timing() const { return all_; }

 private:
  CouplingTimer run_, all_;
  double run_start_ = 0.0;    // MPI_Wtime at start_run
  RezoneTally interval_, whole_run_;
};

}    // namespace coupler
