#include "settings.h"

#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

namespace calib::search::internal {

SettingsReader::SettingsReader(std::string optimizer, const nlohmann::json& settings)
    : optimizer_(std::move(optimizer)),
      settings_(settings.is_null() ? nlohmann::json::object() : settings) {
  if (!settings_.is_object()) {
    throw std::invalid_argument(fmt::format(
        "optimiser '{}': settings = {} are invalid. Violated: settings are a JSON object",
        optimizer_, settings.dump()));
  }
}

bool SettingsReader::Has(const std::string& key) const {
  return settings_.contains(key) && !settings_.at(key).is_null();
}

void SettingsReader::Fail(const std::string& key, const nlohmann::json& value,
                          const std::string& rule) const {
  throw std::invalid_argument(fmt::format("optimiser '{}': setting '{}' = {} is invalid. Violated: {}",
                                          optimizer_, key, value.dump(), rule));
}

const nlohmann::json& SettingsReader::Raw(const std::string& key) {
  read_.insert(key);
  return settings_.at(key);
}

int64_t SettingsReader::Int(const std::string& key, int64_t def, int64_t min, int64_t max) {
  read_.insert(key);
  if (!Has(key)) return def;
  const nlohmann::json& v = settings_.at(key);
  std::string rule = max == INT64_MAX   ? fmt::format("{} >= {}", key, min)
                     : max >= 1000000 ? fmt::format("{} >= {} (and <= {})", key, min, max)
                                      : fmt::format("{} <= {} <= {}", min, key, max);
  if (!v.is_number_integer()) Fail(key, v, key + " is an integer");
  if (v.is_number_unsigned() && v.get<uint64_t>() > static_cast<uint64_t>(INT64_MAX)) {
    Fail(key, v, rule);
  }
  const int64_t i = v.get<int64_t>();
  if (i < min || i > max) Fail(key, v, rule);
  return i;
}

double SettingsReader::Number(const std::string& key, double def, double min, bool min_open,
                              double max, bool max_open) {
  read_.insert(key);
  if (!Has(key)) return def;
  const nlohmann::json& v = settings_.at(key);
  if (!v.is_number()) Fail(key, v, key + " is a number");
  const double d = v.get<double>();
  std::string rule;
  if (std::isinf(max)) {
    rule = fmt::format("{} {} {}", key, min_open ? ">" : ">=", min);
  } else if (std::isinf(min)) {
    rule = fmt::format("{} {} {}", key, max_open ? "<" : "<=", max);
  } else {
    rule = fmt::format("{} {} {} {} {}", min, min_open ? "<" : "<=", key, max_open ? "<" : "<=",
                       max);
  }
  if (!std::isfinite(d)) Fail(key, v, key + " is finite");
  if (d < min || (min_open && d == min) || d > max || (max_open && d == max)) Fail(key, v, rule);
  return d;
}

std::string SettingsReader::OneOf(const std::string& key, const std::string& def,
                                  const std::vector<std::string>& allowed) {
  read_.insert(key);
  if (!Has(key)) return def;
  const nlohmann::json& v = settings_.at(key);
  const std::string rule = fmt::format("{} is one of {}", key, fmt::join(allowed, ", "));
  if (!v.is_string()) Fail(key, v, rule);
  const std::string s = v.get<std::string>();
  for (const auto& a : allowed) {
    if (a == s) return s;
  }
  Fail(key, v, rule);
}

std::optional<std::vector<double>> SettingsReader::PointInBox(const std::string& key,
                                                              const std::vector<double>& lower,
                                                              const std::vector<double>& upper) {
  read_.insert(key);
  if (!Has(key)) return std::nullopt;
  const nlohmann::json& v = settings_.at(key);
  const size_t n = lower.size();
  if (!v.is_array() || v.size() != n) {
    Fail(key, v, fmt::format("{} is an array of {} numbers (one per parameter)", key, n));
  }
  std::vector<double> x(n);
  for (size_t i = 0; i < n; ++i) {
    if (!v[i].is_number()) Fail(key, v, fmt::format("{}[{}] is a number", key, i));
    x[i] = v[i].get<double>();
    if (!(x[i] >= lower[i] && x[i] <= upper[i])) {
      Fail(key, v, fmt::format("{} <= {}[{}] <= {}", lower[i], key, i, upper[i]));
    }
  }
  return x;
}

void SettingsReader::Finish() const {
  std::vector<std::string> known(read_.begin(), read_.end());
  for (const auto& [key, value] : settings_.items()) {
    if (!read_.count(key)) {
      throw std::invalid_argument(fmt::format(
          "optimiser '{}': setting '{}' = {} is invalid. Violated: '{}' is unknown; known "
          "settings are {}",
          optimizer_, key, value.dump(), key, fmt::join(known, ", ")));
    }
  }
}

}  // namespace calib::search::internal
