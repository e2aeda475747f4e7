#pragma once
// What the service shows of a job, as JSON read from the results store
// (opened read-only per call, so reading never waits for the workers).
// Numbers that are NaN (a failed evaluation's score) are null.

#include "calib/results/job_queue.h"
#include "calib/service/job_service.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <optional>

namespace calib::service {

/// {"name", "kind", "state" (queue), "priority", "submitted_unix_s",
///  "message", "status", "stop_reason", "evaluations", "failed", "pruned",
///  "budget", "best": {id, score, mean_iou} or null, "runs": [{started_unix_s,
///  program_version, host, command}]}.
/// A job: its status in the service's store ("queued" before it starts).
/// A loop or a comparison: "queued" before it starts, "running", "stopped"
/// (cancelled, or queued again after a stop), "failed" (done without a
/// report) or "finished" (its report written); evaluations, failed and
/// pruned summed over the jobs of its own store; budget 0 for a loop (its
/// calibrations are decided as it goes), every run's for a comparison;
/// best null; and "progress": {"jobs", "jobs_finished"} (a comparison's
/// "runs" too), "report": the report's path among its artefacts, or null.
nlohmann::json JobStatusView(const ServiceOptions& options, const QueueEntry& entry);

/// A job: {"job": JobStatusView, "summary": {...}, "evaluations": [{id,
///  status ("ok", "failed" or "pruned"), score, mean_iou, iou_min, iou_max,
///  failure_frame, reason, attempt, parameters, x}]}.
/// A loop or a comparison: {"job": JobStatusView, "jobs": [{name, status,
///  evaluations, failed, best}] of its own store, "report": a loop's
///  report.json or null}.
nlohmann::json JobResultsView(const ServiceOptions& options, const QueueEntry& entry);

/// {"evaluation", "score", "mean_iou", "parameters": {name: value}};
/// nullopt when the job has no successful evaluation yet.
std::optional<nlohmann::json> BestView(const std::filesystem::path& store, const std::string& name);

}  // namespace calib::service
