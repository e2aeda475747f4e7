#pragma once
// Which model a calibration runs: the paper's base model plus a list of
// effects from the catalogue (effects.h). Its parameters are the base
// model's followed by each effect's, in the order the effects are listed.

#include <string>
#include <vector>

#include "calib/core/parameters.h"

namespace calib {

struct ModelDefinition {
  /// Names from EffectTermCatalogue(), no duplicates. Empty: the base model.
  std::vector<std::string> effects;

  /// False with a message naming the unknown or repeated effect (and, for
  /// an unknown one, listing the known ones).
  bool IsValid(std::string* error) const;

  /// "base" or "base+inertia+table_friction" (for logs and reports).
  std::string ToString() const;

  bool operator==(const ModelDefinition&) const = default;
};

/// BaseModelParameterSpecs() followed by each effect's parameter specs.
/// Throws std::invalid_argument with IsValid's message for an invalid
/// definition.
std::vector<ParameterSpec> ModelParameterSpecs(const ModelDefinition& model);

}  // namespace calib
