#pragma once
// The report of an optimiser comparison (docs/compare.md) in a folder:
//   report.html       the verdict, the plots (gnuplot SVG, gnuplot.h), the
//                     fixed-budget, fixed-target and pairwise tables, failures
//   runs.csv          one row per run: optimizer, seed, job, status,
//                     evaluations, failed, final_score
//   convergence.csv   optimizer, evaluations, q25, median, q75 of the best so far
//   fixed_budget.csv  optimizer, fraction, evaluations, q25, median, q75
//   fixed_target.csv  optimizer, target, target_score, ert_evaluations, success_rate
//   pairwise.csv      a, b, median_a, median_b, p_value, p_holm, a_lower,
//                     rank_biserial, significant
// Numbers are written with round-trip precision. Same analysis, same bytes.

#include "calib/results/comparison_analysis.h"
#include "calib/results/gnuplot.h"

#include <filesystem>
#include <string>

namespace calib {

struct ComparisonReportOptions {
  GnuplotOptions gnuplot;
  /// Without gnuplot: false writes the page without plots and says so;
  /// true throws std::runtime_error naming gnuplot-nox.
  bool require_plots = false;
};

struct ComparisonReportSummary {
  std::filesystem::path html;
  int plots = 0;  ///< SVG plots in the page
};

/// Writes the files above into `out_dir` (created). Throws
/// std::runtime_error naming a file that cannot be written.
ComparisonReportSummary WriteComparisonReport(const std::filesystem::path& out_dir,
                                              const std::string& title,
                                              const ComparisonAnalysis& analysis,
                                              const ComparisonReportOptions& options = {});

}  // namespace calib
