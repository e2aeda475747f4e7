// benchmark.html (benchmark_html.h): tables in HTML, the plot by gnuplot.

#include "calib/discovery/benchmark_html.h"

#include "calib/results/gnuplot.h"
#include "calib/results/html_page.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <sstream>

namespace calib {
namespace {

using html::Escape;
using html::Num;

std::string Label(const std::string& s) { return s.empty() ? std::string("&ndash;") : Escape(s); }

// A relative change, signed, as a percentage.
std::string Percent(double change) {
  return std::isfinite(change) ? fmt::format("{:+.1f}%", 100.0 * change) : std::string("&ndash;");
}

// A share as a percentage.
std::string Share(double share) {
  return std::isfinite(share) ? fmt::format("{:.3f}%", 100.0 * share) : std::string("&ndash;");
}

// "5 / 6 = 0.83 [0.44, 0.97]"
std::string RateCells(const Proportion& p) {
  return fmt::format(
      "<td class=\"n\">{} / {}</td><td class=\"n\">{}</td><td class=\"n\">[{}, {}]</td>",
      p.successes, p.trials, Num(p.rate), Num(p.lower), Num(p.upper));
}

constexpr const char* kRateHeader = "<th>objects</th><th>rate</th><th>95 % interval (Wilson)</th>";

std::string ConfusionTableHtml(const ConfusionTable& t) {
  std::ostringstream h;
  h << "<table>\n<tr><th>present \\ kept</th>";
  for (const std::string& c : t.columns) h << "<th>" << Escape(c) << "</th>";
  h << "<th>objects</th></tr>\n";
  for (size_t r = 0; r < t.rows.size(); ++r) {
    if (t.row_objects[r] == 0) continue;  // an effect no object has
    h << "<tr><th>" << Escape(t.rows[r]) << "</th>";
    for (size_t c = 0; c < t.columns.size(); ++c) {
      const bool right =
          t.rows[r] == t.columns[c] || (r + 1 == t.rows.size() && c + 1 == t.columns.size());
      const int64_t n = t.counts[r][c];
      const char* cls = n == 0 ? "n" : right ? "n accepted" : "n rejected";
      h << "<td class=\"" << cls << "\">" << n << "</td>";
    }
    h << "<td class=\"n\">" << t.row_objects[r] << "</td></tr>\n";
  }
  h << "</table>\n";
  return h.str();
}

// Detection rate against magnitude, one line with Wilson error bars per
// effect (points of different effects set slightly apart).
std::string DetectionPlotScript(const std::vector<DetectionRate>& detection) {
  if (detection.empty()) return "";
  std::vector<std::string> magnitudes, effects;  // distinct, in order of appearance
  const auto add = [](std::vector<std::string>& list, const std::string& s) {
    if (std::find(list.begin(), list.end(), s) == list.end()) list.push_back(s);
  };
  for (const DetectionRate& d : detection) {
    add(magnitudes, d.magnitude);
    add(effects, d.effect);
  }
  std::sort(magnitudes.begin(), magnitudes.end(), MagnitudeBefore);
  std::string script;
  std::vector<std::string> plots;
  for (size_t k = 0; k < effects.size(); ++k) {
    std::vector<std::vector<double>> rows;
    const double offset = (static_cast<double>(k) - 0.5 * (effects.size() - 1.0)) * 0.04;
    for (size_t m = 0; m < magnitudes.size(); ++m) {
      for (const DetectionRate& d : detection) {
        if (d.effect != effects[k] || d.magnitude != magnitudes[m]) continue;
        rows.push_back({m + offset, d.detected.rate, d.detected.lower, d.detected.upper});
      }
    }
    const std::string name = fmt::format("e{}", k);
    script += Datablock(name, rows);
    plots.push_back(fmt::format("${} using 1:2:3:4 with yerrorlines lw 1.5 pt 7 title {}", name,
                                GnuplotQuote(effects[k])));
  }
  std::vector<std::string> tics;
  for (size_t m = 0; m < magnitudes.size(); ++m) {
    tics.push_back(fmt::format(
        "{} {}", GnuplotQuote(magnitudes[m].empty() ? "unspecified" : magnitudes[m]), m));
  }
  script += fmt::format(
      "set title 'detection rate against magnitude (95 % Wilson intervals)'\n"
      "set xlabel 'magnitude'\nset ylabel 'objects whose effect was kept'\nset grid\n"
      "set xrange [-0.5:{}]\nset yrange [0:1.05]\nset xtics ({})\nset key outside right\nplot {}\n",
      magnitudes.size() - 0.5, fmt::join(tics, ", "), fmt::join(plots, ", \\\n  "));
  return script;
}

std::string ChangeCells(const Quartiles& q) {
  return fmt::format(
      "<td class=\"n\">{}</td><td class=\"n\">{}</td><td class=\"n\">{}</td><td "
      "class=\"n\">{}</td>",
      q.count, Percent(q.median), Percent(q.q1), Percent(q.q3));
}

std::string ObjectRow(const ObjectOutcome& o) {
  std::string kept = o.effects_kept.empty() ? std::string("nothing")
                                            : fmt::format("{}", fmt::join(o.effects_kept, ", "));
  const char* cls = !o.ok()              ? "rejected"
                    : o.FalseDiscovery() ? "rejected"
                    : o.Detected()       ? "accepted"
                                         : "";
  std::string top = o.TopHypothesis().empty() ? std::string("&ndash;")
                                              : fmt::format("{} ({})", Escape(o.TopHypothesis()),
                                                            Num(o.first_round.front().confidence));
  return fmt::format(
      "<tr class=\"{}\"><td><a "
      "href=\"objects/{}/report.html\">{}</a>{}</td><td>{}</td><td>{}</td><td>{}</td>"
      "<td>{}</td><td>{}</td><td class=\"n\">{} &rarr; {}</td><td class=\"n\">{}</td>"
      "<td class=\"n\">{} &rarr; {}</td><td class=\"n\">{}</td><td "
      "class=\"n\">{}</td><td>{}</td></tr>\n",
      cls, Escape(o.id), Escape(o.id), o.resumed ? " (read back)" : "", Escape(o.cell),
      Label(o.loop_effect), Label(o.magnitude), o.ok() ? Escape(kept) : std::string("&ndash;"), top,
      Num(o.holdout_xor_before, 0), Num(o.holdout_xor_after, 0), Percent(o.HoldoutChange()),
      Num(o.train_xor_before, 0), Num(o.train_xor_after, 0), Share(o.MaxSensitivityRelative()),
      Num(o.run_time_s, 1), o.ok() ? "ok" : Escape(o.status + ": " + o.error));
}

}  // namespace

HtmlReportSummary WriteBenchmarkHtml(const std::filesystem::path& html_path,
                                     const LoopBenchmarkReport& report,
                                     const HtmlReportOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  HtmlReportSummary summary;
  html::Plotter plot(options.gnuplot, options.require_plots);
  summary.plots_made = plot.available();
  summary.plot_message = plot.message();
  const BenchmarkAggregate& a = report.aggregate;

  std::ostringstream h;
  h << html::PageStart("loop benchmark: " + report.family_name);
  if (!plot.available()) {
    h << "<p class=\"warn\">This report has no plots: " << Escape(plot.message()) << ".</p>\n";
  }
  h << "<p>Command: <code>" << Escape(report.command) << "</code><br>Family: <code>"
    << Escape(report.family_dir) << "</code>, spec <code>" << Escape(report.family_spec)
    << "</code>, seed " << report.family_seed << ".<br>" << a.objects << " objects, " << a.failed
    << " failed (left out of every rate), " << a.not_made
    << " not made by the generator (left out), " << a.resumed
    << " read back from an earlier run. Run time " << Num(a.total_run_time_s, 1)
    << " s in all, per object median " << Num(a.run_time_s.median, 1) << " s, max "
    << Num(a.run_time_s.max, 1) << " s.</p>\n";

  h << "<h2>Effects present against effects kept</h2>\n"
       "<p>Objects by the effect they have (rows; effects no object has are left out) and the "
       "effects the loop kept (columns); an object that kept two effects counts in both "
       "columns.</p>\n"
    << ConfusionTableHtml(a.confusion);

  h << "<h2>Detection</h2>\n<p>Objects whose effect was kept, over the objects with that effect "
       "and magnitude.</p>\n<table>\n<tr><th>effect</th><th>magnitude</th>"
    << kRateHeader << "</tr>\n";
  for (const DetectionRate& d : a.detection) {
    h << "<tr><td>" << Escape(d.effect) << "</td><td>" << Label(d.magnitude) << "</td>"
      << RateCells(d.detected) << "</tr>\n";
  }
  h << "</table>\n";
  const std::string detection_plot = DetectionPlotScript(a.detection);
  if (!detection_plot.empty()) {
    h << plot.Figure(
        detection_plot,
        "Detection rate per effect against magnitude, with 95 % Wilson score intervals");
  }

  h << "<h2>False discoveries</h2>\n<p>Objects where an effect was kept that the object does "
       "not have: <b>"
    << a.false_discoveries.successes << " / " << a.false_discoveries.trials << " = "
    << Num(a.false_discoveries.rate) << "</b> [" << Num(a.false_discoveries.lower) << ", "
    << Num(a.false_discoveries.upper) << "].</p>\n<table>\n<tr><th>cell</th>" << kRateHeader
    << "</tr>\n";
  for (const CellRate& c : a.false_discoveries_per_cell) {
    h << "<tr><td>" << Escape(c.cell) << "</td>" << RateCells(c.rate) << "</tr>\n";
  }
  h << "</table>\n";

  h << "<h2>Confusable effects</h2>\n<p>Objects that kept the effect they can be mistaken for: <b>"
    << a.confusable_wrong_kept.successes << " / " << a.confusable_wrong_kept.trials << " = "
    << Num(a.confusable_wrong_kept.rate) << "</b> [" << Num(a.confusable_wrong_kept.lower) << ", "
    << Num(a.confusable_wrong_kept.upper)
    << "].</p>\n<table>\n<tr><th>cell</th><th>effect</th><th>confusable with</th>" << kRateHeader
    << "</tr>\n";
  for (const ConfusableRate& c : a.confusable) {
    h << "<tr><td>" << Escape(c.cell) << "</td><td>" << Label(c.effect) << "</td><td>"
      << Escape(c.confusable_with) << "</td>" << RateCells(c.wrong_kept) << "</tr>\n";
  }
  h << "</table>\n";

  h << "<h2>Held-out error change of kept effects</h2>\n<p>Relative change of the held-out XOR "
       "sum from the model before the effect to the model with it; magnitude \"not present\": "
       "kept on objects without that effect.</p>\n<table>\n<tr><th>effect kept</th>"
       "<th>magnitude</th><th>objects</th><th>median</th><th>lower quartile</th><th>upper "
       "quartile</th></tr>\n";
  for (const ChangeSummary& c : a.holdout_change) {
    h << "<tr><td>" << Escape(c.effect) << "</td><td>" << Label(c.magnitude) << "</td>"
      << ChangeCells(c.relative_change) << "</tr>\n";
  }
  h << "</table>\n";

  h << "<h2>Confidences as rates</h2>\n<p>The first round's hypotheses by confidence: how many "
       "named the effect the object has (on the tuning family these are the rates the loop "
       "states its confidences with; DIR/confidence_rates.json).</p>\n<table>\n"
       "<tr><th>confidence</th><th>right / hypotheses</th><th>rate</th><th>95 % interval "
       "(Wilson)</th></tr>\n";
  for (const ConfidenceBin& b : a.confidence_rates.bins) {
    h << "<tr><td>" << Num(b.from, 2) << "&ndash;" << Num(b.to, 2) << "</td>" << RateCells(b.right)
      << "</tr>\n";
  }
  h << "</table>\n<p>Per effect: right / hypotheses in each bin.</p>\n<table>\n<tr><th>effect</th>";
  for (const ConfidenceBin& b : a.confidence_rates.bins) {
    h << "<th>" << Num(b.from, 2) << "&ndash;" << Num(b.to, 2) << "</th>";
  }
  h << "</tr>\n";
  for (const EffectConfidenceBins& e : a.confidence_rates.effects) {
    h << "<tr><td>" << Escape(e.effect) << "</td>";
    for (const ConfidenceBin& b : e.bins) {
      h << "<td class=\"n\">" << b.right.successes << " / " << b.right.trials << "</td>";
    }
    h << "</tr>\n";
  }
  h << "</table>\n";

  h << "<h2>Sensitivity</h2>\n<p>Per object the larger of the base and the final model's 0.1 % "
       "nudge sensitivity relative to its held-out XOR sum: median "
    << Share(a.max_sensitivity_relative.median) << ", max " << Share(a.max_sensitivity_relative.max)
    << " over " << a.max_sensitivity_relative.count << " objects.</p>\n";

  h << "<h2>Objects</h2>\n<table>\n<tr><th>object</th><th>cell</th><th>effect</th>"
       "<th>magnitude</th><th>kept</th><th>top hypothesis (confidence)</th>"
       "<th>held-out XOR before &rarr; after</th><th>change</th><th>training XOR before "
       "&rarr; after</th><th>sensitivity</th><th>time (s)</th><th>status</th></tr>\n";
  for (const ObjectOutcome& o : report.outcomes) h << ObjectRow(o);
  h << "</table>\n" << plot.PageEnd();
  html::WritePage(html_path, h.str());
  summary.plots = plot.plots();
  return summary;
}

}  // namespace calib
