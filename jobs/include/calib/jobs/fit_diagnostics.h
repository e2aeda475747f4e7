#pragma once
// What a calibration's history says about its fit beyond the best score:
// parameters the search pushed against its box (the optimum may lie
// outside), and a score that no parameter moved (nothing drives the mesh,
// so the "fit" is only the search's starting point).

#include "calib/jobs/calibration_request.h"
#include "calib/results/store.h"

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace calib {

struct FitDiagnostics {
  /// Searched parameters whose best value lies on a bound of its box
  /// (within kBoundShare of the box's width on its search scale), in the
  /// settings' order, e.g. "k_phi = 1e+06 (upper bound)". An angle searched
  /// over a whole turn (a name ending in _deg, a box 360 wide) has no bound.
  std::vector<std::string> at_bounds;
  /// Every successful evaluation (at least two) scored the same to
  /// kFlatRelative: the score does not depend on the parameters, and the
  /// fit says nothing about them.
  bool uninformative = false;
  int64_t scored = 0;         ///< successful evaluations looked at
  double score_spread = 0.0;  ///< their largest minus smallest score

  static constexpr double kBoundShare = 1e-6;
  static constexpr double kFlatRelative = 1e-12;

  /// One line for logs and summaries; empty when there is nothing to say.
  std::string Summary() const;
};

/// A searched parameter whose value lies on a bound of its box.
struct BoundHit {
  std::string name;
  bool upper = false;  ///< on the upper bound (else the lower)
};

/// The searched parameters of `settings` whose value in `values` (which
/// holds every searched name) lies on a bound of its box, within
/// FitDiagnostics::kBoundShare of the box's width on its search scale, in
/// the settings' search order. An angle searched over a whole turn (a name
/// ending in _deg, a box 360 wide) has no bound.
std::vector<BoundHit> ValuesOnBounds(const std::vector<ParameterSetting>& settings,
                                     const ParameterValues& values);

/// Diagnoses the fit `best` of a search over `settings` from its
/// evaluations (all of them, in any order; failed ones are skipped).
FitDiagnostics DiagnoseFit(const std::vector<ParameterSetting>& settings,
                           const ParameterValues& best,
                           std::span<const EvaluationRecord> evaluations);

}  // namespace calib
