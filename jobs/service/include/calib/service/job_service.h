#pragma once
// The service's jobs: a queue in one results store (results/job_queue.h)
// and a pool of workers that run queued jobs through RunJob (the same work
// as `calib run` / `calib resume`: exact resume, the job lock, reports).
// The queue holds loops (`calib loop`, discovery/loop_spec.h) and optimiser
// comparisons (`calib compare-optimizers`) too, each run as its command runs
// it in a folder of its own (<state_dir>/jobs/<name>/: its store, report and
// files), resumed the way its command resumes; "job" below means any of the
// three unless it says a calibration job.
//
// Submitted specs are validated before they are queued (ParseJobSpec, the
// recordings read as `calib run` reads them); their paths are relative to
// the first data root, and every recording must lie inside a data root
// (data_roots.h). The server keeps every job in its own store and writes a
// job's report to <state_dir>/jobs/<name>/; a spec's own results.store and
// results.out_dir are ignored, with a notice in the answer.
//
// Workers take the queued job of highest priority, earliest submitted
// first. Reports are kept until their job is deleted, or for
// report_max_age_s after the job last changed. A job stops resumably when cancelled or when the service stops
// (Stop: it stays queued and continues at the next start); after a SIGKILL
// the next start queues every job left running again, and each continues
// from its last checkpoint to the history an uninterrupted run gives.
//
// Every operation takes and returns JSON (the REST API's bodies, described
// in docs/openapi.yaml) and throws ServiceError for a request it refuses.
// Thread-safe.

#include "calib/jobs/job_spec.h"
#include "calib/results/job_queue.h"

#include <nlohmann/json.hpp>

#include <atomic>
#include <condition_variable>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace calib::service {

struct ServiceOptions {
  /// Folders recordings are read from; >= 1, each an existing folder. Paths
  /// in a submitted spec are relative to the first.
  std::vector<std::filesystem::path> data_roots;
  /// The store (service.sqlite), the reports (jobs/<name>/) and the token.
  std::filesystem::path state_dir = "out/service";
  /// Jobs run at a time, >= 1.
  int concurrent_jobs = 1;
  /// OpenMP threads of each job, >= 0 (0: all cores).
  int threads_per_job = 1;
  /// Write a job's report (job_report.h) when it stops.
  bool write_report = true;
  /// Overlay videos in the reports.
  bool report_video = true;
  /// A finished or cancelled job's report folder is deleted this many
  /// seconds after the job last changed (its results stay in the store);
  /// 0: kept until the job is deleted.
  double report_max_age_s = 0.0;
  /// Recorded with every run of a job ("calib 0.1.0").
  std::string program_version = "calib";
  /// Hosts calibration jobs run on as MPI ranks ("H1:SLOTS,H2:SLOTS", at
  /// least 2 slots in all: rank 0 manages on the first host, the others
  /// evaluate), through `mpi_launcher` (scripts/calib-mpirun.sh) with
  /// `calib_executable` on every host; empty: on the server's threads.
  /// Loops and comparisons run on the server's threads either way.
  std::string mpi_hosts;
  std::filesystem::path mpi_launcher;
  /// Passed to the launcher's --mpirun-args (e.g. "--allow-run-as-root").
  std::string mpirun_args;
  /// The calib the launcher starts (the server's own, at the same path on
  /// every host).
  std::filesystem::path calib_executable;

  bool IsValid(std::string* error) const;
  std::filesystem::path store() const { return state_dir / "service.sqlite"; }
  std::filesystem::path reports() const { return state_dir / "jobs"; }
};

class JobService {
 public:
  /// Opens (or creates) the store, queues again the jobs a killed server
  /// left running, and starts the workers. Throws std::invalid_argument for
  /// invalid options, StoreError for a store it cannot open.
  explicit JobService(ServiceOptions options);
  ~JobService();  ///< Stop()
  JobService(const JobService&) = delete;
  JobService& operator=(const JobService&) = delete;

  /// Stops the workers: running jobs stop resumably (checkpointed) and stay
  /// queued for the next start. Idempotent.
  void Stop();

  /// {"kind": "job" (default), "loop" or "comparison", "spec": object or
  /// YAML/JSON text, "priority": integer (default 0)}
  /// -> {"name", "kind", "state": "queued", "priority", "notices": [...]}.
  nlohmann::json Submit(const nlohmann::json& request);
  /// Every job: queue state, status and progress, by submission.
  nlohmann::json List() const;
  /// One job with its live progress (evaluations, budget, failed, best).
  nlohmann::json Status(const std::string& name) const;
  /// A queued job is cancelled; a running one stops resumably.
  nlohmann::json Cancel(const std::string& name);
  /// A cancelled, stopped or failed job is queued again to continue.
  nlohmann::json Resume(const std::string& name);
  /// {"evaluations": N} larger than the job's budget: queued to continue
  /// to N (calibration jobs whose optimiser allows it,
  /// search::BudgetExtendsExactly).
  nlohmann::json ExtendBudget(const std::string& name, const nlohmann::json& request);
  /// Removes a job that is not running: its queue entry, its evaluations
  /// and checkpoints, its report (a loop's or a comparison's folder, its
  /// store with it).
  nlohmann::json Delete(const std::string& name);
  /// The job, its summary and every evaluation.
  nlohmann::json Results(const std::string& name) const;
  /// The best evaluation and its parameters (a parameter file's content);
  /// ServiceError 409 for a loop or a comparison.
  nlohmann::json Best(const std::string& name) const;
  /// The files of the job's folder (path, bytes), its results stores left
  /// out.
  nlohmann::json Artefacts(const std::string& name) const;
  /// The file `relative` of the job's report folder (ServiceError 404 when
  /// absent, 400/403 for a path that leaves it).
  std::filesystem::path Artefact(const std::string& name, const std::string& relative) const;

  const ServiceOptions& options() const { return options_; }

 private:
  QueueEntry Entry(const std::string& name) const;
  void Worker(bool prunes);
  /// Deletes the report folders past report_max_age_s.
  void PruneReports();
  void RunEntry(const QueueEntry& entry);

  ServiceOptions options_;
  mutable JobQueue queue_;
  std::atomic<bool> stopping_{false};
  std::mutex mutex_;
  std::condition_variable wake_;
  std::map<std::string, std::shared_ptr<std::atomic<bool>>> cancel_;  ///< running jobs
  std::vector<std::thread> workers_;
};

}  // namespace calib::service
