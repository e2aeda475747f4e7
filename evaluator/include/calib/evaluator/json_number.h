#pragma once
// A double as a JSON value: JSON has no NaN or infinity, so a value that is
// not finite (NaN: "not measured" / "not applicable" throughout the reports)
// is written as null. Every report and export writes its numbers through
// this one function; readers map null back to NaN.

#include <nlohmann/json.hpp>

#include <cmath>

namespace calib {

/// `v` as a JSON number, or null when it is NaN or infinite.
inline nlohmann::json JsonNumber(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

}  // namespace calib
