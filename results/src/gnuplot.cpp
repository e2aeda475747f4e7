// Running gnuplot as a child process (gnuplot.h).

#include "calib/results/gnuplot.h"

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <unistd.h>

namespace calib {
namespace {

namespace fs = std::filesystem;

// `s` in single quotes for /bin/sh.
std::string ShellQuote(const std::string& s) {
  std::string out = "'";
  for (char c : s) {
    if (c == '\'') {
      out += "'\\''";
    } else {
      out += c;
    }
  }
  return out + "'";
}

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// A fresh folder under the system temp folder, removed by the destructor.
class TempDir {
 public:
  TempDir() {
    std::string pattern = (fs::temp_directory_path() / "calib_gnuplot_XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) {
      throw std::runtime_error(fmt::format("cannot create a temporary folder {}", pattern));
    }
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

}  // namespace

bool GnuplotOptions::IsValid(std::string* error) const {
  if (executable.empty()) {
    if (error != nullptr) *error = "GnuplotOptions::executable is empty. Violated: a program name.";
    return false;
  }
  if (!(width_px >= 100 && width_px <= 10000 && height_px >= 100 && height_px <= 10000)) {
    if (error != nullptr) {
      *error = fmt::format(
          "GnuplotOptions size = {} x {}. Violated: 100 <= width_px, height_px <= 10000.",
          width_px, height_px);
    }
    return false;
  }
  return true;
}

bool GnuplotAvailable(const std::string& executable, std::string* message) {
  TempDir dir;
  const fs::path out = dir.path() / "version.txt";
  const std::string command = fmt::format("{} --version > {} 2>&1", ShellQuote(executable),
                                          ShellQuote(out.string()));
  const int rc = std::system(command.c_str());
  std::string text = ReadFile(out);
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
  if (rc != 0 || text.rfind("gnuplot", 0) != 0) {
    if (message != nullptr) {
      *message = fmt::format(
          "gnuplot is not available ('{} --version' failed{}): install the Debian package "
          "gnuplot-nox (scripts/install-deps.sh does)",
          executable, text.empty() ? std::string() : ": " + text);
    }
    return false;
  }
  if (message != nullptr) *message = text;
  return true;
}

std::string RenderSvg(const std::string& script, const GnuplotOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  TempDir dir;
  const fs::path script_path = dir.path() / "plot.gp";
  const fs::path svg_path = dir.path() / "plot.svg";
  const fs::path err_path = dir.path() / "stderr.txt";
  {
    std::ofstream out(script_path);
    out << fmt::format("set terminal svg size {},{} fixed noenhanced font {} background rgb 'white'\n",
                       options.width_px, options.height_px, GnuplotQuote(options.font));
    out << "set output " << GnuplotQuote(svg_path.string()) << "\n";
    out << script << "\nunset output\n";
    if (!out) throw std::runtime_error(fmt::format("{}: cannot write", script_path.string()));
  }
  const std::string command =
      fmt::format("{} {} > /dev/null 2> {}", ShellQuote(options.executable),
                  ShellQuote(script_path.string()), ShellQuote(err_path.string()));
  const int rc = std::system(command.c_str());
  const std::string err = ReadFile(err_path);
  std::string svg = ReadFile(svg_path);
  if (rc != 0 || svg.find("<svg") == std::string::npos) {
    throw std::runtime_error(fmt::format("gnuplot ({}) failed with status {}: {}",
                                         options.executable, rc,
                                         err.empty() ? std::string("no output") : err));
  }
  return svg;
}

std::string Datablock(const std::string& name, const std::vector<std::vector<double>>& rows) {
  std::string out = "$" + name + " << EOD\n";
  for (const auto& row : rows) {
    for (size_t i = 0; i < row.size(); ++i) {
      if (i > 0) out += ' ';
      out += std::isfinite(row[i]) ? fmt::format("{:.9g}", row[i]) : std::string("NaN");
    }
    out += '\n';
  }
  return out + "EOD\n";
}

std::string GnuplotQuote(const std::string& text) {
  std::string out = "\"";
  for (char c : text) {
    switch (c) {
      case '\\': out += "\\\\"; break;
      case '"': out += "\\\""; break;
      case '\n': out += "\\n"; break;
      default: out += c;
    }
  }
  return out + "\"";
}

}  // namespace calib
