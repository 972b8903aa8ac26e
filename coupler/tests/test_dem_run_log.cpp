// The DEM side's account of a coupled run that the LAMMPS and LIGGGHTS fixes share
// (coupler/dem_run_log.hpp): the coupling's sections of wall time over the ranks, the thermo
// vector's timing entries, the breakdown in LAMMPS's columns, the rezone log's lines and
// summaries at each level, and fix_modify's keywords (coupler/fix_options.hpp). Runs in
// coupler_mpi_tests on 2 ranks.
#include <gtest/gtest.h>
#include <mpi.h>

#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "coupler/dem_run_log.hpp"
#include "coupler/fix_options.hpp"

namespace {

int rank() {
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}

int ranks() {
  int n = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &n);
  return n;
}

std::vector<std::string> lines_of(const std::string &text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string ln; std::getline(in, ln);) out.push_back(ln);
  return out;
}

TEST(DemRunLog, ExchangeTimesGoToTheirSectionsAndTheThermoEntriesAreTheRanksMeans) {
  coupler::DemRunLog log;
  log.start_run(1);
  const double r = rank() + 1.0;    // rank 0 spends 1x, rank 1 2x
  // started at 0, sent at 1 r, reply at 5 r (of which 0.5 r applying, 0.25 r framing), ended at 6 r
  log.charge_exchange(0.0, 1.0 * r, 5.0 * r, 6.0 * r, 0.5 * r, 0.25 * r);
  log.charge(coupler::kTimeApply, 0.1 * r);
  const coupler::CouplingTimer &t = log.run_timing();
  EXPECT_DOUBLE_EQ(t.seconds[coupler::kTimeMpmWait], 3.25 * r);
  EXPECT_DOUBLE_EQ(t.seconds[coupler::kTimeApply], 0.6 * r);
  EXPECT_DOUBLE_EQ(t.seconds[coupler::kTimeOutput], 0.25 * r);
  EXPECT_DOUBLE_EQ(t.seconds[coupler::kTimeExchange], 2.0 * r);    // (6 - 0) - (5 - 1)
  EXPECT_DOUBLE_EQ(t.total(), 6.1 * r);
  EXPECT_EQ(t.exchanges, 1);
  // a negative interval (a clock going backwards) charges nothing
  log.charge(coupler::kTimeOutput, -1.0);
  EXPECT_DOUBLE_EQ(log.run_timing().seconds[coupler::kTimeOutput], 0.25 * r);

  double out[coupler::kVecSize] = {};
  log.thermo_times(MPI_COMM_WORLD, out);
  const double mean = ranks() == 2 ? 1.5 : 1.0;
  EXPECT_DOUBLE_EQ(out[coupler::kVecTimeCoupling], 6.1 * mean);
  EXPECT_DOUBLE_EQ(out[coupler::kVecTimeMpmWait], 3.25 * mean);
  EXPECT_DOUBLE_EQ(out[coupler::kVecTimeRezone], 0.0);
  // these charges are far longer than the run's wall time so far: its share is over 100 %
  EXPECT_GT(out[coupler::kVecTimeShare], 100.0);

  // a new run clears this run's timing, not all runs'
  log.start_run(11);
  EXPECT_DOUBLE_EQ(log.run_timing().total(), 0.0);
  EXPECT_DOUBLE_EQ(log.all_timing().total(), 6.1 * r);
  EXPECT_EQ(log.all_timing().exchanges, 1);
}

TEST(DemRunLog, RezoneTimeLeavesTheOracleWaitApart) {
  coupler::DemRunLog log;
  log.start_run(1);
  const double start = MPI_Wtime() - 2.0;    // a rezone that took 2 s, 0.5 s of it the oracle
  log.charge_rezone(start, 0.5);
  EXPECT_DOUBLE_EQ(log.run_timing().seconds[coupler::kTimeOracle], 0.5);
  EXPECT_NEAR(log.run_timing().seconds[coupler::kTimeRezone], 1.5, 0.1);
  EXPECT_EQ(log.run_timing().rezones, 1);
  // another: its oracle's part (0.25 s, all of it the wait) at post_integrate, the rest (0.5 s) at
  // pre_exchange; one rezone
  log.charge_rezone(MPI_Wtime() - 0.25, 0.25, false);
  EXPECT_EQ(log.run_timing().rezones, 1);
  log.charge_rezone(MPI_Wtime() - 0.5, 0.0);
  EXPECT_DOUBLE_EQ(log.run_timing().seconds[coupler::kTimeOracle], 0.75);
  EXPECT_NEAR(log.run_timing().seconds[coupler::kTimeRezone], 2.0, 0.1);
  EXPECT_EQ(log.run_timing().rezones, 2);
  double out[coupler::kVecSize] = {};
  log.thermo_times(MPI_COMM_WORLD, out);
  EXPECT_NEAR(out[coupler::kVecTimeRezone], 2.75, 0.1);    // with the oracle's wait
  EXPECT_DOUBLE_EQ(out[coupler::kVecTimeMpmWait], 0.0);
}

