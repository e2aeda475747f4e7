#include "calib/service/job_service.h"

#include "calib/jobs/job_commands.h"
#include "calib/search/factory.h"
#include "calib/service/data_roots.h"
#include "calib/service/job_views.h"
#include "calib/service/service_error.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>

namespace calib::service {
namespace {

namespace fs = std::filesystem;

constexpr const char* kSpecSource = "submitted spec";

// The spec the server runs: results in its store, the report in its folder.
void PlaceResults(const ServiceOptions& options, JobSpec* spec) {
  spec->results.store = fs::absolute(options.store());
  spec->results.out_dir = fs::absolute(options.reports() / spec->name);
  spec->results.earlier_default_store.clear();
}

JobSpecParseOptions ParseOptions(const ServiceOptions& options, RecordingCheck recordings) {
  JobSpecParseOptions parse;
  parse.recordings = recordings;
  parse.results_root = options.reports();
  return parse;
}

}  // namespace

bool ServiceOptions::IsValid(std::string* error) const {
  if (data_roots.empty()) {
    *error = "ServiceOptions::data_roots is empty. Violated: at least one data root (--data-root)";
    return false;
  }
  for (const fs::path& root : data_roots) {
    std::error_code ec;
    if (!fs::is_directory(root, ec)) {
      *error = fmt::format("data root '{}': not a folder", root.string());
      return false;
    }
  }
  if (concurrent_jobs < 1) {
    *error = fmt::format("ServiceOptions::concurrent_jobs = {}. Violated: >= 1", concurrent_jobs);
    return false;
  }
  if (!(report_max_age_s >= 0.0)) {
    *error = fmt::format("ServiceOptions::report_max_age_s = {}. Violated: >= 0 (0: kept)",
                         report_max_age_s);
    return false;
  }
  if (threads_per_job < 0) {
    *error = fmt::format("ServiceOptions::threads_per_job = {}. Violated: >= 0 (0: all cores)",
                         threads_per_job);
    return false;
  }
  return true;
}

JobService::JobService(ServiceOptions options)
    : options_([&] {
        std::string error;
        if (!options.IsValid(&error)) throw std::invalid_argument(error);
        for (fs::path& root : options.data_roots) root = fs::absolute(root).lexically_normal();
        fs::create_directories(options.reports());
        return options;
      }()),
      queue_(options_.store()) {
  const int64_t requeued = queue_.RequeueRunning();
  if (requeued > 0) {
    spdlog::info("{} job(s) left running by the last server queued again; they continue from "
                 "their checkpoints",
                 requeued);
  }
  for (int i = 0; i < options_.concurrent_jobs; ++i) {
    workers_.emplace_back([this, i] { Worker(i == 0); });
  }
}

JobService::~JobService() { Stop(); }

void JobService::Stop() {
  stopping_ = true;
  wake_.notify_all();
  for (std::thread& worker : workers_) {
    if (worker.joinable()) worker.join();
  }
}

JobSpec JobService::SpecOf(const nlohmann::json& canonical) const {
  JobSpec spec = ParseJobSpec(canonical, kSpecSource, options_.data_roots.front(),
                              ParseOptions(options_, RecordingCheck::kExists));
  PlaceResults(options_, &spec);
  return spec;
}

QueueEntry JobService::Entry(const std::string& name) const {
  std::optional<QueueEntry> entry = queue_.Find(name);
  if (!entry) throw ServiceError(404, "name", fmt::format("no job '{}' on this server", name));
  return *entry;
}

nlohmann::json JobService::Submit(const nlohmann::json& request) {
  if (!request.is_object()) {
    throw ServiceError(400, "", "the body must be a JSON object: {\"spec\": ..., \"priority\": N}");
  }
  for (const auto& [key, value] : request.items()) {
    if (key != "spec" && key != "priority") {
      throw ServiceError(400, key, fmt::format("{}: unknown field (known: spec, priority)", key));
    }
  }
  if (!request.contains("spec")) throw ServiceError(400, "spec", "spec: missing (a job spec)");
  const nlohmann::json& given = request["spec"];
  if (!given.is_object() && !given.is_string()) {
    throw ServiceError(400, "spec", "spec: must be a job spec as a JSON object or as YAML text");
  }
  int64_t priority = 0;
  if (request.contains("priority")) {
    if (!request["priority"].is_number_integer()) {
      throw ServiceError(400, "priority",
                         fmt::format("priority = {}: must be an integer", request["priority"].dump()));
    }
    priority = request["priority"].get<int64_t>();
  }
  const std::string text = given.is_string() ? given.get<std::string>() : given.dump();

  // Where the recordings are is checked before whether they exist: nothing
  // outside the data roots is looked at.
  JobSpec spec;
  try {
    spec = ParseJobSpec(text, kSpecSource, options_.data_roots.front(),
                        ParseOptions(options_, RecordingCheck::kNone));
    for (size_t i = 0; i < spec.train.size(); ++i) {
      RequireInsideDataRoots(spec.train[i], options_.data_roots, fmt::format("train[{}]", i));
    }
    for (size_t i = 0; i < spec.holdout.size(); ++i) {
      RequireInsideDataRoots(spec.holdout[i], options_.data_roots, fmt::format("holdout[{}]", i));
    }
    spec = ParseJobSpec(text, kSpecSource, options_.data_roots.front(),
                        ParseOptions(options_, RecordingCheck::kExists));
    CheckRecordings(spec);
  } catch (const JobSpecError& e) {
    throw ServiceError(400, "spec", e.what());
  }
  // An external optimiser runs the program its settings name: a client of
  // the service would run any program on the server, which reads no more
  // than its data roots.
  if (spec.optimizer.name == "external") {
    throw ServiceError(403, "spec",
                       fmt::format("{}: optimizer.name = 'external': runs a program on the server, "
                                   "which the service does not do (run it with calib run)",
                                   kSpecSource));
  }
  nlohmann::json notices = nlohmann::json::array();
  const fs::path default_store = fs::absolute(options_.reports() / (spec.name + ".sqlite")).lexically_normal();
  const fs::path default_out = fs::absolute(options_.reports() / spec.name).lexically_normal();
  if (spec.results.store != default_store || spec.results.out_dir != default_out) {
    notices.push_back(fmt::format(
        "results.store and results.out_dir of a submitted spec are ignored: the server keeps "
        "the job in its store {} and its report in {}",
        options_.store().string(), (options_.reports() / spec.name).string()));
  }
  PlaceResults(options_, &spec);
  {
    StoreOptions read_only;
    read_only.read_only = true;
    if (queue_.Find(spec.name) || ResultStore(options_.store(), read_only).FindJob(spec.name)) {
      throw ServiceError(409, "spec",
                         fmt::format("{}: name = '{}': a job of that name is on this server "
                                     "(delete it first, or give another name)",
                                     kSpecSource, spec.name));
    }
  }
  try {
    queue_.Add(spec.name, QueueKind::kJob, ToJson(spec), priority, false);
  } catch (const StoreError& e) {  // submitted at the same moment by another request
    throw ServiceError(409, "spec", e.what());
  }
  wake_.notify_all();
  return {{"name", spec.name}, {"state", "queued"}, {"priority", priority}, {"notices", notices}};
}

nlohmann::json JobService::List() const {
  nlohmann::json jobs = nlohmann::json::array();
  for (const QueueEntry& entry : queue_.Entries()) jobs.push_back(JobStatusView(options_.store(), entry));
  return {{"jobs", jobs}};
}

nlohmann::json JobService::Status(const std::string& name) const {
  return JobStatusView(options_.store(), Entry(name));
}

nlohmann::json JobService::Cancel(const std::string& name) {
  const QueueEntry entry = Entry(name);
  if (entry.state == QueueState::kQueued) {
    queue_.Set(entry.id, QueueState::kCancelled, "cancelled by a request", entry.resume);
    return Status(name);
  }
  if (entry.state == QueueState::kRunning) {
    std::lock_guard lock(mutex_);
    if (auto it = cancel_.find(name); it != cancel_.end()) *it->second = true;
    nlohmann::json view = Status(name);
    view["state"] = "cancelling";
    return view;
  }
  throw ServiceError(409, "name", fmt::format("job '{}' is {}: nothing to cancel", name,
                                              ToString(entry.state)));
}

nlohmann::json JobService::Resume(const std::string& name) {
  const QueueEntry entry = Entry(name);
  if (entry.state == QueueState::kQueued || entry.state == QueueState::kRunning) {
    throw ServiceError(409, "name", fmt::format("job '{}' is {} already", name, ToString(entry.state)));
  }
  queue_.Set(entry.id, QueueState::kQueued, "", true);
  wake_.notify_all();
  return Status(name);
}

nlohmann::json JobService::ExtendBudget(const std::string& name, const nlohmann::json& request) {
  const QueueEntry entry = Entry(name);
  if (!request.is_object() || !request.contains("evaluations") ||
      !request["evaluations"].is_number_integer()) {
    throw ServiceError(400, "evaluations", "evaluations: missing or not an integer (the new budget)");
  }
  const int64_t evaluations = request["evaluations"].get<int64_t>();
  if (entry.state == QueueState::kQueued || entry.state == QueueState::kRunning) {
    throw ServiceError(409, "name", fmt::format("job '{}' is {}: extend its budget once it has "
                                                "stopped (cancel it first)",
                                                name, ToString(entry.state)));
  }
  JobSpec spec = SpecOf(entry.spec);
  if (evaluations <= spec.budget.evaluations) {
    throw ServiceError(400, "evaluations",
                       fmt::format("evaluations = {}: must be > the job's budget ({})", evaluations,
                                   spec.budget.evaluations));
  }
  if (!search::BudgetExtendsExactly(spec.optimizer.name)) {
    throw ServiceError(409, "evaluations",
                       fmt::format("job '{}': optimiser '{}' lays out its search for its budget; "
                                   "a larger one would not give the history of a run with it "
                                   "(budgets extend for random, cmaes and genetic)",
                                   name, spec.optimizer.name));
  }
  nlohmann::json canonical = entry.spec;
  const std::string key = search::BudgetSetting(spec.optimizer.name);
  if (!key.empty() && canonical["optimizer"]["settings"].value(key, int64_t{-1}) == spec.budget.evaluations) {
    canonical["optimizer"]["settings"][key] = evaluations;  // the optimiser's own budget follows
  }
  canonical["budget"]["evaluations"] = evaluations;
  (void)SpecOf(canonical);
  queue_.SetSpec(entry.id, canonical);
  queue_.Set(entry.id, QueueState::kQueued, "", true);
  wake_.notify_all();
  return Status(name);
}

nlohmann::json JobService::Delete(const std::string& name) {
  const QueueEntry entry = Entry(name);
  if (entry.state == QueueState::kRunning) {
    throw ServiceError(409, "name", fmt::format("job '{}' is running: cancel it first", name));
  }
  queue_.Remove(entry.id);
  ResultStore store(options_.store());
  if (const std::optional<JobInfo> job = store.FindJob(name)) store.DeleteJob(job->id);
  std::error_code ec;
  fs::remove_all(options_.reports() / name, ec);
  return {{"name", name}, {"deleted", true}};
}

nlohmann::json JobService::Results(const std::string& name) const {
  return JobResultsView(options_.store(), Entry(name));
}

nlohmann::json JobService::Best(const std::string& name) const {
  (void)Entry(name);
  std::optional<nlohmann::json> best = BestView(options_.store(), name);
  if (!best) throw ServiceError(404, "name", fmt::format("job '{}' has no successful evaluation yet", name));
  return *best;
}

nlohmann::json JobService::Artefacts(const std::string& name) const {
  (void)Entry(name);
  nlohmann::json files = nlohmann::json::array();
  const fs::path folder = options_.reports() / name;
  std::error_code ec;
  if (fs::is_directory(folder, ec)) {
    for (const auto& item : fs::recursive_directory_iterator(folder, ec)) {
      if (!item.is_regular_file()) continue;
      files.push_back({{"path", item.path().lexically_relative(folder).generic_string()},
                       {"bytes", item.file_size()}});
    }
  }
  std::sort(files.begin(), files.end(),
            [](const nlohmann::json& a, const nlohmann::json& b) { return a["path"] < b["path"]; });
  return {{"name", name}, {"files", files}};
}

fs::path JobService::Artefact(const std::string& name, const std::string& relative) const {
  (void)Entry(name);
  const fs::path path = PathInside(options_.reports() / name, relative, "path");
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    throw ServiceError(404, "path", fmt::format("path = '{}': job '{}' has no such file", relative, name));
  }
  return path;
}

