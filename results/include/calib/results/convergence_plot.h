#pragma once
// A job's convergence plot: every finished evaluation's score (points) and
// the best score so far (a line) against evaluations, as an SVG made by
// gnuplot (gnuplot.h). `calib results JOB --plot F` writes it, and so does
// every job's report (convergence.svg).

#include "calib/results/gnuplot.h"
#include "calib/results/store.h"

#include <filesystem>
#include <string>
#include <vector>

namespace calib {

/// The gnuplot script of the plot of `evaluations` (a job's, in id order;
/// failed ones count as evaluations but have no point; the title says how
/// many failed). Empty when no evaluation finished.
std::string ConvergencePlotScript(const std::vector<EvaluationRecord>& evaluations, const std::string& title);

/// Renders the plot to `path` (SVG). Throws std::runtime_error when no
/// evaluation finished, gnuplot fails or the file cannot be written.
void WriteConvergencePlot(const std::filesystem::path& path, const std::vector<EvaluationRecord>& evaluations,
                          const std::string& title, const GnuplotOptions& options = {});

}  // namespace calib
