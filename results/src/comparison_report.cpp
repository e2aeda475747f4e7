// The report of an optimiser comparison (comparison_report.h).

#include "calib/results/comparison_report.h"

#include "calib/results/csv_writer.h"
#include "calib/results/html_page.h"
#include "calib/results/optimizer_stats.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace calib {
namespace {

using html::Escape;

// Round-trip text of a number; "inf" and "nan" as such.
std::string Text(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  return fmt::format("{}", v);
}

void WriteCsv(const std::filesystem::path& path, const std::vector<std::vector<std::string>>& rows) {
  csv_writer::File file = csv_writer::Open(path);
  if (!file) throw std::runtime_error(fmt::format("{}: cannot open for writing", path.string()));
  for (const auto& row : rows) csv_writer::WriteRecord(file.get(), row);
  if (!csv_writer::Close(std::move(file))) {
    throw std::runtime_error(fmt::format("{}: write failed", path.string()));
  }
}

void WriteCsvFiles(const std::filesystem::path& dir, const ComparisonAnalysis& a) {
  std::vector<std::vector<std::string>> runs{
      {"optimizer", "seed", "job", "status", "evaluations", "failed", "pruned", "final_score"}};
  for (const ComparisonRunData& r : a.runs) {
    const std::vector<double> best = optimizer_stats::BestSoFar(r.scores);
    int64_t failed = -r.pruned;
    for (double s : r.scores) failed += std::isnan(s) ? 1 : 0;
    runs.push_back({r.optimizer, std::to_string(r.seed), r.job, r.status, std::to_string(r.scores.size()),
                    std::to_string(failed), std::to_string(r.pruned),
                    Text(best.empty() ? optimizer_stats::kNaN : best.back())});
  }
  WriteCsv(dir / "runs.csv", runs);

  std::vector<std::vector<std::string>> convergence{{"optimizer", "evaluations", "q25", "median", "q75"}};
  std::vector<std::vector<std::string>> budget{{"optimizer", "fraction", "evaluations", "q25", "median", "q75"}};
  std::vector<std::vector<std::string>> target{
      {"optimizer", "target", "target_score", "ert_evaluations", "success_rate"}};
  for (const OptimizerSummary& o : a.optimizers) {
    for (const Band& b : o.by_evaluations) {
      convergence.push_back({o.optimizer, Text(b.x), Text(b.q25), Text(b.median), Text(b.q75)});
    }
    for (size_t i = 0; i < o.fixed_budget.size(); ++i) {
      const Band& b = o.fixed_budget[i];
      budget.push_back({o.optimizer, Text(a.budget_fractions[i]), Text(b.x), Text(b.q25),
                        Text(b.median), Text(b.q75)});
    }
    for (size_t t = 0; t < a.target_scores.size(); ++t) {
      target.push_back({o.optimizer, Text(a.target_values[t]), Text(a.target_scores[t]), Text(o.ert[t]),
                        Text(o.success_rate[t])});
    }
  }
  WriteCsv(dir / "convergence.csv", convergence);
  WriteCsv(dir / "fixed_budget.csv", budget);
  WriteCsv(dir / "fixed_target.csv", target);

  std::vector<std::vector<std::string>> pairs{{"a", "b", "median_a", "median_b", "p_value", "p_holm",
                                               "a_lower", "rank_biserial", "significant"}};
  for (const PairwiseTest& p : a.pairs) {
    pairs.push_back({p.a, p.b, Text(p.median_a), Text(p.median_b), Text(p.p_value), Text(p.p_holm),
                     Text(p.a_lower), Text(p.rank_biserial), p.significant ? "true" : "false"});
  }
  WriteCsv(dir / "pairwise.csv", pairs);
}

// A plot of one band per optimiser: the interquartile range shaded, the
// median as a line.
std::string BandPlotScript(const ComparisonAnalysis& a, const std::vector<Band> OptimizerSummary::*bands,
                           const std::string& title, const std::string& xlabel, const std::string& ylabel,
                           bool log_x, double y_max = optimizer_stats::kNaN) {
  std::string data;
  std::vector<std::string> plots;
  for (size_t i = 0; i < a.optimizers.size(); ++i) {
    std::vector<std::vector<double>> rows;
    for (const Band& b : a.optimizers[i].*bands) rows.push_back({b.x, b.q25, b.median, b.q75});
    if (rows.empty()) continue;
    const std::string name = fmt::format("o{}", i);
    data += Datablock(name, rows);
    const int colour = static_cast<int>(i) + 1;
    plots.push_back(fmt::format("${} using 1:2:4 with filledcurves fs transparent solid 0.15 noborder lc {} notitle",
                                name, colour));
    plots.push_back(fmt::format("${} using 1:3 with lines lw 2 lc {} title {}", name, colour,
                                GnuplotQuote(a.optimizers[i].optimizer)));
  }
  if (plots.empty()) return "";
  const std::string y_range = std::isfinite(y_max) ? fmt::format("set yrange [*:{:.9g}]\n", y_max) : "";
  return fmt::format("{}set title {}\nset xlabel {}\nset ylabel {}\nset grid\n{}{}set key outside right\nplot {}\n",
                     data, GnuplotQuote(title), GnuplotQuote(xlabel), GnuplotQuote(ylabel),
                     log_x ? "set logscale x\n" : "", y_range, fmt::join(plots, ", \\\n  "));
}

// The first evaluations' scores dwarf the later ones: the convergence plots
// show scores up to the worst upper quartile at the first budget fraction.
double ConvergenceYMax(const ComparisonAnalysis& a) {
  double y = optimizer_stats::kNaN;
  for (const OptimizerSummary& o : a.optimizers) {
    if (!o.fixed_budget.empty() && std::isfinite(o.fixed_budget.front().q75)) {
      y = std::isnan(y) ? o.fixed_budget.front().q75 : std::max(y, o.fixed_budget.front().q75);
    }
  }
  return y;
}

// The figure, or nothing for a plot without data.
std::string Figure(html::Plotter& plot, const std::string& script, const std::string& caption) {
  return script.empty() ? std::string() : plot.Figure(script, caption);
}

std::string Cell(double v, const char* format = "{:.6g}") {
  if (std::isinf(v)) return "<td class=\"n\">&infin;</td>";
  if (std::isnan(v)) return "<td class=\"n\">&ndash;</td>";
  return fmt::format("<td class=\"n\">{}</td>", fmt::format(fmt::runtime(format), v));
}

std::string Page(const std::string& title, const ComparisonAnalysis& a, html::Plotter& plot) {
  std::ostringstream h;
  h << html::PageStart(title);
  if (!plot.available()) {
    h << "<p class=\"warn\">This report has no plots: " << Escape(plot.message()) << ".</p>\n";
  }
  h << "<h2>Verdict</h2>\n<p>" << Escape(a.verdict) << "</p>\n";
  h << "<p>Budget " << a.budget << " evaluations per run; best score of any run "
    << Escape(Text(a.best_score)) << ". Lower scores are better.</p>\n";

  h << "<h2>Runs and failures</h2>\n<table>\n<tr><th>optimizer</th><th>runs</th><th>evaluations</th>"
       "<th>failed evaluations</th><th>pruned evaluations</th><th>median final</th><th>best final</th>"
       "<th>worst final</th></tr>\n";
  for (const OptimizerSummary& o : a.optimizers) {
    h << "<tr><td>" << Escape(o.optimizer) << "</td><td class=\"n\">" << o.runs << "</td><td class=\"n\">"
      << o.evaluations << "</td><td class=\"n\">" << o.failed << "</td><td class=\"n\">" << o.pruned << "</td>"
      << Cell(optimizer_stats::Quantile(o.final_scores, 0.5)) << Cell(optimizer_stats::Quantile(o.final_scores, 0.0))
      << Cell(optimizer_stats::Quantile(o.final_scores, 1.0)) << "</tr>\n";
  }
  h << "</table>\n<p>A failed evaluation (a simulation that failed) and a pruned one (stopped "
       "early by a job's <code>budget.prune_factor</code>) have no score: the curves and statistics "
       "pass over them, and they count against the budget.</p>\n";

  h << "<h2>Convergence</h2>\n";
  h << Figure(plot, BandPlotScript(a, &OptimizerSummary::by_evaluations, "best so far against evaluations",
                                  "evaluations", "best score so far", false, ConvergenceYMax(a)),
                   "median (line) and interquartile range (band) over each optimiser's runs; the score axis "
                   "stops at the worst upper quartile after the first tenth of the budget");
  h << Figure(plot, BandPlotScript(a, &OptimizerSummary::by_seconds, "best so far against evaluation time",
                                  "evaluation seconds (sum over the run's evaluations)", "best score so far",
                                  false, ConvergenceYMax(a)),
                   "median and interquartile range; time is the run's summed evaluation wall time");

  h << "<h2>Fixed budget</h2>\n<table>\n<tr><th>optimizer</th>";
  if (!a.optimizers.empty()) {
    const std::vector<Band>& at = a.optimizers.front().fixed_budget;
    for (size_t i = 0; i < at.size(); ++i) {
      h << "<th>" << at[i].x << " evaluations (" << Escape(Text(100.0 * a.budget_fractions[i]))
        << " %): median [q25, q75]</th>";
    }
  }
  h << "</tr>\n";
  for (const OptimizerSummary& o : a.optimizers) {
    h << "<tr><td>" << Escape(o.optimizer) << "</td>";
    for (const Band& b : o.fixed_budget) {
      h << "<td class=\"n\">" << fmt::format("{:.6g} [{:.6g}, {:.6g}]", b.median, b.q25, b.q75) << "</td>";
    }
    h << "</tr>\n";
  }
  h << "</table>\n";

  h << "<h2>Fixed target</h2>\n<p>Expected running time (ERT, evaluations: all evaluations of all runs, "
       "up to the hit for those that reached the target, over the number that did) and success rate per "
       "target score.</p>\n<table>\n<tr><th>optimizer</th>";
  for (size_t t = 0; t < a.target_scores.size(); ++t) {
    h << "<th>" << Escape(a.relative_targets ? fmt::format("best + {:g}", a.target_values[t])
                                             : fmt::format("{:g}", a.target_values[t]))
      << " (" << Escape(Text(a.target_scores[t])) << "): ERT, success</th>";
  }
  h << "</tr>\n";
  for (const OptimizerSummary& o : a.optimizers) {
    h << "<tr><td>" << Escape(o.optimizer) << "</td>";
    for (size_t t = 0; t < o.ert.size(); ++t) {
      h << "<td class=\"n\">" << (std::isinf(o.ert[t]) ? std::string("&infin;") : fmt::format("{:.1f}", o.ert[t]))
        << ", " << fmt::format("{:.0f} %", 100.0 * o.success_rate[t]) << "</td>";
    }
    h << "</tr>\n";
  }
  h << "</table>\n";
  h << Figure(plot, BandPlotScript(a, &OptimizerSummary::ecdf, "runtime ECDF over all targets (as in COCO)",
                                  "evaluations", "fraction of (run, target) pairs reached", true),
                   "the fraction of (run, target) pairs whose target was reached within each budget");

  h << "<h2>Pairwise tests of the final scores</h2>\n<p>Two-sided Mann-Whitney U tests (normal "
       "approximation, tie and continuity corrections), Holm-adjusted over all "
    << a.pairs.size() << " pairs; significant at " << a.alpha
    << ". P(A lower) is the chance that a run of A ends with a lower score than a run of B (ties count "
       "half; 1 - Vargha-Delaney A).</p>\n<table>\n<tr><th>A</th><th>B</th><th>median A</th>"
       "<th>median B</th><th>p</th><th>p (Holm)</th><th>P(A lower)</th><th>rank-biserial</th>"
       "<th>different</th></tr>\n";
  for (const PairwiseTest& p : a.pairs) {
    h << "<tr><td>" << Escape(p.a) << "</td><td>" << Escape(p.b) << "</td>" << Cell(p.median_a)
      << Cell(p.median_b) << Cell(p.p_value, "{:.3g}") << Cell(p.p_holm, "{:.3g}") << Cell(p.a_lower, "{:.2f}")
      << Cell(p.rank_biserial, "{:.2f}") << "<td>" << (p.significant ? "yes" : "no") << "</td></tr>\n";
  }
  h << "</table>\n";
  h << plot.PageEnd();
  return h.str();
}

}  // namespace

ComparisonReportSummary WriteComparisonReport(const std::filesystem::path& out_dir, const std::string& title,
                                              const ComparisonAnalysis& analysis,
                                              const ComparisonReportOptions& options) {
  std::filesystem::create_directories(out_dir);
  WriteCsvFiles(out_dir, analysis);
  html::Plotter plot(options.gnuplot, options.require_plots);
  ComparisonReportSummary summary;
  summary.html = out_dir / "report.html";
  html::WritePage(summary.html, Page(title, analysis, plot));
  summary.plots = plot.plots();
  return summary;
}

}  // namespace calib
