#pragma once
// What a family spec holds besides its labels (private to synth): the trees
// that family_spec.cpp reads and checks and family.cpp draws scenarios from.

#include "calib/synth/family.h"

#include <yaml-cpp/yaml.h>

#include <vector>

namespace calib::synth {

struct FamilySpec::Trees {
  /// The base scenario (a value tree: scenario keys, kind push), without
  /// the keys the generator sets (name, seed, frames, effects).
  YAML::Node base;
  /// Per cell (FamilySpec::cells order): the family's trees with the cell's
  /// laid over them (family_detail::Merge).
  struct Cell {
    YAML::Node sample;      ///< scenario keys
    YAML::Node holdout;     ///< push keys of push-b, laid over push-a's push
    YAML::Node parameters;  ///< the effect's keys (null for none)
    YAML::Node tail_s;      ///< still time after the retraction, s
  };
  std::vector<Cell> cells;
};

namespace family_detail {

/// A push scenario's YAML with every key a family may set present once
/// (every shape's keys, every push effect with one stiffness region), less
/// the keys the generator sets itself: what sample trees are checked against.
YAML::Node ScenarioSchema();

}  // namespace family_detail
}  // namespace calib::synth