TEST(DemRunLog, BreakdownHasLammpsColumnsAndTheHostsTimers) {
  coupler::DemRunLog log;
  log.start_run(1);
  log.charge(coupler::kTimeMpmWait, 0.004 * (rank() + 1));
  log.charge(coupler::kTimeExchange, 0.001);
  coupler::HostTimers timers;
  timers.pair = 1.0, timers.neigh = 2.0, timers.comm = 3.0, timers.modify = 4.0 + rank();
  timers.modify_name = "Other";
  const std::string block = log.timing_breakdown(MPI_COMM_WORLD, "LIGGGHTS", timers);
  if (rank() != 0) {
    EXPECT_EQ(block, "");
    return;
  }
  const auto lines = lines_of(block);
  ASSERT_EQ(lines.size(), 12u) << block;    // blank, title, columns, rule, 6 sections, total, host line
  EXPECT_EQ(lines[1], "fix hybrid/mpm timing breakdown (0 exchanges, 0 rezones):");
  EXPECT_EQ(lines[2], "Section |  min time  |  avg time  |  max time  |%varavg| %total");
  EXPECT_EQ(lines[5].substr(0, 9), "MPM wait|");
  EXPECT_EQ(lines[10].substr(0, 9), "Coupling|");
  const double wait_max = ranks() == 2 ? 0.008 : 0.004, wait_avg = ranks() == 2 ? 0.006 : 0.004;
  char expect[80];
  std::snprintf(expect, sizeof(expect), "MPM wait| %-11.5g| %-11.5g| %-11.5g|", 0.004, wait_avg, wait_max);
  EXPECT_EQ(lines[5].substr(0, std::string(expect).size()), expect) << lines[5];
  const std::string modify = ranks() == 2 ? "Other 4.5 s" : "Other 4 s";
  EXPECT_EQ(lines[11].rfind("DEM side (LIGGGHTS timer, avg): Pair 1 Neigh 2 Comm 3 " + modify + "; coupling ", 0), 0u)
      << lines[11];
  EXPECT_NE(lines[11].find("%, part of Other)"), std::string::npos) << lines[11];
}

coupler::RezoneReport report(std::int64_t step, std::int64_t deleted) {
  coupler::RezoneReport r;
  r.step = step, r.grains_deleted = deleted, r.points_made = deleted / 2, r.moved_cells = 1;
  return r;
}

TEST(DemRunLog, RezoneLinesAndSummariesFollowTheLogLevel) {
  const double totals[7] = {1, 2, 3, 4, 5, 6, 7};
  for (auto level : {coupler::RezoneLog::kFull, coupler::RezoneLog::kSummary, coupler::RezoneLog::kQuiet}) {
    coupler::DemRunLog log;
    log.start_run(1);
    const std::string conversion = log.rezone(report(1, 10), true, level, totals, totals);
    const std::string oracle = log.rezone(report(5, 4), false, level, totals, totals);
    EXPECT_EQ(lines_of(conversion).size(), level == coupler::RezoneLog::kQuiet ? 0u : 2u);
    EXPECT_EQ(lines_of(oracle).size(), level == coupler::RezoneLog::kFull ? 2u : 0u);
    if (level != coupler::RezoneLog::kQuiet)
      EXPECT_EQ(conversion.rfind("fix hybrid/mpm: step 1: 10 grains became 5 material points", 0), 0u) << conversion;
    // at thermo output (step 10): the two rezones, then none until the next
    const std::string at_thermo = log.summary(false, level, 10);
    if (level == coupler::RezoneLog::kQuiet) {
      EXPECT_EQ(at_thermo, "");
    } else {
      EXPECT_EQ(at_thermo.rfind("fix hybrid/mpm: steps 1-10: 2 rezones: 14 grains became 7 material points", 0), 0u)
          << at_thermo;
    }
    EXPECT_EQ(log.summary(false, level, 20), "");
    // the run's summary at every level, over both rezones
    const std::string run = log.summary(true, level, 30);
    EXPECT_EQ(run.rfind("fix hybrid/mpm: run of steps 1-30: 2 rezones: 14 grains became", 0), 0u) << run;
    EXPECT_EQ(run.back(), '\n');
    EXPECT_EQ(log.summary(true, level, 40), "");
  }
}

