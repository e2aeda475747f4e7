#pragma once
// What a loop decided, from its report.json: the stages with their
// decisions, criterion values, parameters and errors, the hypotheses, the
// kept effects and the final model; no texts, no times (they differ between
// runs that decide the same). Two loops that decide alike give equal JSON.

#include <nlohmann/json.hpp>

namespace calib::testing {

inline nlohmann::json LoopDecisions(const nlohmann::json& report) {
  using nlohmann::json;
  json stages = json::array();
  for (const json& s : report["stages"]) {
    json errors = json::array();
    for (const json& e : s["errors"]) {
      errors.push_back({{"recording", e["recording"]},
                        {"status", e["status"]},
                        {"xor_sum", e["xor_sum"]},
                        {"mean_iou", e["mean_iou"]}});
    }
    json stage = {{"name", s["name"]},
                  {"effect_tried", s["effect_tried"]},
                  {"decision", s["decision"]},
                  {"effects", s["effects"]},
                  {"parameters", s["parameters"]},
                  {"errors", errors},
                  {"criterion_value", s["criterion_value"]},
                  {"evaluations", s["evaluations"]}};
    for (const char* optional : {"equally_good", "holdout_sensitivity_px", "restart_training_xor"}) {
      if (s.contains(optional)) stage[optional] = s[optional];
    }
    stages.push_back(std::move(stage));
  }
  json rounds = json::array();
  for (const json& r : report["rounds"]) {
    json hypotheses = json::array();
    for (const json& h : r["hypotheses"]) {
      hypotheses.push_back({{"effect", h["effect"]}, {"confidence", h["confidence"]}});
    }
    rounds.push_back({{"round", r["round"]}, {"stage", r["stage"]}, {"hypotheses", hypotheses}});
  }
  return {{"stages", stages},
          {"rounds", rounds},
          {"effects_kept", report["effects_kept"]},
          {"final_model", report["final_model"]}};
}

}  // namespace calib::testing
