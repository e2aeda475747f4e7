#pragma once
// Shared by the loop tests: the bundled synthetic pairs (examples/NAME and
// examples/NAME_offset or NAME_b), the effects their truth.json says are on
// (mapped to the catalogue's names; read only to check the loop's answer),
// and a small-budget loop run.

#include "calib/discovery/loop.h"
#include "support/test_support.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

namespace calib::testing {

inline std::filesystem::path ExamplesDir() {
  return std::filesystem::path(CALIB_SOURCE_DIR) / "examples";
}

/// The generator's effect names (docs/scenario.md) -> the catalogue's.
inline std::string CatalogueName(const std::string& generator_effect) {
  static const std::map<std::string, std::string> names = {
      {"plasticity", "plasticity"},
      {"uneven_stiffness", "uneven_stiffness"},
      {"strain_stiffening", "strain_stiffening"},
      {"viscoelastic", "viscoelastic"},
      {"strong_friction", "table_friction"},
      {"inertia_gravity", "inertia"}};
  const auto it = names.find(generator_effect);
  return it == names.end() ? "unknown:" + generator_effect : it->second;
}

/// The catalogue names of the effects truth.json of `recording` lists.
inline std::vector<std::string> TrueEffects(const std::filesystem::path& recording) {
  std::ifstream in(recording / "truth.json");
  const nlohmann::json truth = nlohmann::json::parse(in);
  std::vector<std::string> out;
  for (const auto& e : truth.at("effects")) out.push_back(CatalogueName(e.get<std::string>()));
  return out;
}

/// Loop options for a test: the budgets a user's `calib loop` runs with
/// (160 evaluations a search, three searches of the base model, 160 a
/// calibration with an effect), one effect at most, no HTML. Tests that
/// check no search result set smaller budgets.
inline LoopOptions TestLoopOptions(const std::vector<std::filesystem::path>& train,
                                   const std::vector<std::filesystem::path>& holdout,
                                   const std::string& scratch_name) {
  LoopOptions o;
  o.train = train;
  o.holdout = holdout;
  o.out_dir = ScratchDir(scratch_name);
  o.seed = 1;
  o.threads = 2;
  o.max_effects = 1;
  o.tries_per_round = 3;
  o.overlays_per_recording = 0;
  o.write_html = false;
  return o;
}

inline double HeldOutXor(const ReportStage& stage, const LoopReport& report) {
  double s = 0.0;
  for (const ReportRecording& r : report.recordings) {
    if (r.role == "holdout") s += stage.ErrorOn(r.name)->xor_sum;
  }
  return s;
}

}  // namespace calib::testing
