#pragma once
// What the service shows of a job, as JSON read from the results store
// (opened read-only per call, so reading never waits for the workers).
// Numbers that are NaN (a failed evaluation's score) are null.

#include "calib/results/job_queue.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <optional>

namespace calib::service {

/// {"name", "state" (queue), "priority", "submitted_unix_s", "message",
///  "status" (the job's in the store, or "queued" before it starts),
///  "stop_reason", "evaluations", "failed", "pruned", "budget", "best": {id, score,
///  mean_iou} or null, "runs": [{started_unix_s, program_version, host,
///  command}]}.
nlohmann::json JobStatusView(const std::filesystem::path& store, const QueueEntry& entry);

/// {"job": JobStatusView, "summary": {...}, "evaluations": [{id, status
///  ("ok", "failed" or "pruned"), score, mean_iou, iou_min, iou_max,
///  failure_frame, reason, attempt, parameters, x}]}.
nlohmann::json JobResultsView(const std::filesystem::path& store, const QueueEntry& entry);

/// {"evaluation", "score", "mean_iou", "parameters": {name: value}};
/// nullopt when the job has no successful evaluation yet.
std::optional<nlohmann::json> BestView(const std::filesystem::path& store, const std::string& name);

}  // namespace calib::service
