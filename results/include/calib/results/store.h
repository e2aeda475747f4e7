#pragma once
// The results store: one SQLite database (WAL mode) holding jobs, every
// evaluation of every job, and checkpoints. The store owns persistence; the
// runner owns what goes in.
//
// Tables (schema version 5, PRAGMA user_version; a version 1 store, which
// lacks job_locks and job_inputs, a version 2 store, which lacks job_runs
// and job_queue, a version 3 store, whose evaluations are only ok or failed
// and have no pruned frame, or a version 4 store, whose queue entries have no
// kind, is migrated when opened for writing):
//   jobs(id, name UNIQUE, spec_json, created_unix_s, updated_unix_s, status,
//        stop_reason, result_json)
//   evaluations(job_id, id, parameters_json, x_json, status ('ok', 'failed'
//        or 'pruned'), score, mean_iou, iou_min, iou_max, failure_frame,
//        pruned_recording, pruned_frame, reason, eval_time_s, worker,
//        attempt, detail_json, recorded_unix_s)     PRIMARY KEY (job_id, id)
//   checkpoints(job_id, sequence, created_unix_s, evaluations_done,
//        state_json BLOB, state_size, state_fnv1a64)  PRIMARY KEY (job_id, sequence)
//   job_locks(job_id PRIMARY KEY, pid, host, token, acquired_unix_s,
//        heartbeat_unix_s)                            the process working on a job
//   job_inputs(job_id, path, size_bytes, fnv1a64)     PRIMARY KEY (job_id, path)
//   job_runs(job_id, sequence, started_unix_s, program_version, host, pid,
//        command)                                     every run or resume of a job
//   job_queue(id, name UNIQUE, spec_json, priority, submitted_unix_s, state,
//        start, message, kind)                        the service's queue (job_queue.h)
// The best evaluation is derived (lowest score among ok evaluations, ties to
// the lowest id, as search::CheckedOptimizer ranks), so it can never
// disagree with the evaluations.
//
// Every SQLite failure becomes a StoreError naming the database path and the
// operation. Doubles are stored as IEEE REAL (bit-exact, except that SQLite
// keeps -0.0 as 0.0), JSON with round-trip precision (nlohmann), NaN as NULL
// (read back as NaN).
//
// Resume: evaluations are never lost. A checkpoint records how many
// evaluations were done when it was taken; evaluations recorded after it stay
// in the store, and the runner, having restored the optimiser from the
// checkpoint, reuses the stored evaluation of each re-asked candidate whose id
// and x match bit for bit instead of simulating it again (the history is
// deterministic, so they do). DeleteEvaluationsFrom exists for a runner that
// prefers to re-evaluate.
//
// Not thread-safe: one ResultStore per process, used by one thread (the MPI
// manager rank, the runner's main thread). Several processes may open the
// same file (e.g. `calib results` while a job runs); writers wait up to
// busy_timeout_ms for each other.

#include "calib/core/parameters.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace calib {

/// The wall clock as the store's timestamps hold it: seconds since the Unix
/// epoch.
double NowUnixSeconds();

/// A database failure; what() names the path and the operation.
class StoreError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The process that works on a job (`calib run` / `calib resume`), known
/// to be alive by its heartbeat. At most one per job.
struct JobLock {
  int64_t pid = 0;
  std::string host;
  std::string token;               ///< unique per acquisition (a reused pid is another holder)
  double acquired_unix_s = 0.0;    ///< set by AcquireJobLock
  double heartbeat_unix_s = 0.0;   ///< set by AcquireJobLock and HeartbeatJobLock
};

/// AcquireJobLock found the job held by a process it may not take over;
/// what() names the store, the job and the holder.
class JobLockedError : public StoreError {
 public:
  JobLockedError(const std::string& message, JobLock holder)
      : StoreError(message), holder_(std::move(holder)) {}
  const JobLock& holder() const { return holder_; }

 private:
  JobLock holder_;
};

/// Whether a holder whose heartbeat is `heartbeat_age_s` old may be taken
/// over (it stopped: killed, or its machine gone). The policy lives with the
/// caller (jobs/job_lock.h); the store only applies it atomically.
using JobLockTakeover = std::function<bool(const JobLock& holder, double heartbeat_age_s)>;

/// A file a job reads, with a fingerprint of its content: what `resume`
/// compares to refuse a data set changed under a job.
struct InputFingerprint {
  std::string path;         ///< as the caller names it (unique per job)
  int64_t size_bytes = 0;
  uint64_t fnv1a64 = 0;     ///< FNV-1a 64 of the bytes
};

/// One invocation that worked on a job (`calib run`, `calib resume`, the
/// service): which program, where and when.
struct JobRunRecord {
  double started_unix_s = 0.0;
  std::string program_version;  ///< e.g. "calib 0.1.0"
  std::string host;
  int64_t pid = 0;
  std::string command;          ///< "run", "resume", "resume --budget 128", "serve"
};

