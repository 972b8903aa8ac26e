// The rezone log (keyword rezone_log): the full log's lines as the tests and tools parse them,
// and the summary that adds up the rezones between two thermo outputs.
#include <gtest/gtest.h>

#include <regex>

#include "coupler/rezone_log.hpp"

namespace {

coupler::RezoneReport report(std::int64_t step, std::int64_t deleted, std::int64_t made, double lightest,
                             double heaviest) {
  coupler::RezoneReport r;
  r.step = step;
  r.grains_deleted = deleted;
  r.points_made = 4 * deleted;
  r.hybrid_grains = 48 + step;
  r.weight = 0.5;
  r.grains_made = made;
  r.moved_cells = 20;
  r.continuum_cells = 196, r.hybrid_cells = 128 + step, r.discrete_cells = 1276;
  r.rests_moved = 1;
  r.rests_kept = 2;
  r.lightest = lightest, r.heaviest = heaviest;
  r.mean_carried = 1.0 + 0.001 * static_cast<double>(step);
  return r;
}

TEST(RezoneLog, ParsesItsThreeValuesOnly) {
  EXPECT_EQ(coupler::parse_rezone_log("full"), coupler::RezoneLog::kFull);
  EXPECT_EQ(coupler::parse_rezone_log("summary"), coupler::RezoneLog::kSummary);
  EXPECT_EQ(coupler::parse_rezone_log("quiet"), coupler::RezoneLog::kQuiet);
  EXPECT_FALSE(coupler::parse_rezone_log("yes"));
  EXPECT_FALSE(coupler::parse_rezone_log("Full"));
  EXPECT_FALSE(coupler::parse_rezone_log(""));
  for (auto level : {coupler::RezoneLog::kFull, coupler::RezoneLog::kSummary, coupler::RezoneLog::kQuiet})
    EXPECT_EQ(coupler::parse_rezone_log(coupler::rezone_log_name(level)), level);
}

TEST(RezoneLog, FullLineIsTheDocumentedOne) {
  // docs/fix_hybrid_mpm.md, "Adaptive zones": the line the tests' regexes read
  EXPECT_EQ(coupler::rezone_line(report(41, 61, 0, 1.0, 1.0)),
            "fix hybrid/mpm: step 41: 61 grains became 244 material points, 89 grains are hybrid (weight 0.5), 0 "
            "grains made from points; 20 cells moved; grid cells in the box: 196 continuum, 169 hybrid, 1276 "
            "discrete; 1 cells gave their rest of material to nearby points, 2 kept it; carried mass / solid mass 1 "
            "to 1 (mean 1.041)");
  auto r = report(1, 0, 0, 0.8412345, 2.0);
  r.weight = 0.3;
  const std::string line = coupler::rezone_line(r);
  EXPECT_NE(line.find("(weight 0.3)"), std::string::npos) << line;
  EXPECT_NE(line.find("solid mass 0.841 to 2"), std::string::npos) << line;
}

TEST(RezoneLog, TotalsLineKeepsEveryDigit) {
  const double before[7] = {0.1, 1e-20, -3, 0, 1.0 / 3.0, 5, 6}, after[7] = {0.1, 2e-20, -3, 0, 1.0 / 3.0, 5, 7};
  const std::string line = coupler::rezone_totals_line(7, before, after);
  EXPECT_EQ(line.rfind("fix hybrid/mpm: step 7: totals before/after the rezone: 0.10000000000000001 0.10000000000000001 "
                       "9.9999999999999995e-21 1.9999999999999999e-20 -3 -3 0 0 0.33333333333333331",
                       0),
            0u)
      << line;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(line, m, std::regex(R"(totals before/after the rezone:((?: \S+){14})$)")));
}

TEST(RezoneLog, SummaryAddsTheCountsAndKeepsTheLastZonesAndTheExtremes) {
  coupler::RezoneTally tally(2);
  EXPECT_EQ(tally.rezones(), 0);
  tally.add(report(21, 10, 3, 0.9, 1.1));
  tally.add(report(41, 5, 0, 1.0, 1.7));
  tally.add(report(61, 0, 7, 0.95, 1.0));
  EXPECT_EQ(tally.rezones(), 3);
  EXPECT_EQ(tally.sum().grains_deleted, 15);
  EXPECT_EQ(tally.sum().points_made, 60);
  EXPECT_EQ(tally.sum().grains_made, 10);
  EXPECT_EQ(tally.sum().moved_cells, 60);
  EXPECT_EQ(tally.sum().rests_moved, 3);
  EXPECT_EQ(tally.sum().rests_kept, 6);
  EXPECT_EQ(tally.sum().hybrid_grains, 48 + 61);    // the last rezone's
  EXPECT_EQ(tally.sum().hybrid_cells, 128 + 61);
  EXPECT_DOUBLE_EQ(tally.sum().lightest, 0.9);
  EXPECT_DOUBLE_EQ(tally.sum().heaviest, 1.7);
  EXPECT_EQ(tally.summary_line(coupler::kSummaryInterval, 100),
            "fix hybrid/mpm: steps 2-100: 3 rezones: 15 grains became 60 material points, 10 grains made from "
            "points, 60 cells moved; 3 cells gave their rest of material to nearby points, 6 kept it; now 109 hybrid "
            "grains, zones 196 continuum, 189 hybrid, 1276 discrete cells; carried mass / solid mass 0.9 to 1.7 (mean "
            "1.061)");    // the mean of the last rezone, as its zones
  // the summary does not read as a rezone line to the full log's parsers
  EXPECT_EQ(tally.summary_line(coupler::kSummaryInterval, 100).find("grains are hybrid"), std::string::npos);
  EXPECT_EQ(tally.summary_line(coupler::kSummaryInterval, 100).find("grid cells in the box"), std::string::npos);

  tally.restart(101);
  EXPECT_EQ(tally.rezones(), 0);
  EXPECT_EQ(tally.first_step(), 101);
  tally.add(report(121, 1, 0, 1.2, 1.3));    // the extremes start from the first rezone, not from 1
  EXPECT_DOUBLE_EQ(tally.sum().lightest, 1.2);
  EXPECT_EQ(tally.summary_line(coupler::kSummaryRun, 200).rfind("fix hybrid/mpm: run of steps 101-200: 1 rezone: 1 "
                                                                "grains became 4 material points",
                                                                0),
            0u);
}

}    // namespace
