#pragma once
// Sample trees of scene families (private to synth; family_spec.cpp checks
// them, family.cpp draws from them).
//
// A sample tree mirrors a scenario's YAML map; where a scenario has a value
// it has one of
//   - a fixed value (a number, text or list, copied as it is);
//   - a range {min: a, max: b}: uniform in [a, b]; with step: s, one of
//     a, a + s, ... <= b, each as likely (integers when a, b and s are);
//   - a choice {choices: [v1, v2, ...]}: one of them, each as likely; each
//     may itself be a tree (a range, a map);
// and a list may hold trees (colours: [{min: 200, max: 240, step: 1}, ...]).
// A map may also hold `one_of: [map, map, ...]`: one of the maps, each as
// likely, is drawn after the map's other keys and laid over them (Merge):
// its keys join the map's (an object's shape with the keys of that shape), a
// key the map has too only where both hold maps (a camera's resolution
// beside its other keys).

#include "random.h"

#include <yaml-cpp/yaml.h>

#include <string>

namespace calib::synth::family_detail {

/// A map that is one drawn value: a range (a key min or max) or a choice (a
/// key choices); any other map is a map of keys.
bool IsRange(const YAML::Node& node);
bool IsChoice(const YAML::Node& node);
bool PlainMap(const YAML::Node& node);

/// Checks the forms of `tree` (ranges, choices, one_of) and that each of its
/// keys is one of `schema`'s at the same place (a scenario's YAML with every
/// key present; lists are checked against its first element). Throws
/// FamilyError "<source>: <path>.<key> = <value>: <rule>".
void CheckTree(const YAML::Node& tree, const YAML::Node& schema, const std::string& path,
               const std::string& source);

/// Draws a value tree from a (checked) sample tree, in the order of its keys.
YAML::Node Sample(const YAML::Node& tree, SplitMix64& rng);

/// A new tree: `under` with `over` laid on it; maps merge key by key (a
/// range or choice counts as one value), anything else of `over` replaces;
/// an empty `over` leaves `under`.
YAML::Node Merge(const YAML::Node& under, const YAML::Node& over);

}  // namespace calib::synth::family_detail