TEST(DemRunLog, TheRunsSummaryEndsWithWhatItsRezonesDidToTheGrainsEnergy) {
  // two rezones' splits (J): the run's line has their sums, term by term; the thermo intervals'
  // summaries do not print it, and a run without rezones prints neither
  const double totals[7] = {1, 2, 3, 4, 5, 6, 7};
  coupler::DemRunLog log;
  log.start_run(1);
  coupler::RezoneReport first = report(1, 10), second = report(5, 4);
  first.grain_energy.made = {0.5, 0.25}, first.grain_energy.removed = {-2, -1}, first.grain_energy.corrected = {0.125, 0};
  second.grain_energy.made = {1, 0.75}, second.grain_energy.removed = {-0.5, -4}, second.grain_energy.corrected = {-1, 2};
  // the same changes by the cells' zone change (each rezone's sum is its own)
  first.grain_energy.by_mechanism[coupler::kEnrichment] = {0.5, 0.25};
  first.grain_energy.by_mechanism[coupler::kHomogenisation] = {-1.875, -1};
  second.grain_energy.by_mechanism[coupler::kHomogenisation] = {-1.5, -1.25};
  second.grain_energy.by_mechanism[coupler::kRepair] = {1, 0};
  log.rezone(first, true, coupler::RezoneLog::kSummary, totals, totals);
  log.rezone(second, false, coupler::RezoneLog::kSummary, totals, totals);
  const std::string interval = log.summary(false, coupler::RezoneLog::kSummary, 10);
  EXPECT_EQ(lines_of(interval).size(), 1u) << interval;
  const std::vector<std::string> run = lines_of(log.summary(true, coupler::RezoneLog::kSummary, 30));
  ASSERT_EQ(run.size(), 2u);
  EXPECT_EQ(run[1], "fix hybrid/mpm: run of steps 1-30: the rezones' energy on the grains (J, J/m in 2D): made 2.5 "
                    "(kinetic 1.5, potential 1), removed -7.5 (kinetic -2.5, potential -5), corrected 1.125 (kinetic "
                    "-0.875, potential 2); by the cells' zone change: enrichment 0.75 (kinetic 0.5, potential "
                    "0.25), homogenisation -5.625 (kinetic -3.375, potential -2.25), repair 1 (kinetic 1, potential "
                    "0); in all -3.875");
  coupler::DemRunLog quiet;
  quiet.start_run(31);
  EXPECT_EQ(quiet.summary(true, coupler::RezoneLog::kSummary, 40), "");
}

TEST(DemRunLog, FixModifyTakesRezoneLogAndTheOraclesKeywordsOnly) {
  coupler::FixOptions o;
  o.adapt_every = 10, o.cell = 0.01;
  EXPECT_TRUE(coupler::modify_option(o, "rezone_log", "quiet", 3));
  EXPECT_EQ(o.rezone_log, coupler::RezoneLog::kQuiet);
  EXPECT_TRUE(coupler::modify_option(o, "depth", "0.05", 3));
  EXPECT_DOUBLE_EQ(o.oracle.continuum_depth, 0.05);
  EXPECT_DOUBLE_EQ(o.oracle.band, 0.01);    // its default followed from the cell
  EXPECT_FALSE(coupler::modify_option(o, "cell", "0.02", 3));
  EXPECT_DOUBLE_EQ(o.cell, 0.01);
  EXPECT_THROW(coupler::modify_option(o, "rezone_log", "loud", 3), coupler::OptionError);
  EXPECT_THROW(coupler::modify_option(o, "depth", "0.005", 3), coupler::OptionError);    // not above band
}

}    // namespace
