#pragma once
// A loop as a spec (YAML or JSON text): what `calib loop` takes as options,
// for loops the service queues (docs/service.md, "Loops and comparisons").
// Its keys are the command's long options with '_' for '-':
//   name              required; letters, digits, '_', '-', '.'
//   train             required; a list of recording folders (fitted)
//   holdout           a list of recording folders (decide, never fitted)
//   seed, budget, effect_budget, optimizer, max_effects, tries,
//   min_confidence, fdr, min_drop, held_out_stretch, equally_good_fits,
//   restarts, overlays, contact_friction, integrator
//                     as the options of the same name, with their ranges
//   outline_contact   true (--outline-contact, the default) or false
//                     (--node-contact)
//   html              false: --no-html
// Relative recording paths are relative to `base_dir`. What the command
// line gives the loop besides (--out, --threads, --resume, the cache) is its
// runner's to set. Every error is a LoopSpecError naming the source, the key
// and the rule: "submitted loop spec: budget = '1': must be in [2, 100000000]".

#include "calib/discovery/loop.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <stdexcept>
#include <string>

namespace calib {

class LoopSpecError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct LoopSpec {
  std::string name;
  /// The options the spec sets; train and holdout absolute (base_dir
  /// joined), out_dir empty.
  LoopOptions options;
};

/// Reads and validates a loop spec. Recordings are not opened.
LoopSpec ParseLoopSpec(const std::string& text, const std::string& source,
                       const std::filesystem::path& base_dir);

/// The spec with every key, which ParseLoopSpec reads back to the same
/// options (the paths absolute).
nlohmann::json ToJson(const LoopSpec& spec);

}  // namespace calib
