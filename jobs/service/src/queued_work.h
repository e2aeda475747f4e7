#pragma once
// What the service queues, by kind (results/job_queue.h QueueKind): a
// calibration job, a loop (`calib loop`) or an optimiser comparison (`calib
// compare-optimizers`). Per kind, a submitted spec is validated into what
// the queue keeps, and a queued entry is run. The service's private helper
// (job_service.cpp); docs/service.md describes what a client sees.
//
// A job runs in the service's store and writes its report to
// <reports>/<name>/; a loop and a comparison keep their own store, report
// and files in <reports>/<name>/ (the folder `calib loop --out` or `calib
// compare-optimizers --out` would be), so that each resumes as its command
// does.

#include "calib/jobs/job_spec.h"
#include "calib/results/job_queue.h"
#include "calib/service/job_service.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <functional>
#include <string>

namespace calib::service {

/// A submitted spec, validated: its name, what the queue keeps of it (the
/// spec RunQueued reads back), and notices for the client.
struct ValidatedWork {
  std::string name;
  nlohmann::json queued_spec;
  nlohmann::json notices = nlohmann::json::array();
};

/// Validates the spec text of a kind: ServiceError 400 (field "spec") for a
/// bad spec, with the message its command gives; 403 for a recording
/// outside the data roots (checked before anything there is opened) or an
/// external optimiser.
ValidatedWork ValidateSubmitted(QueueKind kind, const std::string& text, const ServiceOptions& options);

/// How messages name a submitted spec of a kind: "submitted spec" (a job's,
/// as `calib run` names a spec file), "submitted loop spec", "submitted
/// comparison spec".
std::string SubmittedSource(QueueKind kind);

/// A queued job's spec as the server runs it (its results in the server's
/// store and report folder).
JobSpec ServiceJobSpec(const nlohmann::json& canonical, const ServiceOptions& options);

/// How a run of an entry ended.
struct WorkOutcome {
  bool stopped = false;  ///< resumably, by `interrupted`
  std::string message;   ///< what it ended with
};

/// Runs (or, `entry.resume`, continues) an entry to its end or until
/// `interrupted` returns true. Throws for errors (the entry is then done
/// with the message).
WorkOutcome RunQueued(const QueueEntry& entry, const ServiceOptions& options,
                      const std::function<bool()>& interrupted);

/// The folder of an entry's report (a job) or of everything it makes (a loop
/// or a comparison).
std::filesystem::path WorkFolder(const ServiceOptions& options, const std::string& name);

/// The store a loop or a comparison keeps in its folder (empty for a job,
/// which is in the service's store).
std::filesystem::path OwnStore(const ServiceOptions& options, const QueueEntry& entry);

}  // namespace calib::service
