#pragma once
// Plots by gnuplot (Debian package gnuplot-nox), rendered to SVG text for
// embedding in HTML reports. gnuplot runs as a child process on a script
// file in a fresh temporary folder, which is removed afterwards.

#include <string>
#include <vector>

namespace calib {

struct GnuplotOptions {
  std::string executable = "gnuplot";  ///< a name on PATH or a path
  int width_px = 900;
  int height_px = 320;
  std::string font = "Helvetica,11";

  bool IsValid(std::string* error) const;
};

/// Whether `executable --version` runs; *message gets the version line, or
/// what went wrong (with the hint to install gnuplot-nox).
bool GnuplotAvailable(const std::string& executable, std::string* message);

/// Runs `script` (plot commands; the SVG terminal, its size and the output
/// file are set before it) and returns the SVG document. Throws
/// std::runtime_error with gnuplot's error output when it fails or writes
/// nothing, std::invalid_argument for invalid options. Same script, same
/// SVG (gnuplot writes no time stamps).
std::string RenderSvg(const std::string& script, const GnuplotOptions& options);

/// A gnuplot datablock `$name << EOD ... EOD` of whitespace-separated rows;
/// NaN is written as NaN (gnuplot skips it), numbers with 9 significant
/// digits. An empty row writes a blank line (a gap between data sets).
std::string Datablock(const std::string& name, const std::vector<std::vector<double>>& rows);

/// `text` quoted for a gnuplot string in double quotes (\ " and newlines
/// escaped). The terminal is noenhanced: labels show text as it is.
std::string GnuplotQuote(const std::string& text);

}  // namespace calib
