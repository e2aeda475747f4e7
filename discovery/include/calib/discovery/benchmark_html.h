#pragma once
// benchmark.html of the loop benchmark (loop_benchmark.h): the confusion
// table of effects present against effects kept, detection rates per effect
// and magnitude with their 95 % Wilson intervals (and a plot of them against
// magnitude, by gnuplot), false discoveries, confusable pairs, the held-out
// change of kept effects, run times, sensitivities, and a row per object
// linking its report.html. The style of report.html (report_html.h).

#include "calib/discovery/benchmark_report.h"
#include "calib/discovery/report_html.h"

#include <filesystem>

namespace calib {

/// Writes `html_path`; object reports are linked as objects/<id>/report.html
/// relative to it. Throws std::runtime_error naming the path when it cannot
/// be written, or (require_plots) when gnuplot is missing or fails.
/// Deterministic: same report, same bytes.
HtmlReportSummary WriteBenchmarkHtml(const std::filesystem::path& html_path,
                                     const LoopBenchmarkReport& report,
                                     const HtmlReportOptions& options = {});

}  // namespace calib
