#include "calib/jobs/fit_diagnostics.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string_view>

namespace calib {
namespace {

// An angle searched over a whole turn (a name in degrees, a box 360 wide)
// has no bound: its ends are the same direction.
bool IsWholeTurn(const ParameterSetting& s) {
  constexpr std::string_view kDegrees = "_deg";
  const bool degrees = s.name.size() >= kDegrees.size() &&
                       s.name.compare(s.name.size() - kDegrees.size(), kDegrees.size(), kDegrees) == 0;
  return degrees && s.upper - s.lower >= 360.0;
}

}  // namespace

std::string FitDiagnostics::Summary() const {
  std::string out;
  if (uninformative) {
    out = fmt::format(
        "uninformative: all {} successful evaluations scored the same (the score does not depend "
        "on the parameters: nothing moves the mesh), so the fit says nothing about them",
        scored);
  }
  if (!at_bounds.empty()) {
    std::string list;
    for (const std::string& b : at_bounds) list += (list.empty() ? "" : ", ") + b;
    out += fmt::format("{}on the search box's bound: {}", out.empty() ? "" : "; ", list);
  }
  return out;
}

std::vector<BoundHit> ValuesOnBounds(const std::vector<ParameterSetting>& settings,
                                     const ParameterValues& values) {
  std::vector<BoundHit> hits;
  const SearchSpace space(settings);
  const std::vector<std::string> names = space.names();
  const std::vector<double> unit = space.ToUnit(values);
  for (size_t k = 0; k < names.size(); ++k) {
    const auto setting = std::find_if(settings.begin(), settings.end(),
                                      [&](const ParameterSetting& s) { return s.name == names[k]; });
    if (setting != settings.end() && IsWholeTurn(*setting)) continue;
    if (unit[k] <= FitDiagnostics::kBoundShare) {
      hits.push_back({names[k], false});
    } else if (unit[k] >= 1.0 - FitDiagnostics::kBoundShare) {
      hits.push_back({names[k], true});
    }
  }
  return hits;
}

FitDiagnostics DiagnoseFit(const std::vector<ParameterSetting>& settings,
                           const ParameterValues& best,
                           std::span<const EvaluationRecord> evaluations) {
  FitDiagnostics d;
  if (!best.empty()) {
    for (const BoundHit& hit : ValuesOnBounds(settings, best)) {
      d.at_bounds.push_back(fmt::format("{} = {:g} ({} bound)", hit.name, best.at(hit.name),
                                        hit.upper ? "upper" : "lower"));
    }
  }
  double lowest = std::numeric_limits<double>::infinity();
  double highest = -lowest;
  for (const EvaluationRecord& e : evaluations) {
    if (!e.ok || !std::isfinite(e.score)) continue;
    ++d.scored;
    lowest = std::min(lowest, e.score);
    highest = std::max(highest, e.score);
  }
  if (d.scored > 0) d.score_spread = highest - lowest;
  d.uninformative =
      d.scored >= 2 && d.score_spread <= FitDiagnostics::kFlatRelative * std::max(1.0, std::abs(lowest));
  return d;
}

}  // namespace calib
