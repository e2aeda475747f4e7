// report.html (report_html.h): tables in HTML, plots by gnuplot as SVG.

#include "calib/discovery/report_html.h"

#include "calib/discovery/confidence_rates.h"
#include "calib/results/html_page.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>

namespace calib {
namespace {

namespace fs = std::filesystem;
using html::Escape;
using html::Num;
using html::Plotter;

std::string Base64(const std::string& bytes) {
  static const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const uint32_t v = (static_cast<uint8_t>(bytes[i]) << 16) |
                       (static_cast<uint8_t>(bytes[i + 1]) << 8) | static_cast<uint8_t>(bytes[i + 2]);
    out += table[v >> 18];
    out += table[(v >> 12) & 63];
    out += table[(v >> 6) & 63];
    out += table[v & 63];
  }
  if (i + 1 == bytes.size()) {
    const uint32_t v = static_cast<uint8_t>(bytes[i]) << 16;
    out += table[v >> 18];
    out += table[(v >> 12) & 63];
    out += "==";
  } else if (i + 2 == bytes.size()) {
    const uint32_t v = (static_cast<uint8_t>(bytes[i]) << 16) | (static_cast<uint8_t>(bytes[i + 1]) << 8);
    out += table[v >> 18];
    out += table[(v >> 12) & 63];
    out += table[(v >> 6) & 63];
    out += '=';
  }
  return out;
}

std::string Percent(double before, double after) {
  if (!(before > 0.0)) return "&ndash;";
  return fmt::format("{:+.1f}%", 100.0 * (after - before) / before);
}

// A per-frame series (XOR or IoU) of base and final model on one recording.
std::string FramePlotScript(const ReportRecording& rec, const RecordingScore* before,
                            const RecordingScore* after,
                            std::vector<double> RecordingScore::*series, const std::string& what,
                            const std::string& ylabel, const std::string& yrange) {
  auto rows = [&](const RecordingScore* e) {
    std::vector<std::vector<double>> out;
    const double fps = rec.fps > 0 ? rec.fps : 1.0;
    const std::vector<double>& values = e->*series;
    for (size_t f = 0; f < values.size(); ++f) {
      out.push_back({static_cast<double>(f) / fps, values[f]});
    }
    return out;
  };
  std::string script;
  std::vector<std::string> plots;
  if (before != nullptr && !(before->*series).empty()) {
    script += Datablock("before", rows(before));
    plots.push_back("$before using 1:2 with lines lw 1.5 lc rgb '#c0392b' title 'before (base model)'");
  }
  if (after != nullptr && after != before && !(after->*series).empty()) {
    script += Datablock("after", rows(after));
    plots.push_back("$after using 1:2 with lines lw 1.5 lc rgb '#2471a3' title 'after (final model)'");
  }
  if (plots.empty()) return "";
  if (series == &RecordingScore::frame_iou && !rec.registered_iou.empty()) {
    std::vector<std::vector<double>> registered;
    const double fps = rec.fps > 0 ? rec.fps : 1.0;
    for (size_t f = 0; f < rec.registered_iou.size(); ++f) {
      registered.push_back({static_cast<double>(f) / fps, rec.registered_iou[f]});
    }
    script += Datablock("registered", registered);
    plots.push_back(
        "$registered using 1:2 with lines lw 1 lc rgb '#7f8c8d' title 'the mesh registered to the "
        "video'");
  }
  script += fmt::format(
      "set title {}\nset xlabel 'time (s)'\nset ylabel {}\nset grid\n"
      "set key top left\nset yrange {}\nplot {}\n",
      GnuplotQuote(rec.name + " (" + rec.role + "): " + what), GnuplotQuote(ylabel), yrange,
      fmt::join(plots, ", \\\n  "));
  return script;
}

// The tip's horizontal position over time: the video's and the base and
// final models' (objects held by clamps; the model tips of a failed
// simulation stop at its failure).
std::string TipPlotScript(const ReportRecording& rec, const RecordingScore* before,
                          const RecordingScore* after) {
  if (rec.tip_x_px.empty()) return "";
  const double fps = rec.fps > 0 ? rec.fps : 1.0;
  auto rows = [&](const std::vector<double>& x) {
    std::vector<std::vector<double>> out;
    for (size_t f = 0; f < x.size(); ++f) out.push_back({static_cast<double>(f) / fps, x[f]});
    return out;
  };
  std::string script = Datablock("video", rows(rec.tip_x_px));
  std::vector<std::string> plots{"$video using 1:2 with lines lw 2 lc rgb '#333333' title 'video'"};
  const auto add = [&](const RecordingScore* e, const char* name, const char* colour,
                       const std::string& title) {
    if (e == nullptr || e->tip_x_px.empty()) return;
    script += Datablock(name, rows(e->tip_x_px));
    plots.push_back(fmt::format("${} using 1:2 with lines lw 1.2 lc rgb '{}' title {}", name, colour,
                                GnuplotQuote(title)));
  };
  add(before, "before", "#c0392b",
      before != nullptr ? fmt::format("base model (median tip distance {:.1f} px)", before->median_tip_distance_px)
                        : "");
  if (after != before) {
    add(after, "after", "#2471a3",
        after != nullptr ? fmt::format("final model (median tip distance {:.1f} px)", after->median_tip_distance_px)
                         : "");
  }
  script += fmt::format(
      "set title {}\nset xlabel 'time (s)'\nset ylabel 'tip x (px)'\nset grid\n"
      "set key top right\nplot {}\n",
      GnuplotQuote(rec.name + " (" + rec.role + "): the tip (farthest from the clamp), across the image"),
      fmt::join(plots, ", \\\n  "));
  return script;
}

// Two heat maps (missed, extra) over the rest shape: residual pixel-frames
// per rest pixel, averaged over the analysed frames.
std::string HeatMapScript(const ReportResidual& r) {
  const RestHeatMap& h = r.analysis.heat_map;
  if (h.cols < 1 || h.rows < 1 || h.missed.size() != static_cast<size_t>(h.cols) * h.rows) {
    return "";
  }
  const double frames = std::max(1, r.analysis.frames_analysed);
  auto block = [&](const std::string& name, const std::vector<double>& v) {
    std::vector<std::vector<double>> rows;
    for (int row = 0; row < h.rows; ++row) {
      for (int col = 0; col < h.cols; ++col) {
        const size_t i = static_cast<size_t>(row) * h.cols + col;
        const double area = h.area_px[i];
        rows.push_back({h.origin_px.x() + (col + 0.5) * h.cell_px,
                        h.origin_px.y() + (row + 0.5) * h.cell_px,
                        area > 0.0 ? v[i] / area / frames : 0.0});
      }
      rows.push_back({});
    }
    return Datablock(name, rows);
  };
  const double x0 = h.origin_px.x(), y0 = h.origin_px.y();
  const double x1 = x0 + h.cols * h.cell_px, y1 = y0 + h.rows * h.cell_px;
  std::string s = block("missed", h.missed) + block("extra", h.extra);
  s += fmt::format(
      "set multiplot layout 1,2 title {}\n"
      "set size ratio -1\nset xrange [{:.3f}:{:.3f}]\nset yrange [{:.3f}:{:.3f}] reverse\n"
      "set xlabel 'rest x (px)'\nset ylabel 'rest y (px)'\nset cbrange [0:*]\n"
      "set palette defined (0 '#ffffff', 1 '#fcbba1', 2 '#fb6a4a', 3 '#99000d')\n"
      "set title 'missed: object, not mesh'\nplot $missed using 1:2:3 with image notitle\n"
      "set palette defined (0 '#ffffff', 1 '#c6dbef', 2 '#6baed6', 3 '#08306b')\n"
      "set title 'extra: mesh, not object'\nplot $extra using 1:2:3 with image notitle\n"
      "unset multiplot\n",
      GnuplotQuote(fmt::format("{} / {}: residual over the rest shape (share of frames)",
                               r.recording, r.stage)),
      x0, x1, y0, y1);
  return s;
}

// Clustered bars: XOR sum before / after per recording.
std::string SummaryBarsScript(const LoopReport& report) {
  const ReportStage* base = report.BaseStage();
  const ReportStage* fin = report.FinalStage();
  if (base == nullptr) return "";
  std::string data = "$bars << EOD\n";
  int n = 0;
  for (const ReportRecording& rec : report.recordings) {
    const RecordingScore* b = base->ErrorOn(rec.name);
    const RecordingScore* a = fin->ErrorOn(rec.name);
    if (b == nullptr || a == nullptr) continue;
    data += fmt::format("{} {:.1f} {:.1f}\n", GnuplotQuote(rec.name + " (" + rec.role + ")"),
                        b->xor_sum, a->xor_sum);
    ++n;
  }
  data += "EOD\n";
  if (n == 0) return "";
  return data +
         "set style data histogram\nset style histogram clustered gap 1\n"
         "set style fill solid 0.8 border -1\nset boxwidth 0.9\nset grid ytics\n"
         "set ylabel 'XOR pixel area summed over frames'\nset yrange [0:*]\nset key top right\n"
         "set xtics rotate by -20\n"
         "set title 'error before and after, every recording'\n"
         "plot $bars using 2:xtic(1) title 'before (base model)' lc rgb '#c0392b', "
         "'' using 3 title 'after (final model)' lc rgb '#2471a3'\n";
}

// "5 / 9 = 0.56 [0.27, 0.81]", or "none".
std::string RateOf(const ConfidenceBin* bin) {
  if (bin == nullptr || bin->right.trials == 0) return "none";
  const Proportion& p = bin->right;
  return fmt::format("{} / {} = {:.2f} [{:.2f}, {:.2f}]", p.successes, p.trials, p.rate, p.lower,
                     p.upper);
}

// How often a first-round hypothesis of this effect, and of any effect, at
// this confidence was right on the tuning family, and the estimate that
// `--rank-by rate` ranks it by.
std::string RateCell(const std::string& effect, double confidence) {
  const ConfidenceRates& rates = TuningFamilyConfidenceRates();
  const ConfidenceBin* all = rates.Find(confidence);
  if (all == nullptr) return "&ndash;";
  const double ranking = RankingRate(rates, effect, confidence);
  return fmt::format("{}: {}<br>any effect: {}<br>(at {:.2f}&ndash;{:.2f}){}", Escape(effect),
                     RateOf(rates.Find(effect, confidence)), RateOf(all), all->from, all->to,
                     std::isnan(ranking) ? std::string()
                                         : fmt::format("<br>estimate {:.2f}", ranking));
}

std::string Params(const ParameterValues& values) {
  std::string s;
  for (const auto& [name, v] : values) {
    if (!s.empty()) s += ", ";
    s += fmt::format("{} = {:.4g}", Escape(name), v);
  }
  return s;
}

// The fitted values on a bound of the search box, for the parameters cell.
std::string AtBoundsText(const std::vector<std::string>& at_bounds) {
  if (at_bounds.empty()) return "";
  std::string s = "<br>on the box's bound: ";
  for (size_t i = 0; i < at_bounds.size(); ++i) s += (i == 0 ? "" : ", ") + Escape(at_bounds[i]);
  return s;
}

// The held-out spread of a model's equally good fits, for its reason cell.
// The keep rule's test of a tried stage, e.g. "<br>p = 0.0004, significant
// over 3 hypotheses".
std::string TestText(const StageTest& t) {
  if (t.frames == 0) return "";
  return fmt::format("<br>p = {:.4f} ({} frames, {} blocks), {} over {} hypotheses", t.p_value,
                     t.frames, t.blocks, t.significant ? "significant" : "not significant",
                     t.hypotheses);
}

std::string EquallyGoodText(const EquallyGoodFits& g) {
  if (g.fits == 0) return "";
  return fmt::format(
      "<br><i>{} equally good fits (training XOR within {:.0f} px of the best): held-out XOR "
      "{:.0f} to {:.0f}</i>",
      g.fits, g.training_tolerance_px, g.holdout_xor_min, g.holdout_xor_max);
}

// The independent searches of a calibration from scratch, for its reason cell.
std::string RestartsText(const std::vector<double>& training_xor) {
  if (training_xor.size() < 2) return "";
  return fmt::format("<br><i>{} independent searches, best training XOR of each: {:.0f}</i>",
                     training_xor.size(), fmt::join(training_xor, ", "));
}

}  // namespace