void JobService::PruneReports() {
  const double now = std::chrono::duration<double>(
                         std::chrono::system_clock::now().time_since_epoch())
                         .count();
  StoreOptions read_only;
  read_only.read_only = true;
  const ResultStore store(options_.store(), read_only);
  for (const QueueEntry& entry : queue_.Entries()) {
    if (entry.state != QueueState::kDone && entry.state != QueueState::kCancelled) continue;
    const fs::path folder = options_.reports() / entry.name;
    std::error_code ec;
    if (!fs::exists(folder, ec)) continue;
    const std::optional<JobInfo> job = store.FindJob(entry.name);
    if (job && now - job->updated_unix_s > options_.report_max_age_s) {
      fs::remove_all(folder, ec);
      spdlog::info("job '{}': report {} deleted, {:.0f} s after the job last changed "
                   "(--report-max-age); its results stay in the store",
                   entry.name, folder.string(), now - job->updated_unix_s);
    }
  }
}

void JobService::Worker(bool prunes) {
  while (!stopping_) {
    if (prunes && options_.report_max_age_s > 0.0) {
      try {
        PruneReports();
      } catch (const std::exception& e) {
        spdlog::error("pruning reports: {}", e.what());
      }
    }
    std::optional<QueueEntry> entry;
    try {
      entry = queue_.ClaimNext();
    } catch (const std::exception& e) {
      spdlog::error("{}", e.what());
    }
    if (!entry) {
      std::unique_lock lock(mutex_);
      wake_.wait_for(lock, std::chrono::seconds(1), [this] { return stopping_.load(); });
      continue;
    }
    RunEntry(*entry);
  }
}

