#include "coupler/dem_run_log.hpp"

#include <cstdio>

namespace coupler {

void DemRunLog::start_run(std::int64_t first_step) {
  run_.clear();
  run_start_ = MPI_Wtime();
  interval_.restart(first_step);
  whole_run_.restart(first_step);
}

void DemRunLog::charge(CouplingSection section, double seconds) {
  run_.add(section, seconds);
  all_.add(section, seconds);
}

void DemRunLog::charge_exchange(double start, double sent, double replied, double end, double applying,
                                double framing) {
  // the round trip is the wait for the MPM process, less the grains' updates and the output frame
  // the session calls back for inside it
  charge(kTimeMpmWait, replied - sent - applying - framing);
  charge(kTimeApply, applying);
  charge(kTimeOutput, framing);
  charge(kTimeExchange, (end - start) - (replied - sent));
  run_.exchanges++;
  all_.exchanges++;
}

void DemRunLog::charge_rezone(double start, double oracle_wait, bool ends) {
  charge(kTimeOracle, oracle_wait);
  charge(kTimeRezone, MPI_Wtime() - start - oracle_wait);
  if (!ends) return;
  run_.rezones++;
  all_.rezones++;
}

std::string DemRunLog::rezone(const RezoneReport &report, bool conversion, RezoneLog level, const double before[7],
                              const double after[7]) {
  interval_.add(report);
  whole_run_.add(report);
  if (level == RezoneLog::kFull || (level == RezoneLog::kSummary && conversion))
    return rezone_line(report) + "\n" + rezone_totals_line(report.step, before, after) + "\n";
  return "";
}

std::string DemRunLog::summary(bool end_of_run, RezoneLog level, std::int64_t step) {
  RezoneTally &tally = end_of_run ? whole_run_ : interval_;
  const bool shown = end_of_run || level != RezoneLog::kQuiet;
  std::string line;
  if (shown && tally.rezones() > 0)
    line = tally.summary_line(end_of_run ? kSummaryRun : kSummaryInterval, step) + "\n";
  if (end_of_run && tally.rezones() > 0) line += tally.energy_line(kSummaryRun, step) + "\n";
  tally.restart(step + 1);
  return line;
}

void DemRunLog::thermo_times(MPI_Comm comm, double out[kVecSize]) const {
  int nprocs = 1;
  MPI_Comm_size(comm, &nprocs);
  const double local[5] = {all_.total(), all_.seconds[kTimeMpmWait],
                           all_.seconds[kTimeRezone] + all_.seconds[kTimeOracle], run_.total(),
                           MPI_Wtime() - run_start_};
  double sum[5];
  MPI_Allreduce(local, sum, 5, MPI_DOUBLE, MPI_SUM, comm);
  out[kVecTimeCoupling] = sum[0] / nprocs;
  out[kVecTimeMpmWait] = sum[1] / nprocs;
  out[kVecTimeRezone] = sum[2] / nprocs;
  out[kVecTimeShare] = sum[4] > 0.0 ? 100.0 * sum[3] / sum[4] : 0.0;
}

std::string DemRunLog::timing_breakdown(MPI_Comm comm, const std::string &host, const HostTimers &timers) const {
  int nprocs = 1, me = 0;
  MPI_Comm_size(comm, &nprocs);
  MPI_Comm_rank(comm, &me);
  const double wall_local = MPI_Wtime() - run_start_;
  double wall = 0.0;
  MPI_Allreduce(&wall_local, &wall, 1, MPI_DOUBLE, MPI_SUM, comm);
  wall /= nprocs;

  constexpr int n = kTimeSections + 1;    // the sections and their total
  double t[n], t_sq[n], t_min[n], t_max[n], t_sum[n], t_sq_sum[n];
  for (int k = 0; k < kTimeSections; k++) t[k] = run_.seconds[k];
  t[n - 1] = run_.total();
  for (int k = 0; k < n; k++) t_sq[k] = t[k] * t[k];
  MPI_Allreduce(t, t_min, n, MPI_DOUBLE, MPI_MIN, comm);
  MPI_Allreduce(t, t_max, n, MPI_DOUBLE, MPI_MAX, comm);
  MPI_Allreduce(t, t_sum, n, MPI_DOUBLE, MPI_SUM, comm);
  MPI_Allreduce(t_sq, t_sq_sum, n, MPI_DOUBLE, MPI_SUM, comm);

  // the host's own timers of this run (wall time, the ranks' mean)
  const double host_local[4] = {timers.pair, timers.neigh, timers.comm, timers.modify};
  double dem[4];
  MPI_Allreduce(host_local, dem, 4, MPI_DOUBLE, MPI_SUM, comm);
  for (double &d : dem) d /= nprocs;
  if (me != 0) return "";

  std::string block = timing_header("\nfix hybrid/mpm timing breakdown (" + std::to_string(run_.exchanges) +
                                    " exchanges, " + std::to_string(run_.rezones) + " rezones):");
  for (int k = 0; k < kTimeSections; k++)
    block += timing_line(kTimeSectionLabels[k], section_timing(t_min[k], t_max[k], t_sum[k], t_sq_sum[k], nprocs, wall));
  const SectionTiming total = section_timing(t_min[n - 1], t_max[n - 1], t_sum[n - 1], t_sq_sum[n - 1], nprocs, wall);
  block += timing_line("Coupling", total);
  char line[400];
  std::snprintf(line, sizeof(line),
                "DEM side (%s timer, avg): Pair %.5g Neigh %.5g Comm %.5g %s %.5g s; coupling %.5g s of %.5g s "
                "wall (%.2f%%, part of %s)\n",
                host.c_str(), dem[0], dem[1], dem[2], timers.modify_name, dem[3], total.avg, wall, total.percent,
                timers.modify_name);
  return block + line;
}

}    // namespace coupler