enum class JobStatus {
  kCreated,   ///< made, not started
  kRunning,   ///< started (also what a killed job is left in)
  kStopped,   ///< stopped resumably (wall time, user)
  kFinished,  ///< optimiser done or budget used
  kAborted,   ///< stopped by the failure policy
  kFailed,    ///< stopped by an error
};
std::string ToString(JobStatus status);  ///< "created", "running", ...
/// Throws std::invalid_argument naming the value.
JobStatus JobStatusFromString(const std::string& name);

struct JobInfo {
  int64_t id = 0;
  std::string name;
  nlohmann::json spec;  ///< as given to CreateJob (ToJson(JobSpec))
  double created_unix_s = 0.0;
  double updated_unix_s = 0.0;
  JobStatus status = JobStatus::kCreated;
  std::string stop_reason;
  nlohmann::json result;  ///< free JSON the runner sets (held-out scores...); null if unset
};

/// One evaluated candidate: ok, failed, or pruned (stopped early as
/// hopeless, jobs/pruning.h; neither ok nor failed).
struct EvaluationRecord {
  int64_t id = 0;              ///< the optimiser's candidate id; unique per job
  ParameterValues parameters;  ///< every model parameter, fixed ones included
  std::vector<double> x;       ///< the candidate's point as the optimiser asked it
  bool ok = false;             ///< false: failed or pruned (see reason)
  bool pruned = false;         ///< true: pruned (ok is false)
  /// ok: the objective (XOR area over the training set); pruned: the score
  /// so far at the pruning frame (a lower bound); failed: NaN.
  double score = 0.0;
  double mean_iou = 0.0;       ///< ok: over every frame; otherwise NaN (never ranks first)
  double iou_min = 0.0;        ///< ok: per-frame IoU summary; otherwise NaN
  double iou_max = 0.0;
  int failure_frame = -1;      ///< failed: the first frame not simulated; -1 otherwise
  int pruned_recording = -1;   ///< pruned: index of the training recording of the pruning frame
  int pruned_frame = -1;       ///< pruned: the frame (from 0) after which it was pruned
  std::string reason;          ///< failed or pruned: why; empty when ok
  double eval_time_s = 0.0;    ///< wall time of the evaluation
  std::string worker;          ///< who evaluated it, e.g. "rank 0 thread 3"
  int attempt = 1;             ///< attempts used (retry policy), >= 1
  nlohmann::json detail;       ///< free JSON (per-recording scores...); null if unset
  double recorded_unix_s = 0.0;  ///< set by RecordEvaluations; ignored on input

  /// "ok", "failed" or "pruned": the status column.
  const char* status() const { return ok ? "ok" : pruned ? "pruned" : "failed"; }
};

/// A checkpoint: the optimiser's state, RNG and counters at a moment.
struct CheckpointRecord {
  int64_t sequence = 0;          ///< assigned by SaveCheckpoint: 1, 2, ... per job
  double created_unix_s = 0.0;   ///< set by SaveCheckpoint
  int64_t evaluations_done = 0;  ///< evaluations recorded when it was taken
  nlohmann::json state;          ///< a JSON object (anything the runner needs)
};

struct LatestCheckpointResult {
  /// The newest checkpoint that is intact; nullopt when the job has none
  /// intact (or none at all).
  std::optional<CheckpointRecord> checkpoint;
  /// One message per newer checkpoint skipped because it was corrupted
  /// (size or checksum mismatch, JSON that does not parse or is not an
  /// object), naming the database, job, sequence and what was wrong.
  std::vector<std::string> warnings;
};

struct JobSummary {
  int64_t evaluations = 0;  ///< recorded (ok + failed + pruned)
  int64_t ok = 0;
  int64_t failed = 0;
  int64_t pruned = 0;
  std::optional<EvaluationRecord> best;  ///< nullopt: no ok evaluation
  double mean_eval_time_s = 0.0;          ///< over all evaluations; 0 if none
  double total_eval_time_s = 0.0;
  double first_recorded_unix_s = 0.0;     ///< 0 if none
  double last_recorded_unix_s = 0.0;
  int64_t checkpoints = 0;                ///< kept

  /// A few lines for a terminal: counts, best score and parameters, times.
  std::string Report() const;
};

struct StoreOptions {
  bool read_only = false;         ///< open an existing store without writing
  int keep_checkpoints = 3;       ///< newest kept per job, >= 1
  int busy_timeout_ms = 10000;    ///< wait for another writer this long
};

class ResultStore {
 public:
  /// Opens (creating if absent, unless read_only) the database at `path`,
  /// turns on WAL mode and creates or checks the schema. The folder must
  /// exist. Throws StoreError naming the path: cannot open, not a calib
  /// store, a schema version this build does not know.
  explicit ResultStore(const std::filesystem::path& path, const StoreOptions& options = {});
  ~ResultStore();
  ResultStore(ResultStore&&) noexcept;
  ResultStore& operator=(ResultStore&&) noexcept;
  ResultStore(const ResultStore&) = delete;
  ResultStore& operator=(const ResultStore&) = delete;

  const std::filesystem::path& path() const;
  /// "wal" for a writable store (tests check it).
  std::string JournalMode() const;
  /// PRAGMA user_version: the current one, or 1 for a read-only store
  /// written by an older build.
  int64_t SchemaVersion() const;

