// The calibration request's search space (calibration_request.h), the job
// spec's small types and canonical JSON (job_spec.h); reading and
// validating a spec is in job_spec_parse.cpp.

#include "calib/jobs/job_spec.h"

#include "calib/core/effects.h"
#include "calib/core/enum_names.h"
#include "calib/search/factory.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace calib {

// ------------------------------------------------------------ small types

std::vector<ParameterSpec> ModelCatalog::ParameterSpecsFor(
    const std::vector<std::string>& effect_names) const {
  std::vector<ParameterSpec> specs = base;
  for (const auto& name : effect_names) {
    const auto& extra = effects.at(name);
    specs.insert(specs.end(), extra.begin(), extra.end());
  }
  return specs;
}

const ModelCatalog& DefaultModelCatalog() {
  static const ModelCatalog catalog = [] {
    ModelCatalog c{BaseModelParameterSpecs(), {}};
    for (const EffectInfo& effect : EffectTermCatalogue()) c.effects[effect.name] = effect.parameters;
    return c;
  }();
  return catalog;
}

namespace {

constexpr auto kFailureModeNames = std::to_array<EnumName<FailureMode>>({
    {FailureMode::kPenalty, "penalty"},
    {FailureMode::kRetry, "retry"},
    {FailureMode::kAbort, "abort"},
});

}  // namespace

std::string ToString(FailureMode mode) { return EnumToString(kFailureModeNames, mode); }

FailureMode FailureModeFromString(const std::string& name) {
  return EnumFromString(kFailureModeNames, "failure mode", name);
}

std::vector<std::string> CalibrationRequest::SearchedNames() const {
  std::vector<std::string> names;
  for (const auto& p : parameters) {
    if (p.searched()) names.push_back(p.name);
  }
  return names;
}

// ------------------------------------------------------------- SearchSpace

SearchSpace::SearchSpace(const std::vector<ParameterSetting>& parameters) {
  for (const auto& p : parameters) {
    if (p.searched()) {
      searched_.push_back({p.name, p.lower, p.upper, p.scale == ParameterScale::kLog});
    } else {
      fixed_[p.name] = *p.fixed;
    }
  }
}

std::vector<std::string> SearchSpace::names() const {
  std::vector<std::string> out;
  for (const auto& a : searched_) out.push_back(a.name);
  return out;
}

search::Bounds SearchSpace::UnitBounds() const {
  return {std::vector<double>(searched_.size(), 0.0), std::vector<double>(searched_.size(), 1.0)};
}

ParameterValues SearchSpace::ToParameters(std::span<const double> u) const {
  if (u.size() != searched_.size()) {
    throw std::invalid_argument(fmt::format("search space: point of size {}, expected {}", u.size(),
                                            searched_.size()));
  }
  ParameterValues values = fixed_;
  for (size_t i = 0; i < searched_.size(); ++i) {
    const Axis& a = searched_[i];
    const double t = std::clamp(u[i], 0.0, 1.0);
    double v;
    if (t == 0.0) {
      v = a.lower;
    } else if (t == 1.0) {
      v = a.upper;
    } else if (a.log) {
      const double ll = std::log(a.lower);
      v = std::exp(ll + t * (std::log(a.upper) - ll));
    } else {
      v = a.lower + t * (a.upper - a.lower);
    }
    values[a.name] = std::clamp(v, a.lower, a.upper);
  }
  return values;
}

std::vector<double> SearchSpace::ToUnit(const ParameterValues& values) const {
  std::vector<double> u;
  u.reserve(searched_.size());
  for (const Axis& a : searched_) {
    const auto it = values.find(a.name);
    if (it == values.end()) {
      throw std::invalid_argument(fmt::format("search space: no value for parameter '{}'", a.name));
    }
    if (a.log) {
      const double ll = std::log(a.lower);
      u.push_back((std::log(it->second) - ll) / (std::log(a.upper) - ll));
    } else {
      u.push_back((it->second - a.lower) / (a.upper - a.lower));
    }
  }
  return u;
}

