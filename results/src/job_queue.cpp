#include "calib/results/job_queue.h"

#include "calib/core/enum_names.h"
#include "calib/results/store.h"
#include "sqlite_db.h"

#include <fmt/format.h>

#include <chrono>

namespace calib {
namespace {

constexpr auto kQueueStateNames = std::to_array<EnumName<QueueState>>({
    {QueueState::kQueued, "queued"},
    {QueueState::kRunning, "running"},
    {QueueState::kDone, "done"},
    {QueueState::kCancelled, "cancelled"},
});

constexpr auto kQueueKindNames = std::to_array<EnumName<QueueKind>>({
    {QueueKind::kJob, "job"},
    {QueueKind::kLoop, "loop"},
    {QueueKind::kComparison, "comparison"},
});

constexpr const char* kColumns =
    "id, name, spec_json, priority, submitted_unix_s, state, start, message, kind";

}  // namespace

std::string ToString(QueueState state) { return EnumToString(kQueueStateNames, state); }

QueueState QueueStateFromString(const std::string& name) {
  return EnumFromString(kQueueStateNames, "queue state", name);
}

std::string ToString(QueueKind kind) { return EnumToString(kQueueKindNames, kind); }

QueueKind QueueKindFromString(const std::string& name) {
  return EnumFromString(kQueueKindNames, "queue entry kind", name);
}

struct JobQueue::Impl {
  explicit Impl(const std::filesystem::path& path) : db(path, false, 10000) {}
  sqlite::Db db;

  QueueEntry Read(const sqlite::Statement& s, const std::string& op) const {
    QueueEntry e;
    e.id = s.Int(0);
    e.name = s.Text(1);
    try {
      e.spec = nlohmann::json::parse(s.Text(2));
      e.state = QueueStateFromString(s.Text(5));
      e.kind = QueueKindFromString(s.Text(8));
    } catch (const std::exception& ex) {
      throw StoreError(fmt::format("{}: {} (queue entry {}): {}", db.path().string(), op, e.id,
                                   ex.what()));
    }
    e.priority = s.Int(3);
    e.submitted_unix_s = s.Double(4);
    e.resume = s.Text(6) == "resume";
    e.message = s.Text(7);
    return e;
  }
};

JobQueue::JobQueue(const std::filesystem::path& store) {
  { ResultStore create_or_migrate(store); }
  impl_ = std::make_unique<Impl>(store);
}

JobQueue::~JobQueue() = default;

int64_t JobQueue::Add(const std::string& name, QueueKind kind, const nlohmann::json& spec,
                      int64_t priority, bool resume) {
  std::lock_guard lock(mutex_);
  const std::string op = fmt::format("queue job '{}'", name);
  sqlite::Transaction tx(impl_->db, op);
  {
    auto find = impl_->db.Prepare("SELECT id FROM job_queue WHERE name = ?1", op);
    find.Bind(1, name);
    if (find.Step()) {
      throw StoreError(fmt::format("{}: {}: a job of that name is in the queue (entry {})",
                                   impl_->db.path().string(), op, find.Int(0)));
    }
  }
  auto s = impl_->db.Prepare(
      "INSERT INTO job_queue(name, spec_json, priority, submitted_unix_s, state, start, kind) "
      "VALUES (?1, ?2, ?3, ?4, 'queued', ?5, ?6)",
      op);
  s.Bind(1, name).Bind(2, spec.dump()).Bind(3, priority).Bind(4, NowUnixSeconds());
  s.Bind(5, resume ? "resume" : "run").Bind(6, ToString(kind));
  s.Run();
  const int64_t id = sqlite3_last_insert_rowid(impl_->db.handle());
  tx.Commit();
  return id;
}

std::optional<QueueEntry> JobQueue::ClaimNext() {
  std::lock_guard lock(mutex_);
  const std::string op = "claim the next queued job";
  sqlite::Transaction tx(impl_->db, op);
  std::optional<QueueEntry> entry;
  {
    auto s = impl_->db.Prepare(fmt::format("SELECT {} FROM job_queue WHERE state = 'queued' "
                                           "ORDER BY priority DESC, id LIMIT 1",
                                           kColumns),
                               op);
    if (s.Step()) entry = impl_->Read(s, op);
  }
  if (!entry) return std::nullopt;
  auto s = impl_->db.Prepare("UPDATE job_queue SET state = 'running' WHERE id = ?1", op);
  s.Bind(1, entry->id);
  s.Run();
  tx.Commit();
  entry->state = QueueState::kRunning;
  return entry;
}

void JobQueue::Set(int64_t id, QueueState state, const std::string& message, bool resume) {
  std::lock_guard lock(mutex_);
  auto s = impl_->db.Prepare(
      "UPDATE job_queue SET state = ?2, message = ?3, start = ?4 WHERE id = ?1",
      fmt::format("set state of queue entry {}", id));
  s.Bind(1, id).Bind(2, ToString(state)).Bind(3, message).Bind(4, resume ? "resume" : "run");
  s.Run();
}

void JobQueue::SetSpec(int64_t id, const nlohmann::json& spec) {
  std::lock_guard lock(mutex_);
  auto s = impl_->db.Prepare("UPDATE job_queue SET spec_json = ?2 WHERE id = ?1",
                             fmt::format("set spec of queue entry {}", id));
  s.Bind(1, id).Bind(2, spec.dump());
  s.Run();
}

std::optional<QueueEntry> JobQueue::Find(const std::string& name) const {
  std::lock_guard lock(mutex_);
  const std::string op = fmt::format("find queued job '{}'", name);
  auto s = impl_->db.Prepare(fmt::format("SELECT {} FROM job_queue WHERE name = ?1", kColumns), op);
  s.Bind(1, name);
  if (!s.Step()) return std::nullopt;
  return impl_->Read(s, op);
}

std::vector<QueueEntry> JobQueue::Entries() const {
  std::lock_guard lock(mutex_);
  const std::string op = "list the queue";
  auto s = impl_->db.Prepare(fmt::format("SELECT {} FROM job_queue ORDER BY id", kColumns), op);
  std::vector<QueueEntry> out;
  while (s.Step()) out.push_back(impl_->Read(s, op));
  return out;
}

void JobQueue::Remove(int64_t id) {
  std::lock_guard lock(mutex_);
  auto s = impl_->db.Prepare("DELETE FROM job_queue WHERE id = ?1",
                             fmt::format("remove queue entry {}", id));
  s.Bind(1, id);
  s.Run();
}

int64_t JobQueue::RequeueRunning() {
  std::lock_guard lock(mutex_);
  auto s = impl_->db.Prepare(
      "UPDATE job_queue SET state = 'queued', start = 'resume' WHERE state = 'running'",
      "queue again the jobs left running");
  s.Run();
  return impl_->db.Changes();
}

}  // namespace calib