void JobService::RunEntry(const QueueEntry& entry) {
  auto cancel = std::make_shared<std::atomic<bool>>(false);
  {
    std::lock_guard lock(mutex_);
    cancel_[entry.name] = cancel;
  }
  QueueState state = QueueState::kDone;
  std::string message;
  try {
    const JobSpec spec = SpecOf(entry.spec);
    JobCommandOptions run;
    run.threads = options_.threads_per_job;
    run.write_report = options_.write_report;
    run.report_video = options_.report_video;
    run.progress = ProgressMode::kNone;
    run.handle_signals = false;
    run.interrupted = [this, cancel] { return stopping_.load() || cancel->load(); };
    run.program_version = options_.program_version;
    run.command = "serve";
    bool exists = false;
    {
      ResultStore store(options_.store());
      exists = store.FindJob(spec.name).has_value();
    }
    // A job already in the store continues (after a restart, a cancel, an
    // extended budget); RunJob starts afresh one that recorded nothing yet.
    const JobCommandResult result = RunJob(spec, exists ? JobStart::kResume : JobStart::kRun, run);
    message = result.run.status == JobStatus::kCreated
                  ? result.run.stop_reason
                  : fmt::format("{}: {}", ToString(result.run.status), result.run.stop_reason);
    if (result.run.status == JobStatus::kStopped) {
      if (cancel->load()) {
        state = QueueState::kCancelled;
        message = "cancelled by a request; resume it to continue";
      } else if (stopping_) {
        state = QueueState::kQueued;  // continues at the next start
        message = "the server stopped; it continues when the server starts again";
      }
    }
  } catch (const std::exception& e) {
    message = e.what();
    spdlog::error("job '{}': {}", entry.name, e.what());
  }
  try {
    queue_.Set(entry.id, state, message, true);
  } catch (const std::exception& e) {
    spdlog::error("job '{}': {}", entry.name, e.what());
  }
  std::lock_guard lock(mutex_);
  cancel_.erase(entry.name);
}

}  // namespace calib::service
