#pragma once
// What the HTML reports share (the loop's report and the loop benchmark's
// in discovery/, the optimiser comparison's here): escaping, numbers,
// the style sheet, gnuplot figures (or their absence) and writing the page.

#include "calib/results/gnuplot.h"

#include <filesystem>
#include <string>

namespace calib::html {

/// `s` with & < > " escaped.
std::string Escape(const std::string& s);

/// `v` with `decimals` decimals; an en dash when it is not finite.
std::string Num(double v, int decimals = 2);

/// The pages' style sheet (the contents of <style>).
extern const char* const kStyle;

/// The start of a page up to and including its <h1> title.
std::string PageStart(const std::string& title);

// Makes the pages' plots, or notes their absence.
class Plotter {
 public:
  /// Without gnuplot: require_plots false makes pages without plots (the
  /// caller says so); true throws std::runtime_error naming gnuplot-nox.
  Plotter(GnuplotOptions gnuplot, bool require_plots);
  bool available() const { return available_; }
  const std::string& message() const { return message_; }
  int plots() const { return plots_; }

  /// The figure for `script` (a <figure> with the SVG and a caption), or
  /// an empty string without gnuplot; a failed plot is a warning paragraph
  /// unless plots are required.
  std::string Figure(const std::string& script, const std::string& caption, int height_px = 0);

  /// The page's last lines: which gnuplot made the plots, </body></html>.
  std::string PageEnd() const;

 private:
  GnuplotOptions gnuplot_;
  bool require_plots_ = false;
  bool available_ = false;
  std::string message_;
  int plots_ = 0;
};

/// Writes `page` to `path`. Throws std::runtime_error naming the path.
void WritePage(const std::filesystem::path& path, const std::string& page);

}  // namespace calib::html
