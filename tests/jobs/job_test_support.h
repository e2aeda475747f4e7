#pragma once
// Shared by the runner and job command tests: a cheap deterministic
// objective, job specs that use it, and the comparison of two histories.

#include "calib/jobs/job_commands.h"
#include "calib/jobs/job_spec.h"
#include "calib/jobs/objective.h"
#include "calib/jobs/runner.h"
#include "calib/results/store.h"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace calib::testing {

/// A cheap deterministic objective on the base model's parameters: a
/// Rastrigin-like function of the parameters' log10 distances from a target
/// (many local minima, one global one), reported as a score with an IoU
/// summary over 10 "frames" of one recording, each scoring a tenth of it
/// (the score so far after frame k is (k + 1) Score(values)); it stops
/// early and traces as EarlyStop asks.
struct SyntheticOptions {
  /// Candidates with tau above this fail (as a simulation that blows up at
  /// frame 3), their reason naming tau.
  double fail_above_tau = 1e300;
  /// Each candidate's first attempt throws (a transient error: the retry
  /// policy's case); its second attempt gives the result.
  bool flaky = false;
  /// Each evaluation sleeps this long (a slower objective without using a
  /// core).
  double sleep_s = 0.0;
};

class SyntheticObjective final : public Objective {
 public:
  explicit SyntheticObjective(SyntheticOptions options = {}) : options_(options) {}
  std::unique_ptr<ObjectiveWorker> MakeWorker() const override;
  std::string Describe() const override { return "synthetic objective"; }

  /// The score of `values` (no failure, no sleep).
  static double Score(const ParameterValues& values);

 private:
  SyntheticOptions options_;
};

/// The YAML of a `parameters` list: k_D, k_d, k_A, k_phi searched on log
/// scales, tau on a linear one, mass fixed (the base model's parameters).
extern const char* const kBaseParametersYaml;

/// A job spec searching k_D, k_d, k_A, k_phi (log) and tau (linear) with
/// mass fixed; `optimizer` is the YAML of the optimizer map, `extra` more
/// top-level YAML (budget, failure_policy, checkpoint...). Its train
/// recording is a placeholder (not read). Budget 96 unless `extra` sets one.
JobSpec SyntheticJobSpec(const std::string& optimizer, const std::string& extra = "",
                         const std::string& name = "synthetic");

/// The YAML of a small real job: CMA-ES (generations of 4) over the base
/// model on the bundled centre push `push_centre` (a folder path) with
/// 40 px mesh edges and 4 substeps, `budget` evaluations at `seed`, 2
/// threads, a checkpoint every 4 evaluations; `results` is the YAML of its
/// results line ("" for none).
std::string SmallPushJobYaml(const std::string& name, const std::string& push_centre, int seed,
                             int budget, const std::string& results);

/// Expects the two histories to be the same: every field of every
/// evaluation bit for bit, except the timing (eval_time_s,
/// recorded_unix_s) and who evaluated it (worker). `what` labels failures.
void ExpectSameHistory(const std::vector<EvaluationRecord>& expected,
                       const std::vector<EvaluationRecord>& actual, const std::string& what);

/// What a run (RunJobIn) left in its store.
struct JobRun {
  RunSummary summary;
  std::vector<EvaluationRecord> history;
  std::optional<EvaluationRecord> best;
  JobInfo info;
};

/// Runs (or resumes) `spec` in the store at `db` with `threads` threads.
JobRun RunJobIn(const JobSpec& spec, const std::filesystem::path& db, const Objective& objective,
                int threads, RunControl control = {}, RunObserver* observer = nullptr);

/// Expects `actual` to have `expected`'s best evaluation (id, parameters,
/// score), and its summary to name it.
void ExpectSameBest(const JobRun& expected, const JobRun& actual, const std::string& what);

/// Runs `spec` at 1, 2 and 4 threads with batches of 3 and of 64 (a store
/// each in `dir`) and expects every run to end as `reference` did, with its
/// history and best.
void ExpectSameRunAtThreadCountsAndBatchSizes(const JobSpec& spec, const Objective& objective,
                                              const std::filesystem::path& dir,
                                              const JobRun& reference);

/// Stops the run when the runner has polled `polls` times.
RunControl StopAfterPolls(int polls, int batch_size);

/// Options for RunJob / ResumeJob that evaluate SyntheticObjective (no
/// recording is simulated) on one thread, with no report and no progress.
JobCommandOptions SyntheticJobCommandOptions();

}  // namespace calib::testing