HtmlReportSummary WriteLoopReportHtml(const fs::path& html_path, const LoopReport& report,
                                      const HtmlReportOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  HtmlReportSummary summary;
  Plotter plot(options.gnuplot, options.require_plots);
  summary.plots_made = plot.available();
  summary.plot_message = plot.message();

  const ReportStage* base = report.BaseStage();
  const ReportStage* fin = report.FinalStage();
  std::ostringstream h;
  h << html::PageStart(report.title);
  if (!plot.available()) {
    h << "<p class=\"warn\">This report has no plots: " << Escape(plot.message()) << ".</p>\n";
  }
  h << "<p>Command: <code>" << Escape(report.command) << "</code><br>Seed " << report.seed
    << ", run time " << Num(report.run_time_s, 1) << " s.<br>Selection rule: "
    << Escape(report.selection_rule) << "</p>\n";
  h << "<p>Effects kept: <b>"
    << (report.effects_kept.empty() ? std::string("none")
                                    : Escape(fmt::format("{}", fmt::join(report.effects_kept, ", "))))
    << "</b>. Final model: <b>" << (fin != nullptr ? Escape(fin->name) : std::string("&ndash;"))
    << "</b>.</p>\n";

  // Before / after.
  h << "<h2>Error before and after</h2>\n<table>\n<tr><th>recording</th><th>role</th>"
       "<th>XOR sum before</th><th>XOR sum after</th><th>change</th><th>mean IoU before</th>"
       "<th>mean IoU after</th></tr>\n";
  for (const ReportRecording& rec : report.recordings) {
    const RecordingScore* b = base != nullptr ? base->ErrorOn(rec.name) : nullptr;
    const RecordingScore* a = fin != nullptr ? fin->ErrorOn(rec.name) : nullptr;
    h << "<tr><td>" << Escape(rec.name) << "</td><td>" << Escape(rec.role) << "</td>";
    h << "<td class=\"n\">" << (b ? Num(b->xor_sum, 0) : "&ndash;") << "</td>";
    h << "<td class=\"n\">" << (a ? Num(a->xor_sum, 0) : "&ndash;") << "</td>";
    h << "<td class=\"n\">"
      << (a && b ? Percent(b->xor_sum, a->xor_sum)
                 : "&ndash;")
      << "</td>";
    h << "<td class=\"n\">" << (b ? Num(b->mean_iou, 4) : "&ndash;") << "</td>";
    h << "<td class=\"n\">" << (a ? Num(a->mean_iou, 4) : "&ndash;") << "</td></tr>\n";
  }
  h << "</table>\n";
  const std::string bars = SummaryBarsScript(report);
  if (!bars.empty()) {
    h << plot.Figure(bars, "XOR pixel area summed over each recording, base model and final model");
  }

  // Stages.
  h << "<h2>Models calibrated</h2>\n<table>\n<tr><th>stage</th><th>effect tried</th>"
       "<th>decision</th><th>criterion</th><th>reason</th><th>parameters</th>"
       "<th>evaluations</th><th>time (s)</th></tr>\n";
  for (const ReportStage& s : report.stages) {
    h << "<tr class=\"" << ToString(s.decision) << "\"><td>" << Escape(s.name) << "</td><td>"
      << Escape(s.effect_tried) << (s.restart > 0 ? " (calibration " + std::to_string(s.restart + 1) + ")" : "")
      << "</td><td>" << ToString(s.decision) << "</td><td>"
      << Escape(s.criterion) << " = " << Num(s.criterion_value, 4) << TestText(s.test)
      << "</td><td>" << Escape(s.reason) << EquallyGoodText(s.equally_good)
      << RestartsText(s.restart_training_xor) << "</td><td>" << Params(s.parameters)
      << (s.uninformative ? "<br><b>uninformative</b>: the score does not depend on them" : "")
      << AtBoundsText(s.at_bounds) << "</td><td class=\"n\">"
      << s.evaluations << "</td><td class=\"n\">" << Num(s.calibration_time_s, 1)
      << "</td></tr>\n";
  }
  h << "</table>\n";

  // Hypotheses.
  h << "<h2>Hypotheses</h2>\n";
  for (const HypothesisRound& round : report.rounds) {
    h << "<h3>Round " << round.round << ": traced from the residual of " << Escape(round.stage)
      << "</h3>\n<table>\n<tr><th>rank</th><th>effect</th><th>confidence</th><th>right at that "
         "confidence on the tuning family</th><th>signature</th><th>evidence</th></tr>\n";
    int rank = 1;
    for (const Hypothesis& hyp : round.hypotheses) {
      h << "<tr><td class=\"n\">" << rank++ << "</td><td>" << Escape(hyp.effect)
        << "</td><td class=\"n\">" << Num(hyp.confidence, 2) << "</td><td>"
        << RateCell(hyp.effect, hyp.confidence) << "</td><td>" << Escape(hyp.summary)
        << "</td><td><ul class=\"evidence\">";
      for (const Evidence& e : hyp.evidence) {
        h << "<li>[" << Num(e.support, 2) << "] " << Escape(e.statement) << "</li>";
      }
      h << "</ul></td></tr>\n";
    }
    h << "</table>\n";
  }
  if (!report.confusions.empty()) {
    h << "<h2>Effects that look alike</h2>\n<table>\n<tr><th>round</th><th>effect</th>"
         "<th>confused with</th><th>separated</th><th>evidence</th><th>recording that would "
         "separate them</th></tr>\n";
    for (const ReportConfusion& c : report.confusions) {
      h << "<tr><td class=\"n\">" << c.round << "</td><td>" << Escape(c.effect) << "</td><td>"
        << Escape(c.confused_with.empty() ? std::string("the base model") : c.confused_with)
        << "</td><td>" << (c.separated ? "yes" : "no") << "</td><td>" << Escape(c.evidence)
        << "</td><td>" << Escape(c.proposal) << "</td></tr>\n";
    }
    h << "</table>\n";
  }

  // Per recording.
  for (const ReportRecording& rec : report.recordings) {
    h << "<h2>" << Escape(rec.name) << " (" << Escape(rec.role) << ")</h2>\n";
    const RecordingScore* b = base != nullptr ? base->ErrorOn(rec.name) : nullptr;
    const RecordingScore* a = fin != nullptr ? fin->ErrorOn(rec.name) : nullptr;
    const std::string error_script = FramePlotScript(rec, b, a, &RecordingScore::frame_xor,
                                                     "per-frame error", "XOR (px per frame)", "[0:*]");
    if (!error_script.empty()) {
      h << plot.Figure(error_script, "XOR pixel area per frame: base model and final model");
    }
    const std::string iou_script = FramePlotScript(rec, b, a, &RecordingScore::frame_iou,
                                                   "per-frame IoU", "IoU", "[0:1]");
    if (!iou_script.empty()) {
      h << plot.Figure(iou_script,
                       rec.registered_iou.empty()
                           ? "Intersection over union per frame: base model and final model"
                           : "Intersection over union per frame: base model, final model and "
                             "the mesh registered to each frame (the most a model moving this "
                             "mesh could cover)");
    }
    const std::string tip_script = TipPlotScript(rec, b, a);
    if (!tip_script.empty()) {
      h << plot.Figure(tip_script,
                       "The tip across the image over time: the video's (its pixel farthest "
                       "from the clamp) and the models' (their node farthest from it)");
    }
    for (const ReportResidual& r : report.residuals) {
      if (r.recording != rec.name) continue;
      const std::string script = HeatMapScript(r);
      if (!script.empty()) {
        h << plot.Figure(script,
                         fmt::format("Where the residual of {} lies on the rest shape (missed "
                                     "pixels mapped to the nearest mesh boundary, extra pixels "
                                     "through the mesh's barycentric coordinates); mean XOR "
                                     "{:.0f} px/frame",
                                     r.stage, r.analysis.mean_xor_px),
                         420);
      }
      h << "<details><summary>Residual analysis of " << Escape(r.stage)
        << "</summary><pre>" << Escape(r.analysis.BriefReport()) << "</pre></details>\n";
    }
    for (const ReportOverlay& o : report.overlays) {
      if (o.recording != rec.name) continue;
      std::string src = Escape(o.png_file);
      if (options.embed_images) {
        std::ifstream in(html_path.parent_path() / o.png_file, std::ios::binary);
        if (in) {
          std::ostringstream bytes;
          bytes << in.rdbuf();
          src = "data:image/png;base64," + Base64(bytes.str());
        }
      }
      h << "<figure><img class=\"overlay\" src=\"" << src << "\" alt=\"overlay frame " << o.frame
        << "\"><figcaption>" << Escape(o.stage) << ", frame " << o.frame << ": XOR "
        << Num(o.xor_px, 1) << " px, IoU " << Num(o.iou, 4) << ". " << Escape(o.caption)
        << "</figcaption></figure>\n";
      ++summary.overlays;
    }
  }
  if (!report.notes.empty()) {
    h << "<h2>Notes</h2>\n<ul>\n";
    for (const std::string& n : report.notes) h << "<li>" << Escape(n) << "</li>\n";
    h << "</ul>\n";
  }
  h << plot.PageEnd();
  html::WritePage(html_path, h.str());
  summary.plots = plot.plots();
  return summary;
}

HtmlReportSummary WriteLoopReport(const fs::path& out_dir, const LoopReport& report,
                                  const HtmlReportOptions& options) {
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec) throw std::runtime_error(fmt::format("{}: cannot create: {}", out_dir.string(), ec.message()));
  WriteLoopReportJson(out_dir / "report.json", report);
  return WriteLoopReportHtml(out_dir / "report.html", report, options);
}

}  // namespace calib
