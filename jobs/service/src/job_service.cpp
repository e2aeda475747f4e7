#include "calib/service/job_service.h"

#include "calib/jobs/job_commands.h"
#include "calib/search/factory.h"
#include "calib/service/data_roots.h"
#include "calib/service/job_views.h"
#include "calib/service/service_error.h"
#include "queued_work.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>

namespace calib::service {
namespace {

namespace fs = std::filesystem;

// A results store's files (a loop's or a comparison's, in its folder): their
// content is served as results, not as files.
bool IsStoreFile(const fs::path& path) {
  const std::string name = path.filename().string();
  for (const char* suffix : {".sqlite", ".sqlite-wal", ".sqlite-shm", ".sqlite-journal"}) {
    const std::string s(suffix);
    if (name.size() >= s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0) return true;
  }
  return false;
}

// "a:2,b" -> {"a:2", "b"} (empty items kept, to be refused).
std::vector<std::string> SplitHosts(const std::string& list) {
  std::vector<std::string> out;
  size_t start = 0;
  while (true) {
    const size_t comma = list.find(',', start);
    out.push_back(list.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (comma == std::string::npos) return out;
    start = comma + 1;
  }
}

// Request fields of a submission.
constexpr const char* kSubmitFields = "kind, spec, priority";

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
  if (!mpi_hosts.empty()) {
    // HOST[:SLOTS],... with at least two slots: the manager and a worker.
    int slots = 0;
    for (const std::string& host : SplitHosts(mpi_hosts)) {
      const size_t colon = host.find(':');
      const std::string count = colon == std::string::npos ? "1" : host.substr(colon + 1);
      const bool digits = !count.empty() && count.size() < 6 &&
                          std::all_of(count.begin(), count.end(), [](char c) { return c >= '0' && c <= '9'; });
      if (host.substr(0, colon).empty() || !digits || std::stoi(count) < 1) {
        *error = fmt::format("ServiceOptions::mpi_hosts = '{}': '{}' is not HOST or HOST:SLOTS (SLOTS >= 1)",
                             mpi_hosts, host);
        return false;
      }
      slots += std::stoi(count);
    }
    if (slots < 2) {
      *error = fmt::format("ServiceOptions::mpi_hosts = '{}': {} slot(s). Violated: >= 2 (the manager "
                           "and a worker rank)",
                           mpi_hosts, slots);
      return false;
    }
  }
  if (!mpi_hosts.empty() && (mpi_launcher.empty() || calib_executable.empty())) {
    *error = fmt::format("ServiceOptions::mpi_hosts = '{}' needs mpi_launcher (--mpi-launcher, "
                         "scripts/calib-mpirun.sh) and calib_executable",
                         mpi_hosts);
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

QueueEntry JobService::Entry(const std::string& name) const {
  std::optional<QueueEntry> entry = queue_.Find(name);
  if (!entry) throw ServiceError(404, "name", fmt::format("no job '{}' on this server", name));
  return *entry;
}

nlohmann::json JobService::Submit(const nlohmann::json& request) {
  if (!request.is_object()) {
    throw ServiceError(400, "", "the body must be a JSON object: {\"kind\": ..., \"spec\": ..., \"priority\": N}");
  }
  for (const auto& [key, value] : request.items()) {
    if (key != "kind" && key != "spec" && key != "priority") {
      throw ServiceError(400, key, fmt::format("{}: unknown field (known: {})", key, kSubmitFields));
    }
  }
  QueueKind kind = QueueKind::kJob;
  if (request.contains("kind")) {
    const nlohmann::json& given = request["kind"];
    try {
      kind = QueueKindFromString(given.is_string() ? given.get<std::string>() : given.dump());
    } catch (const std::invalid_argument&) {
      throw ServiceError(400, "kind", fmt::format("kind = {}: must be \"job\", \"loop\" or "
                                                  "\"comparison\"",
                                                  given.dump()));
    }
  }
  if (!request.contains("spec")) {
    throw ServiceError(400, "spec", fmt::format("spec: missing (a {} spec)", ToString(kind)));
  }
  const nlohmann::json& given = request["spec"];
  if (!given.is_object() && !given.is_string()) {
    throw ServiceError(400, "spec", fmt::format("spec: must be a {} spec as a JSON object or as YAML text",
                                                ToString(kind)));
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
  const ValidatedWork work = ValidateSubmitted(kind, text, options_);
  {
    StoreOptions read_only;
    read_only.read_only = true;
    if (queue_.Find(work.name) || ResultStore(options_.store(), read_only).FindJob(work.name)) {
      throw ServiceError(409, "spec",
                         fmt::format("{}: name = '{}': a job of that name is on this server "
                                     "(jobs, loops and comparisons share names; delete it first, "
                                     "or give another name)",
                                     SubmittedSource(kind), work.name));
    }
  }
  try {
    queue_.Add(work.name, kind, work.queued_spec, priority, false);
  } catch (const StoreError& e) {  // submitted at the same moment by another request
    throw ServiceError(409, "spec", e.what());
  }
  wake_.notify_all();
  return {{"name", work.name},
          {"kind", ToString(kind)},
          {"state", "queued"},
          {"priority", priority},
          {"notices", work.notices}};
}

nlohmann::json JobService::List() const {
  nlohmann::json jobs = nlohmann::json::array();
  for (const QueueEntry& entry : queue_.Entries()) jobs.push_back(JobStatusView(options_, entry));
  return {{"jobs", jobs}};
}

nlohmann::json JobService::Status(const std::string& name) const {
  return JobStatusView(options_, Entry(name));
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
  if (entry.kind != QueueKind::kJob) {
    throw ServiceError(409, "name", fmt::format("{} '{}': budgets extend for jobs only (submit the "
                                                "{} again under another name with larger budgets)",
                                                ToString(entry.kind), name, ToString(entry.kind)));
  }
  if (entry.state == QueueState::kQueued || entry.state == QueueState::kRunning) {
    throw ServiceError(409, "name", fmt::format("job '{}' is {}: extend its budget once it has "
                                                "stopped (cancel it first)",
                                                name, ToString(entry.state)));
  }
  JobSpec spec = ServiceJobSpec(entry.spec, options_);
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
  (void)ServiceJobSpec(canonical, options_);
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
  if (entry.kind == QueueKind::kJob) {
    ResultStore store(options_.store());
    if (const std::optional<JobInfo> job = store.FindJob(name)) store.DeleteJob(job->id);
  }
  std::error_code ec;
  fs::remove_all(WorkFolder(options_, name), ec);  // a loop's or a comparison's store with it
  return {{"name", name}, {"deleted", true}};
}

nlohmann::json JobService::Results(const std::string& name) const {
  return JobResultsView(options_, Entry(name));
}

nlohmann::json JobService::Best(const std::string& name) const {
  const QueueEntry entry = Entry(name);
  if (entry.kind != QueueKind::kJob) {
    throw ServiceError(409, "name", fmt::format("{} '{}' has no one best evaluation: its report "
                                                "({}/artefacts) says what it found",
                                                ToString(entry.kind), name, name));
  }
  std::optional<nlohmann::json> best = BestView(options_.store(), name);
  if (!best) throw ServiceError(404, "name", fmt::format("job '{}' has no successful evaluation yet", name));
  return *best;
}

nlohmann::json JobService::Artefacts(const std::string& name) const {
  (void)Entry(name);
  nlohmann::json files = nlohmann::json::array();
  const fs::path folder = WorkFolder(options_, name);
  std::error_code ec;
  if (fs::is_directory(folder, ec)) {
    for (const auto& item : fs::recursive_directory_iterator(folder, ec)) {
      if (!item.is_regular_file() || IsStoreFile(item.path())) continue;
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
  const fs::path path = PathInside(WorkFolder(options_, name), relative, "path");
  std::error_code ec;
  if (!fs::is_regular_file(path, ec) || IsStoreFile(path)) {
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
    // A loop's or a comparison's folder holds its results: kept until deleted.
    if (entry.kind != QueueKind::kJob) continue;
    if (entry.state != QueueState::kDone && entry.state != QueueState::kCancelled) continue;
    const fs::path folder = WorkFolder(options_, entry.name);
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
    const WorkOutcome outcome =
        RunQueued(entry, options_, [this, cancel] { return stopping_.load() || cancel->load(); });
    message = outcome.message;
    if (outcome.stopped) {
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
    spdlog::error("{} '{}': {}", ToString(entry.kind), entry.name, e.what());
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
