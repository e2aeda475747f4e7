#pragma once
// A loop as a spec (YAML or JSON text): what `calib loop` takes as options,
// for loops the service queues (docs/service.md, "Loops and comparisons").
// Its keys are the command's long options with '_' for '-':
//   name              required; letters, digits, '_', '-', '.'
//   train             required; a list of recording folders (fitted)
//   holdout           a list of recording folders (decide, never fitted)
//   seed, budget, effect_budget, optimizer, max_effects, tries,
//   min_confidence, fdr, min_drop, held_out_stretch, equally_good_fits,
//   refit_candidates, restarts, effect_restarts, overlays, contact_friction,
//   integrator
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

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>

namespace calib {

class LoopSpecError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The bounds (inclusive) `calib loop`'s options and a loop spec's keys are
/// held to, read by both; the other numbers are only non-negative or
/// positive.
template <typename T>
struct LoopOptionRange {
  T low, high;
};
inline constexpr LoopOptionRange<int64_t> kLoopBudgetRange{2, 100000000};
inline constexpr LoopOptionRange<double> kLoopMinConfidenceRange{0.0, 1.0};
inline constexpr LoopOptionRange<double> kLoopFdrRange{0.001, 0.5};
inline constexpr LoopOptionRange<double> kLoopMinDropRange{0.0, 0.5};
inline constexpr LoopOptionRange<double> kLoopHeldOutStretchRange{0.05, 0.95};

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
