// Internal: reads an optimiser's JSON settings, each value checked once,
// every message naming the optimiser, the key, the value and the rule.
#pragma once

#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace calib::search::internal {

class SettingsReader {
 public:
  // settings: a JSON object, or null for all defaults.
  SettingsReader(std::string optimizer, const nlohmann::json& settings);

  bool Has(const std::string& key) const;
  // Integer in [min, max]; rule text names the key.
  int64_t Int(const std::string& key, int64_t def, int64_t min, int64_t max);
  // Finite number checked by [min, max] with open/closed ends.
  double Number(const std::string& key, double def, double min, bool min_open, double max,
                bool max_open);
  std::string OneOf(const std::string& key, const std::string& def,
                    const std::vector<std::string>& allowed);
  // Array of exactly n finite numbers, each in [lower[i], upper[i]].
  std::optional<std::vector<double>> PointInBox(const std::string& key,
                                                const std::vector<double>& lower,
                                                const std::vector<double>& upper);
  const nlohmann::json& Raw(const std::string& key);
  // Rejects keys never read. Call last.
  void Finish() const;

  [[noreturn]] void Fail(const std::string& key, const nlohmann::json& value,
                         const std::string& rule) const;

 private:
  std::string optimizer_;
  nlohmann::json settings_;
  std::set<std::string> read_;
};

}  // namespace calib::search::internal
