// The optimiser comparison's analysis and report count failed and pruned
// evaluations apart (a pruned one, stopped early by a job's
// budget.prune_factor, has no score either), and name each fixed budget by
// the fraction asked for.

#include "calib/results/comparison_analysis.h"
#include "calib/results/comparison_report.h"

#include "support/csv_support.h"
#include "support/process_support.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <limits>
#include <string>
#include <vector>

namespace calib {
namespace {

constexpr double kNoScore = std::numeric_limits<double>::quiet_NaN();

ComparisonRunData RunOf(const std::string& optimizer, uint64_t seed, std::vector<double> scores,
                      int64_t pruned) {
  ComparisonRunData run;
  run.optimizer = optimizer;
  run.seed = seed;
  run.job = optimizer + ".s" + std::to_string(seed);
  run.status = "finished";
  run.eval_seconds.assign(scores.size(), 0.5);
  run.scores = std::move(scores);
  run.pruned = pruned;
  return run;
}

TEST(ComparisonReport, CountsFailedAndPrunedEvaluationsApart) {
  // a: one failed and two pruned evaluations over its runs; b: one failed.
  const std::vector<ComparisonRunData> runs{
      RunOf("a", 1, {5.0, kNoScore, 4.0, kNoScore}, 1),
      RunOf("a", 2, {6.0, 3.0, kNoScore, 2.0}, 1),
      RunOf("b", 1, {7.0, kNoScore, 6.5, 6.0}, 0),
  };
  ComparisonAnalysisOptions options;
  options.budget = 4;
  const ComparisonAnalysis analysis = AnalyseComparison(runs, options);
  ASSERT_EQ(analysis.optimizers.size(), 2u);
  for (const OptimizerSummary& o : analysis.optimizers) {
    EXPECT_EQ(o.evaluations, o.optimizer == "a" ? 8 : 4) << o.optimizer;
    EXPECT_EQ(o.failed, 1) << o.optimizer;
    EXPECT_EQ(o.pruned, o.optimizer == "a" ? 2 : 0) << o.optimizer;
  }

  const auto dir = testing::ScratchDir("comparison_report_pruned");
  WriteComparisonReport(dir, "pruned", analysis);
  const testing::CsvRows rows = testing::ParseCsvFile(dir / "runs.csv");
  ASSERT_EQ(rows.size(), 4u) << "a header and 3 runs";
  const std::vector<std::string> header = rows.front();
  const auto column = [&](const std::string& name) {
    for (size_t i = 0; i < header.size(); ++i) {
      if (header[i] == name) return i;
    }
    ADD_FAILURE() << "runs.csv has no column " << name;
    return header.size();
  };
  const size_t failed = column("failed"), pruned = column("pruned");
  ASSERT_LT(failed, header.size());
  ASSERT_LT(pruned, header.size());
  const std::vector<std::pair<std::string, std::string>> expected{{"1", "1"}, {"0", "1"}, {"1", "0"}};
  for (size_t r = 0; r < expected.size(); ++r) {
    EXPECT_EQ(rows[r + 1][failed], expected[r].first) << "run " << r;
    EXPECT_EQ(rows[r + 1][pruned], expected[r].second) << "run " << r;
  }
  const std::string html = testing::ReadText(dir / "report.html");
  EXPECT_NE(html.find("<th>pruned evaluations</th>"), std::string::npos);
}

// At 4 evaluations 10 % and 25 % of the budget are both one evaluation:
// the table still names each by its fraction.
TEST(ComparisonReport, NamesEachFixedBudgetByItsFraction) {
  const std::vector<ComparisonRunData> runs{RunOf("a", 1, {5.0, 4.0, 3.0, 2.0}, 0)};
  ComparisonAnalysisOptions options;
  options.budget = 4;
  const ComparisonAnalysis analysis = AnalyseComparison(runs, options);
  const auto dir = testing::ScratchDir("comparison_report_fractions");
  WriteComparisonReport(dir, "fractions", analysis);
  const testing::CsvRows rows = testing::ParseCsvFile(dir / "fixed_budget.csv");
  const testing::CsvRows expected{{"optimizer", "fraction", "evaluations", "q25", "median", "q75"},
                                  {"a", "0.1", "1", "5", "5", "5"},
                                  {"a", "0.25", "1", "5", "5", "5"},
                                  {"a", "0.5", "2", "4", "4", "4"},
                                  {"a", "1", "4", "2", "2", "2"}};
  EXPECT_EQ(rows, expected);
  const std::string html = testing::ReadText(dir / "report.html");
  EXPECT_NE(html.find("<th>1 evaluations (10 %)"), std::string::npos);
  EXPECT_NE(html.find("<th>1 evaluations (25 %)"), std::string::npos);
}

}  // namespace
}  // namespace calib
