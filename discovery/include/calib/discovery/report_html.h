#pragma once
// report.html of the closed loop: the before / after table, the stages and
// their decisions, the hypotheses with their evidence, and per recording the
// per-frame error of the base and the final model, residual heat maps over
// the rest shape and overlay frames at the worst moments. Plots are SVG made
// by gnuplot (gnuplot.h) and embedded in the page; overlays are the PNG
// files the report names (linked, or embedded as base64).

#include "calib/results/gnuplot.h"
#include "calib/discovery/loop_report.h"

#include <filesystem>
#include <string>

namespace calib {

struct HtmlReportOptions {
  GnuplotOptions gnuplot;
  /// Without gnuplot: false writes the page without plots and says so at
  /// its top; true throws std::runtime_error naming gnuplot-nox.
  bool require_plots = false;
  /// Embed overlay PNGs as base64 data URIs (one self-contained file)
  /// instead of linking them.
  bool embed_images = false;

  bool IsValid(std::string* error) const { return gnuplot.IsValid(error); }
};

struct HtmlReportSummary {
  int plots = 0;            ///< SVG plots embedded
  int overlays = 0;         ///< overlay images shown
  bool plots_made = false;  ///< false: gnuplot was missing (see plot_message)
  std::string plot_message; ///< gnuplot's version line, or why there are no plots
};

/// Writes `html_path`; overlay PNG paths are resolved against its folder.
/// Throws std::runtime_error naming the path when it cannot be written, or
/// (require_plots) when gnuplot is missing or fails. Deterministic: same
/// report, same bytes.
HtmlReportSummary WriteLoopReportHtml(const std::filesystem::path& html_path,
                                      const LoopReport& report,
                                      const HtmlReportOptions& options = {});

/// report.json and report.html into `out_dir` (created).
HtmlReportSummary WriteLoopReport(const std::filesystem::path& out_dir, const LoopReport& report,
                                  const HtmlReportOptions& options = {});

}  // namespace calib