search::CheckedOptimizer MakeRequestOptimizer(const CalibrationRequest& request) {
  return search::MakeOptimizer(request.optimizer.name, request.optimizer.settings,
                               SearchSpace(request).UnitBounds(), request.seed);
}

// --------------------------------------------------------------- ToJson

namespace {

std::string Relative(const std::filesystem::path& p, const std::filesystem::path& base) {
  if (base.empty()) return p.generic_string();
  const std::filesystem::path rel = p.lexically_relative(base);
  if (rel.empty()) return p.generic_string();
  return rel.generic_string();
}

}  // namespace

nlohmann::json ToJson(const JobSpec& spec) {
  using nlohmann::json;
  json out = json::object();
  out["name"] = spec.name;
  out["train"] = json::array();
  for (const auto& p : spec.train) out["train"].push_back(Relative(p, spec.base_dir));
  out["holdout"] = json::array();
  for (const auto& p : spec.holdout) out["holdout"].push_back(Relative(p, spec.base_dir));

  const ModelSpec& m = spec.model;
  out["model"] = {
      {"effects", m.effects},
      {"substeps", m.simulation.substeps},
      {"integrator", ToString(m.simulation.integrator)},
      {"constraint_iterations", m.simulation.constraint_iterations},
      {"min_area_fraction", m.simulation.min_area_fraction},
      {"divergence_diameters", m.simulation.divergence_diameters},
      {"segmentation",
       {{"open_radius_px", m.preparation.segmentation.open_radius_px},
        {"close_radius_px", m.preparation.segmentation.close_radius_px},
        {"fill_holes", m.preparation.segmentation.fill_holes}}},
      {"mesh", {{"edge_length_px", m.preparation.mesher.edge_length_px}}},
      {"outline_tolerance_px", m.preparation.outline_tolerance_px},
  };
  // Written only when on: a job stored before the key existed (off) keeps
  // the same spec and resumes.
  if (m.preparation.mesher.min_edges_across > 0) {
    out["model"]["mesh"]["min_edges_across"] = m.preparation.mesher.min_edges_across;
  }
  if (m.simulation.outline_contact) out["model"]["outline_contact"] = true;
  if (m.simulation.area_weighted) out["model"]["area_weighted"] = true;
  if (m.preparation.max_frames != 0) out["model"]["frames"] = m.preparation.max_frames;
  if (m.simulation.contact_friction != 0.0) {
    out["model"]["contact_friction"] = m.simulation.contact_friction;
  }
  out["parameters"] = json::array();
  for (const auto& p : spec.parameters) {
    if (p.searched()) {
      out["parameters"].push_back(
          {{"name", p.name}, {"lower", p.lower}, {"upper", p.upper}, {"scale", ToString(p.scale)}});
    } else {
      out["parameters"].push_back({{"name", p.name}, {"fixed", *p.fixed}});
    }
  }
  out["optimizer"] = {{"name", spec.optimizer.name}, {"settings", spec.optimizer.settings}};
  out["budget"] = {{"evaluations", spec.budget.evaluations}};
  if (spec.budget.wall_time_s) out["budget"]["wall_time_s"] = *spec.budget.wall_time_s;
  // Written only when set: a job stored before the key existed (no pruning)
  // keeps the same spec and resumes.
  if (spec.budget.prune_factor) out["budget"]["prune_factor"] = *spec.budget.prune_factor;
  out["seed"] = spec.seed;
  out["threads"] = spec.threads;
  out["processes"] = spec.processes;
  out["checkpoint"] = {{"every_evaluations", spec.checkpoint.every_evaluations},
                       {"every_seconds", spec.checkpoint.every_seconds}};
  const FailurePolicy& fp = spec.failure_policy;
  out["failure_policy"] = {{"mode", ToString(fp.mode)}, {"abort_after", fp.abort_after}};
  if (fp.mode == FailureMode::kRetry) out["failure_policy"]["max_retries"] = fp.max_retries;
  if (fp.penalty_score) out["failure_policy"]["penalty_score"] = *fp.penalty_score;
  out["results"] = {{"store", Relative(spec.results.store, spec.base_dir)},
                    {"out_dir", Relative(spec.results.out_dir, spec.base_dir)}};
  return out;
}

}  // namespace calib