  // ------------------------------------------------------------- jobs
  /// A new job; throws StoreError if the name is taken.
  int64_t CreateJob(const std::string& name, const nlohmann::json& spec);
  std::optional<JobInfo> FindJob(const std::string& name) const;
  /// Throws StoreError for an unknown id.
  JobInfo Job(int64_t job) const;
  std::vector<JobInfo> Jobs() const;  ///< by id
  void SetJobStatus(int64_t job, JobStatus status, const std::string& stop_reason = "");
  void SetJobResult(int64_t job, const nlohmann::json& result);
  /// Replaces the stored spec (a resume that accepts a changed spec).
  void SetJobSpec(int64_t job, const nlohmann::json& spec);
  /// Deletes the job and everything of it (evaluations, checkpoints, lock,
  /// inputs, runs). Throws StoreError for an unknown id.
  void DeleteJob(int64_t job);
  /// Appends a run to the job's runs.
  void RecordJobRun(int64_t job, const JobRunRecord& run);
  /// Oldest first; empty when none were recorded (or a read-only store of
  /// version < 3).
  std::vector<JobRunRecord> JobRuns(int64_t job) const;

  // ---------------------------------------------------- lock, inputs
  /// Takes job `job` for `claim` (pid, host, token; the times are set here)
  /// in one transaction: when no one holds it, when claim.token already
  /// does, or when `may_take_over` says the holder stopped. Returns the
  /// holder taken over (nullopt: the lock was free or already claim's).
  /// Throws JobLockedError naming the holder otherwise.
  std::optional<JobLock> AcquireJobLock(int64_t job, const JobLock& claim,
                                        const JobLockTakeover& may_take_over);
  /// Renews the heartbeat of the holder `token`; false when it no longer
  /// holds the job (taken over).
  bool HeartbeatJobLock(int64_t job, const std::string& token);
  /// Releases the lock if `token` holds it.
  void ReleaseJobLock(int64_t job, const std::string& token);
  /// Who holds the job; nullopt when no one does (or a version 1 store).
  std::optional<JobLock> JobLockHolder(int64_t job) const;
  /// Replaces the job's input fingerprints.
  void SetJobInputs(int64_t job, std::span<const InputFingerprint> inputs);
  /// By path; empty when none were recorded (or a version 1 store).
  std::vector<InputFingerprint> JobInputs(int64_t job) const;

  // ------------------------------------------------------ evaluations
  /// Records a batch in one transaction (all or nothing). Throws StoreError
  /// for an id already recorded for the job (naming it).
  void RecordEvaluations(int64_t job, std::span<const EvaluationRecord> records);
  /// Every evaluation of the job, by id.
  std::vector<EvaluationRecord> Evaluations(int64_t job) const;
  /// Those with id >= first_id, by id.
  std::vector<EvaluationRecord> EvaluationsFrom(int64_t job, int64_t first_id) const;
  std::optional<EvaluationRecord> Evaluation(int64_t job, int64_t id) const;
  int64_t EvaluationCount(int64_t job) const;
  /// Deletes the evaluations with id >= first_id; returns how many.
  int64_t DeleteEvaluationsFrom(int64_t job, int64_t first_id);
  /// Lowest score among ok evaluations, ties to the lowest id.
  std::optional<EvaluationRecord> Best(int64_t job) const;

  // ------------------------------------------------------ checkpoints
  /// Writes the checkpoint in one transaction with its size and checksum,
  /// then deletes all but the newest keep_checkpoints; returns its sequence.
  /// state must be a JSON object.
  int64_t SaveCheckpoint(int64_t job, const CheckpointRecord& checkpoint);
  /// The newest intact checkpoint, falling back past corrupted ones (see
  /// LatestCheckpointResult). Nothing is deleted.
  LatestCheckpointResult LatestCheckpoint(int64_t job) const;
  int64_t CheckpointCount(int64_t job) const;

  // ------------------------------------------------- reports, exports
  JobSummary Summary(int64_t job) const;
  /// One row per evaluation, by id: id, status, score, mean_iou, iou_min,
  /// iou_max, failure_frame, pruned_recording, pruned_frame, reason,
  /// eval_time_s, worker, attempt, then one
  /// column per parameter (sorted by name). Doubles in their shortest form
  /// that reads back to the same bits; NaN as an empty field; fields quoted
  /// by libcsv where needed. Throws StoreError naming the path, or for an
  /// unknown job.
  void ExportCsv(int64_t job, const std::filesystem::path& path) const;
  /// {"job": {id, name, status, stop_reason, created, spec, result},
  ///  "summary": {...}, "evaluations": [...]}; NaN as null. Throws StoreError
  ///  naming the path, or for an unknown job.
  void ExportJson(int64_t job, const std::filesystem::path& path) const;
  /// The best evaluation's full parameter set in the SaveParameterFile
  /// format, which `calib simulate --params` reads. Throws StoreError when
  /// the job has no ok evaluation.
  void WriteBestParameterFile(int64_t job, const std::filesystem::path& path) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace calib
