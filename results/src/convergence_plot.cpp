// A job's convergence plot (convergence_plot.h).

#include "calib/results/convergence_plot.h"

#include "calib/results/html_page.h"
#include "calib/results/optimizer_stats.h"

#include <fmt/format.h>

#include <stdexcept>

namespace calib {

std::string ConvergencePlotScript(const std::vector<EvaluationRecord>& evaluations, const std::string& title) {
  std::vector<double> scores;
  std::vector<std::vector<double>> points, line;
  int64_t failed = 0;
  for (size_t i = 0; i < evaluations.size(); ++i) {
    const EvaluationRecord& e = evaluations[i];
    scores.push_back(e.ok ? e.score : optimizer_stats::kNaN);
    if (e.ok) {
      points.push_back({static_cast<double>(i + 1), e.score});
    } else {
      ++failed;
    }
  }
  if (points.empty()) return "";
  const std::vector<double> best = optimizer_stats::BestSoFar(scores);
  for (size_t i = 0; i < best.size(); ++i) line.push_back({static_cast<double>(i + 1), best[i]});
  return fmt::format(
      "{}{}set title {}\nset xlabel 'evaluations'\nset ylabel 'score (lower is better)'\nset grid\n"
      "set key top right\n"
      "plot $points using 1:2 with points pt 7 ps 0.4 lc rgb '#999999' title 'evaluation', \\\n"
      "  $best using 1:2 with steps lw 2 lc rgb '#1f5fbf' title 'best so far'\n",
      Datablock("points", points), Datablock("best", line),
      GnuplotQuote(fmt::format("{}: {} evaluations, {} failed", title, evaluations.size(), failed)));
}

void WriteConvergencePlot(const std::filesystem::path& path, const std::vector<EvaluationRecord>& evaluations,
                          const std::string& title, const GnuplotOptions& options) {
  const std::string script = ConvergencePlotScript(evaluations, title);
  if (script.empty()) {
    throw std::runtime_error(fmt::format("{}: no convergence plot: no evaluation of '{}' finished",
                                         path.string(), title));
  }
  html::WritePage(path, RenderSvg(script, options));
}

}  // namespace calib
