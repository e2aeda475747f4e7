// Fuzz target: the checkpoint a resume reads (the JSON text the results
// store keeps; RunnerCheckpoint::FromJson, then CheckedOptimizer::
// RestoreState on a fresh optimiser, as the runner's Restore does), and the
// search going on from it as the runner's cycle does: the outstanding
// candidates re-evaluated and told, then Ask / Tell to a budget of 48.
// The optimiser is the one the state names (any of OptimizerNames(), with
// default settings; "random" otherwise) over the unit box of the dimension
// it names (1..4; 2 otherwise). Expected: JSON that does not parse (the
// store warns and skips it), std::invalid_argument from FromJson or
// RestoreState, or a told count that does not match (the runner's error).
// Anything thrown after a successful restore is a finding.
//
// With CALIB_FUZZ_WRITE_SEEDS=<folder> in the environment it writes a
// checkpoint of every optimiser taken mid-search into <folder> and exits:
// how fuzz/corpus/fuzz_checkpoint/ was made.

#include "calib/jobs/checkpoint.h"
#include "calib/search/factory.h"
#include "fuzz_support.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <stdexcept>

namespace {

using calib::search::Candidate;
using calib::search::CheckedOptimizer;
using calib::search::Evaluation;

constexpr int64_t kBudget = 48;

CheckedOptimizer Make(const std::string& name, int dimension, uint64_t seed) {
  const calib::search::Bounds bounds{std::vector<double>(dimension, 0.0),
                                     std::vector<double>(dimension, 1.0)};
  return calib::search::MakeOptimizer(name, calib::search::WithBudget(name, nullptr, kBudget),
                                      bounds, seed);
}

Evaluation Evaluate(const Candidate& c) {
  double f = 0.0;
  for (double x : c.x) f += (x - 0.3) * (x - 0.3);
  Evaluation e;
  e.id = c.id;
  e.x = c.x;
  e.value = f;
  e.failed = c.id % 7 == 3;  // a failure now and then, as real jobs have
  return e;
}

/// The runner's cycle: outstanding first, then new batches of up to 4.
void Continue(CheckedOptimizer* opt, int64_t steps) {
  for (int64_t i = 0; i < steps && !opt->Done(); ++i) {
    std::vector<Candidate> batch = opt->Outstanding();
    if (batch.empty()) {
      if (opt->asked_count() >= kBudget) return;
      batch = opt->Ask(static_cast<int>(std::min<int64_t>(4, kBudget - opt->asked_count())));
      if (batch.empty()) {  // the runner's error too
        throw std::logic_error(opt->name() +
                               " proposed nothing, has nothing outstanding and is not done");
      }
    }
    std::vector<Evaluation> results;
    for (const Candidate& c : batch) results.push_back(Evaluate(c));
    std::reverse(results.begin(), results.end());  // arrival order is not id order
    opt->Tell(results);
  }
}

void WriteSeeds(const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir);
  for (const std::string& name : calib::search::OptimizerNames()) {
    CheckedOptimizer opt = Make(name, 2, 7);
    Continue(&opt, 3);
    // One batch asked and not yet told: the state a kill leaves.
    if (!opt.Done() && opt.asked_count() < kBudget) (void)opt.Ask(2);
    calib::RunnerCheckpoint cp;
    cp.optimizer = opt.SaveState();
    cp.told = opt.told_count();
    cp.failed = opt.failed_count();
    cp.run_seconds = 1.5;
    cp.seed = 7;
    std::string file = name;
    std::replace(file.begin(), file.end(), ':', '_');
    std::ofstream(dir / (file + ".json")) << cp.ToJson().dump() << '\n';
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  if (const char* dir = std::getenv("CALIB_FUZZ_WRITE_SEEDS")) {
    WriteSeeds(dir);
    std::exit(0);
  }
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace calib;
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(fuzz::Text(data, size));
  } catch (const nlohmann::json::exception&) {
    return 0;  // what ResultStore::LatestCheckpoint catches: skipped with a warning
  }
  static const std::vector<std::string> names = search::OptimizerNames();
  RunnerCheckpoint cp;
  std::string name = "random";
  int dimension = 2;
  try {
    cp = RunnerCheckpoint::FromJson(doc);
    const auto n = cp.optimizer.find("optimizer");
    if (n != cp.optimizer.end() && n->is_string() &&
        std::find(names.begin(), names.end(), n->get<std::string>()) != names.end()) {
      name = n->get<std::string>();
    }
    const auto d = cp.optimizer.find("dimension");
    if (d != cp.optimizer.end() && d->is_number_integer() && *d >= 1 && *d <= 4) {
      dimension = d->get<int>();
    }
  } catch (const std::invalid_argument&) {
    return 0;
  } catch (...) {
    fuzz::Unexpected("fuzz_checkpoint (RunnerCheckpoint::FromJson)");
  }
  std::optional<CheckedOptimizer> made;
  try {
    made.emplace(Make(name, dimension, cp.seed));
  } catch (const std::invalid_argument&) {
    return 0;  // an optimiser that needs more dimensions: no job has it
  }
  try {
    CheckedOptimizer& opt = *made;
    try {
      opt.RestoreState(cp.optimizer);
    } catch (const std::invalid_argument&) {
      return 0;
    }
    if (opt.told_count() != cp.told) return 0;  // the runner refuses it
    Continue(&opt, 16);
  } catch (...) {
    fuzz::Unexpected("fuzz_checkpoint (restored search)");
  }
  return 0;
}
