// The coupling's timing breakdown (coupler/coupling_timer.hpp): the accumulator and the
// min/avg/max/%varavg/%total arithmetic of LAMMPS's "MPI task timing breakdown".
#include <gtest/gtest.h>

#include <cmath>
#include <regex>

#include "coupler/coupling_timer.hpp"

namespace {

TEST(CouplingTimer, SumsItsSectionsAndIgnoresNegativeIntervals) {
  coupler::CouplingTimer t;
  t.add(coupler::kTimeExchange, 0.25);
  t.add(coupler::kTimeMpmWait, 1.5);
  t.add(coupler::kTimeMpmWait, 0.5);
  t.add(coupler::kTimeOracle, -1.0e-9);    // a clock's round-off in a difference of intervals
  t.exchanges = 3;
  EXPECT_DOUBLE_EQ(t.seconds[coupler::kTimeMpmWait], 2.0);
  EXPECT_DOUBLE_EQ(t.seconds[coupler::kTimeOracle], 0.0);
  EXPECT_DOUBLE_EQ(t.total(), 2.25);
  t.clear();
  EXPECT_DOUBLE_EQ(t.total(), 0.0);
  EXPECT_EQ(t.exchanges, 0);
}

TEST(CouplingTimer, MinAvgMaxAndPercentOverRanks) {
  // three ranks: 1, 2 and 3 s of a 10 s run
  const double times[3] = {1.0, 2.0, 3.0};
  double sum = 0, sum_sq = 0;
  for (double t : times) sum += t, sum_sq += t * t;
  const coupler::SectionTiming s = coupler::section_timing(1.0, 3.0, sum, sum_sq, 3, 10.0);
  EXPECT_DOUBLE_EQ(s.min, 1.0);
  EXPECT_DOUBLE_EQ(s.max, 3.0);
  EXPECT_DOUBLE_EQ(s.avg, 2.0);
  EXPECT_DOUBLE_EQ(s.percent, 20.0);
  // LAMMPS's %varavg: sqrt(<t^2>/<t> - <t>) * 100 = sqrt((14/3)/2 - 2) * 100
  EXPECT_NEAR(s.varavg, std::sqrt(14.0 / 6.0 - 2.0) * 100.0, 1e-9);
}

TEST(CouplingTimer, BalancedOrTinySectionsHaveNoVariationAndNoWallTimeNoPercent) {
  const coupler::SectionTiming even = coupler::section_timing(2.0, 2.0, 4.0, 8.0, 2, 4.0);
  EXPECT_DOUBLE_EQ(even.varavg, 0.0);
  EXPECT_DOUBLE_EQ(even.percent, 50.0);
  const coupler::SectionTiming tiny = coupler::section_timing(0.0, 0.001, 0.001, 1e-6, 2, 1.0);
  EXPECT_DOUBLE_EQ(tiny.varavg, 0.0);    // under 1 ms on average, as LAMMPS
  EXPECT_DOUBLE_EQ(coupler::section_timing(1.0, 1.0, 1.0, 1.0, 1, 0.0).percent, 0.0);
  EXPECT_DOUBLE_EQ(coupler::section_timing(1.0, 1.0, 1.0, 1.0, 0, 1.0).avg, 0.0);
}

TEST(CouplingTimer, LinesInLammpsColumns) {
  const std::string head = coupler::timing_header("fix hybrid/mpm timing breakdown (2 exchanges, 0 rezones):");
  EXPECT_EQ(head,
            "fix hybrid/mpm timing breakdown (2 exchanges, 0 rezones):\n"
            "Section |  min time  |  avg time  |  max time  |%varavg| %total\n"
            "---------------------------------------------------------------\n");
  const std::string line = coupler::timing_line("MPM wait", coupler::section_timing(1.0, 3.0, 6.0, 14.0, 3, 10.0));
  EXPECT_EQ(line.find("MPM wait| 1          | 2          | 3          |"), 0u) << line;
  EXPECT_TRUE(std::regex_search(line, std::regex(R"(\|\s+[0-9.]+ \| 20\.00\n$)"))) << line;
  // the columns line up with the header's bars
  const std::string columns = head.substr(head.find('\n') + 1);
  for (std::size_t k = 0; k < columns.find('\n'); ++k)
    if (columns[k] == '|') EXPECT_EQ(line[k], '|') << k << ": " << line;
}

}    // namespace
