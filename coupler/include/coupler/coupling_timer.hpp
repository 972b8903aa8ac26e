#pragma once
// Where the coupled run's wall time goes on the DEM side (docs/fix_hybrid_mpm.md, "Timing
// breakdown"): an accumulator per section, and the min/avg/max/%varavg/%total arithmetic of
// LAMMPS's "MPI task timing breakdown" (its Finish class) over the host's ranks. Host-neutral:
// the host measures (its wall clock), reduces over its ranks and prints.

#include <array>
#include <cstdint>
#include <string>

namespace coupler {

/// The sections of the coupling's wall time on one DEM rank.
enum CouplingSection {
  kTimeExchange,    ///< packing the grains' node sums, sending them, the exchange's own reductions
  kTimeMpmWait,     ///< waiting for the MPM process's reply (its substeps, as seen from the host)
  kTimeApply,       ///< applying the agreed velocities and the support force
  kTimeRezone,      ///< rezones: grains made and deleted, their round trips (not the oracle)
  kTimeOracle,      ///< a rezone's wait for the new zone map (the oracle runs in the MPM process)
  kTimeOutput,      ///< the grains of output frames, the fix's log lines
  kTimeSections
};

/// Labels as LAMMPS prints them (8 characters at most).
inline constexpr std::array<const char *, kTimeSections> kTimeSectionLabels = {"Exchange", "MPM wait", "Apply",
                                                                              "Rezone",   "Oracle",   "Output"};

/// One rank's accumulated wall time per section (s), and what happened in it.
struct CouplingTimer {
  std::array<double, kTimeSections> seconds{};
  std::int64_t exchanges = 0;
  std::int64_t rezones = 0;

  void add(CouplingSection section, double s) { seconds[section] += s > 0.0 ? s : 0.0; }
  /// All sections.
  double total() const;
  void clear() { *this = CouplingTimer{}; }
};

/// One section over the ranks, as a line of LAMMPS's breakdown.
struct SectionTiming {
  double min = 0;       ///< s, the fastest rank
  double avg = 0;       ///< s, the ranks' mean
  double max = 0;       ///< s, the slowest rank
  double varavg = 0;    ///< LAMMPS's %varavg: sqrt(<t^2>/<t> - <t>) * 100, 0 below 1 ms
  double percent = 0;   ///< avg over the run's wall time, %
};

/// A section from the reductions over `nprocs` ranks of its time t: min, max, sum of t, sum of
/// t^2; `wall` is the run's wall time (the ranks' mean). As LAMMPS's Finish::mpi_timings.
SectionTiming section_timing(double min, double max, double sum, double sum_sq, int nprocs, double wall);

/// The breakdown's header: title, column names, rule (lines end with a newline).
std::string timing_header(const std::string &title);
/// One line: "Label   |  min |  avg |  max |%varavg| %total".
std::string timing_line(const std::string &label, const SectionTiming &t);

}    // namespace coupler
