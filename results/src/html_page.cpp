// What the HTML reports share (html_page.h).

#include "calib/results/html_page.h"

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <stdexcept>
#include <utility>

namespace calib::html {
namespace {

// The SVG document without its XML prologue, for inline use.
std::string InlineSvg(const std::string& svg) {
  const size_t at = svg.find("<svg");
  return at == std::string::npos ? svg : svg.substr(at);
}

}  // namespace

std::string Escape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string Num(double v, int decimals) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, decimals) : std::string("&ndash;");
}

const char* const kStyle = R"(
body { font-family: sans-serif; margin: 2em; max-width: 1200px; color: #222; }
table { border-collapse: collapse; margin: 1em 0; }
th, td { border: 1px solid #bbb; padding: 0.3em 0.6em; text-align: left; vertical-align: top; }
th { background: #eee; }
td.n { text-align: right; font-variant-numeric: tabular-nums; }
.accepted { background: #e8f6e8; } .rejected { background: #fbeaea; } .base { background: #f4f4f4; }
.warn { background: #fff3cd; border: 1px solid #e0c060; padding: 0.6em; }
figure { margin: 1em 0; } figcaption { font-size: 0.9em; color: #555; }
img.overlay { max-width: 100%; border: 1px solid #999; }
ul.evidence { margin: 0.2em 0; padding-left: 1.2em; font-size: 0.9em; }
)";

std::string PageStart(const std::string& title) {
  return fmt::format(
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{0}</title>\n"
      "<style>{1}</style>\n</head>\n<body>\n<h1>{0}</h1>\n",
      Escape(title), kStyle);
}

Plotter::Plotter(GnuplotOptions gnuplot, bool require_plots)
    : gnuplot_(std::move(gnuplot)), require_plots_(require_plots) {
  available_ = GnuplotAvailable(gnuplot_.executable, &message_);
  if (!available_ && require_plots_) throw std::runtime_error(message_);
}

std::string Plotter::Figure(const std::string& script, const std::string& caption, int height_px) {
  if (!available_) return "";
  GnuplotOptions g = gnuplot_;
  if (height_px > 0) g.height_px = height_px;
  std::string svg;
  try {
    svg = RenderSvg(script, g);
  } catch (const std::runtime_error&) {
    if (require_plots_) throw;
    return fmt::format("<p class=\"warn\">Plot failed: {}</p>\n", Escape(caption));
  }
  ++plots_;
  return fmt::format("<figure class=\"plot\">{}<figcaption>{}</figcaption></figure>\n",
                     InlineSvg(svg), Escape(caption));
}

std::string Plotter::PageEnd() const {
  return fmt::format("<p style=\"font-size:0.8em;color:#777\">Plots: {}.</p>\n</body>\n</html>\n",
                     available_ ? Escape(message_) : std::string("none"));
}

void WritePage(const std::filesystem::path& path, const std::string& page) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(fmt::format("{}: cannot open for writing", path.string()));
  out << page;
  if (!out) throw std::runtime_error(fmt::format("{}: write failed", path.string()));
}

}  // namespace calib::html
