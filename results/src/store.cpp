#include "calib/results/store.h"

#include "calib/core/enum_names.h"
#include "sqlite_db.h"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <limits>

namespace calib {

double NowUnixSeconds() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

namespace {

// Version 1: jobs, evaluations, checkpoints. Version 2 adds job_locks and
// job_inputs, version 3 job_runs and job_queue, version 4 pruned
// evaluations, version 5 the kind of a queue entry; an older store is
// migrated when opened for writing and read as it is (no locks, inputs, runs,
// queue or pruned evaluations) when opened read-only.
constexpr int kSchemaVersion = 5;
// PRAGMA application_id: 'CALB', so a foreign SQLite file is recognised.
constexpr int64_t kApplicationId = 0x43414C42;

// Version 1 without its evaluations table: a new store makes that in its
// newest form (kEvaluationsTable).
constexpr const char* kSchema = R"sql(
CREATE TABLE jobs(
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  spec_json TEXT NOT NULL,
  created_unix_s REAL NOT NULL,
  updated_unix_s REAL NOT NULL,
  status TEXT NOT NULL,
  stop_reason TEXT NOT NULL DEFAULT '',
  result_json TEXT
);
CREATE TABLE checkpoints(
  job_id INTEGER NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,
  sequence INTEGER NOT NULL,
  created_unix_s REAL NOT NULL,
  evaluations_done INTEGER NOT NULL,
  state_json BLOB NOT NULL,
  state_size INTEGER NOT NULL,
  state_fnv1a64 INTEGER NOT NULL,
  PRIMARY KEY (job_id, sequence)
);
)sql";

// What version 2 adds to version 1 (a new store gets both).
constexpr const char* kSchemaVersion2 = R"sql(
CREATE TABLE job_locks(
  job_id INTEGER PRIMARY KEY REFERENCES jobs(id) ON DELETE CASCADE,
  pid INTEGER NOT NULL,
  host TEXT NOT NULL,
  token TEXT NOT NULL,
  acquired_unix_s REAL NOT NULL,
  heartbeat_unix_s REAL NOT NULL
);
CREATE TABLE job_inputs(
  job_id INTEGER NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,
  path TEXT NOT NULL,
  size_bytes INTEGER NOT NULL,
  fnv1a64 INTEGER NOT NULL,
  PRIMARY KEY (job_id, path)
) WITHOUT ROWID;
)sql";

// What version 3 adds to version 2: who ran a job when (program version,
// host), and the service's job queue (results/job_queue.h).
constexpr const char* kSchemaVersion3 = R"sql(
CREATE TABLE job_runs(
  job_id INTEGER NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,
  sequence INTEGER NOT NULL,
  started_unix_s REAL NOT NULL,
  program_version TEXT NOT NULL,
  host TEXT NOT NULL,
  pid INTEGER NOT NULL,
  command TEXT NOT NULL,
  PRIMARY KEY (job_id, sequence)
) WITHOUT ROWID;
CREATE TABLE job_queue(
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  name TEXT NOT NULL UNIQUE,
  spec_json TEXT NOT NULL,
  priority INTEGER NOT NULL,
  submitted_unix_s REAL NOT NULL,
  state TEXT NOT NULL,
  start TEXT NOT NULL,
  message TEXT NOT NULL DEFAULT ''
);
)sql";

// The evaluations table as version 4 has it; {} is its name. Versions 1 to
// 3 had no pruned_recording and pruned_frame, and a status only 'ok' or
// 'failed'.
constexpr const char* kEvaluationsTable = R"sql(
CREATE TABLE {}(
  job_id INTEGER NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,
  id INTEGER NOT NULL,
  parameters_json TEXT NOT NULL,
  x_json TEXT NOT NULL,
  status TEXT NOT NULL CHECK (status IN ('ok', 'failed', 'pruned')),
  score REAL,
  mean_iou REAL,
  iou_min REAL,
  iou_max REAL,
  failure_frame INTEGER NOT NULL,
  pruned_recording INTEGER NOT NULL DEFAULT -1,
  pruned_frame INTEGER NOT NULL DEFAULT -1,
  reason TEXT NOT NULL,
  eval_time_s REAL NOT NULL,
  worker TEXT NOT NULL,
  attempt INTEGER NOT NULL,
  detail_json TEXT,
  recorded_unix_s REAL NOT NULL,
  PRIMARY KEY (job_id, id)
) WITHOUT ROWID;
)sql";
constexpr const char* kEvaluationsIndex =
    "CREATE INDEX evaluations_by_score ON evaluations(job_id, status, score, id);";

// What version 4 changes in version 3: an evaluation may be pruned
// (jobs/pruning.h), with the recording and frame it was pruned at. SQLite
// cannot change a CHECK constraint in place, so the evaluations are copied
// into a table of the new form (kEvaluationsTable named evaluations_v4),
// which then takes the old one's place.
constexpr const char* kMigrateEvaluationsTo4 = R"sql(
INSERT INTO evaluations_v4(job_id, id, parameters_json, x_json, status, score, mean_iou, iou_min,
    iou_max, failure_frame, reason, eval_time_s, worker, attempt, detail_json, recorded_unix_s)
  SELECT job_id, id, parameters_json, x_json, status, score, mean_iou, iou_min, iou_max,
    failure_frame, reason, eval_time_s, worker, attempt, detail_json, recorded_unix_s
  FROM evaluations;
DROP TABLE evaluations;
ALTER TABLE evaluations_v4 RENAME TO evaluations;
)sql";

// What version 5 adds to version 4: what a queue entry runs (job, loop or
// comparison; results/job_queue.h); entries queued before are jobs.
constexpr const char* kSchemaVersion5 =
    "ALTER TABLE job_queue ADD COLUMN kind TEXT NOT NULL DEFAULT 'job';";

constexpr const char* kEvaluationColumns =
    "id, parameters_json, x_json, status, score, mean_iou, iou_min, iou_max, failure_frame, "
    "pruned_recording, pruned_frame, reason, eval_time_s, worker, attempt, detail_json, "
    "recorded_unix_s";
// The same read from a store before version 4 (opened read-only).
constexpr const char* kEvaluationColumnsBefore4 =
    "id, parameters_json, x_json, status, score, mean_iou, iou_min, iou_max, failure_frame, "
    "-1, -1, reason, eval_time_s, worker, attempt, detail_json, recorded_unix_s";

constexpr const char* kJobColumns =
    "id, name, spec_json, created_unix_s, updated_unix_s, status, stop_reason, result_json";

// FNV-1a, 64 bit: detects flipped or lost bytes in a checkpoint blob.
uint64_t Fnv1a64(std::string_view bytes) {
  uint64_t h = 0xcbf29ce484222325ULL;
  for (const char c : bytes) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ULL;
  }
  return h;
}

nlohmann::json ParseStoredJson(const sqlite::Db& db, const std::string& text, const std::string& what) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw StoreError(fmt::format("{}: {}: stored JSON does not parse: {}", db.path().string(), what,
                                 e.what()));
  }
}

}  // namespace

namespace {

constexpr auto kJobStatusNames = std::to_array<EnumName<JobStatus>>({
    {JobStatus::kCreated, "created"},
    {JobStatus::kRunning, "running"},
    {JobStatus::kStopped, "stopped"},
    {JobStatus::kFinished, "finished"},
    {JobStatus::kAborted, "aborted"},
    {JobStatus::kFailed, "failed"},
});

}  // namespace

std::string ToString(JobStatus status) { return EnumToString(kJobStatusNames, status); }

JobStatus JobStatusFromString(const std::string& name) {
  return EnumFromString(kJobStatusNames, "job status", name);
}

struct ResultStore::Impl {
  Impl(const std::filesystem::path& path, const StoreOptions& opt)
      : options(opt), db(path, opt.read_only, opt.busy_timeout_ms) {}

  StoreOptions options;
  sqlite::Db db;
  int64_t schema_version = kSchemaVersion;  // 1: a read-only store not migrated

  void OpenSchema();
  void Migrate(int64_t from);
  // The columns ReadEvaluation reads, as this store's version has them.
  const char* EvaluationColumns() const {
    return schema_version >= 4 ? kEvaluationColumns : kEvaluationColumnsBefore4;
  }
  void RequireJob(int64_t job, const std::string& operation);
  JobInfo ReadJob(const sqlite::Statement& s, const std::string& operation);
  EvaluationRecord ReadEvaluation(const sqlite::Statement& s, int64_t job);
  std::vector<EvaluationRecord> ReadEvaluations(int64_t job, int64_t first_id);
};

void ResultStore::Impl::OpenSchema() {
  if (options.keep_checkpoints < 1) {
    throw StoreError(fmt::format("{}: StoreOptions::keep_checkpoints = {}. Violated: >= 1",
                                 db.path().string(), options.keep_checkpoints));
  }
  const std::string where = "open results store";
  if (!options.read_only) {
    const std::string mode = db.QueryText("PRAGMA journal_mode=WAL", where + " (journal_mode=WAL)");
    if (mode != "wal") {
      throw StoreError(fmt::format("{}: {}: journal_mode is '{}', WAL could not be turned on",
                                   db.path().string(), where, mode));
    }
    // In WAL mode NORMAL keeps every committed transaction across a process
    // crash (SIGKILL); only a power loss may undo the last ones.
    db.Exec("PRAGMA synchronous=NORMAL", where);
  }
  db.Exec("PRAGMA foreign_keys=ON", where);

  const int64_t app_id = std::stoll(db.QueryText("PRAGMA application_id", where));
  const int64_t version = std::stoll(db.QueryText("PRAGMA user_version", where));
  const int64_t tables =
      std::stoll(db.QueryText("SELECT count(*) FROM sqlite_schema", where + " (read schema)"));
  if (app_id == 0 && version == 0 && tables == 0) {
    if (options.read_only) {
      throw StoreError(fmt::format("{}: {}: the database is empty, not a calib results store",
                                   db.path().string(), where));
    }
    sqlite::Transaction tx(db, "create schema");
    // Another process may have created it between the check and the lock.
    if (std::stoll(db.QueryText("PRAGMA user_version", "create schema")) == 0) {
      db.Exec(kSchema, "create schema");
      db.Exec(fmt::format(fmt::runtime(kEvaluationsTable), "evaluations"), "create schema");
      db.Exec(kEvaluationsIndex, "create schema");
      db.Exec(kSchemaVersion2, "create schema");
      db.Exec(kSchemaVersion3, "create schema");
      db.Exec(kSchemaVersion5, "create schema");
      db.Exec(fmt::format("PRAGMA application_id={}; PRAGMA user_version={}", kApplicationId,
                          kSchemaVersion),
              "create schema (version)");
    }
    tx.Commit();
    return;
  }
  if (app_id != kApplicationId) {
    throw StoreError(fmt::format("{}: {}: not a calib results store (application_id {}, expected {})",
                                 db.path().string(), where, app_id, kApplicationId));
  }
  if (version < 1 || version > kSchemaVersion) {
    throw StoreError(fmt::format("{}: {}: schema version {}; this build reads versions 1 to {}",
                                 db.path().string(), where, version, kSchemaVersion));
  }
  schema_version = version;
  if (version < kSchemaVersion && !options.read_only) Migrate(version);
}

void ResultStore::Impl::Migrate(int64_t from) {
  const std::string op = fmt::format("migrate schema version {} to {}", from, kSchemaVersion);
  sqlite::Transaction tx(db, op);
  // Another process may have migrated it between the check and the lock.
  const int64_t now = std::stoll(db.QueryText("PRAGMA user_version", op));
  if (now < 2) db.Exec(kSchemaVersion2, op);
  if (now < 3) db.Exec(kSchemaVersion3, op);
  if (now < 4) {
    db.Exec(fmt::format(fmt::runtime(kEvaluationsTable), "evaluations_v4"), op);
    db.Exec(kMigrateEvaluationsTo4, op);
    db.Exec(kEvaluationsIndex, op);
  }
  // A queue made by a build that was newer once (a store written by this
  // version, its user_version set back) has the column already.
  if (now < 5 && db.QueryText("SELECT count(*) FROM pragma_table_info('job_queue') WHERE name = 'kind'",
                              op) == "0") {
    db.Exec(kSchemaVersion5, op);
  }
  if (now < kSchemaVersion) db.Exec(fmt::format("PRAGMA user_version={}", kSchemaVersion), op);
  tx.Commit();
  schema_version = kSchemaVersion;
}

void ResultStore::Impl::RequireJob(int64_t job, const std::string& operation) {
  auto s = db.Prepare("SELECT 1 FROM jobs WHERE id = ?1", operation);
  s.Bind(1, job);
  if (!s.Step()) throw StoreError(fmt::format("{}: {}: no job with id {}", db.path().string(), operation, job));
}

JobInfo ResultStore::Impl::ReadJob(const sqlite::Statement& s, const std::string& operation) {
  JobInfo j;
  j.id = s.Int(0);
  j.name = s.Text(1);
  j.spec = ParseStoredJson(db, s.Text(2), fmt::format("{} (job {} spec)", operation, j.id));
  j.created_unix_s = s.Double(3);
  j.updated_unix_s = s.Double(4);
  try {
    j.status = JobStatusFromString(s.Text(5));
  } catch (const std::invalid_argument& e) {
    throw StoreError(fmt::format("{}: {} (job {}): {}", db.path().string(), operation, j.id, e.what()));
  }
  j.stop_reason = s.Text(6);
  if (!s.IsNull(7)) j.result = ParseStoredJson(db, s.Text(7), fmt::format("{} (job {} result)", operation, j.id));
  return j;
}

EvaluationRecord ResultStore::Impl::ReadEvaluation(const sqlite::Statement& s, int64_t job) {
  EvaluationRecord r;
  r.id = s.Int(0);
  const std::string what = fmt::format("read evaluation {} of job {}", r.id, job);
  try {
    r.parameters = ParseStoredJson(db, s.Text(1), what).get<ParameterValues>();
    r.x = ParseStoredJson(db, s.Text(2), what).get<std::vector<double>>();
  } catch (const nlohmann::json::exception& e) {
    throw StoreError(fmt::format("{}: {}: {}", db.path().string(), what, e.what()));
  }
  const std::string status = s.Text(3);
  r.ok = status == "ok";
  r.pruned = status == "pruned";
  r.score = s.Double(4);
  r.mean_iou = s.Double(5);
  r.iou_min = s.Double(6);
  r.iou_max = s.Double(7);
  r.failure_frame = static_cast<int>(s.Int(8));
  r.pruned_recording = static_cast<int>(s.Int(9));
  r.pruned_frame = static_cast<int>(s.Int(10));
  r.reason = s.Text(11);
  r.eval_time_s = s.Double(12);
  r.worker = s.Text(13);
  r.attempt = static_cast<int>(s.Int(14));
  if (!s.IsNull(15)) r.detail = ParseStoredJson(db, s.Text(15), what);
  r.recorded_unix_s = s.Double(16);
  return r;
}

std::vector<EvaluationRecord> ResultStore::Impl::ReadEvaluations(int64_t job, int64_t first_id) {
  auto s = db.Prepare(fmt::format("SELECT {} FROM evaluations WHERE job_id = ?1 AND id >= ?2 "
                                  "ORDER BY id",
                                  EvaluationColumns()),
                      "read evaluations");
  s.Bind(1, job).Bind(2, first_id);
  std::vector<EvaluationRecord> out;
  while (s.Step()) out.push_back(ReadEvaluation(s, job));
  return out;
}

// ------------------------------------------------------------ lifetime

ResultStore::ResultStore(const std::filesystem::path& path, const StoreOptions& options)
    : impl_(std::make_unique<Impl>(path, options)) {
  impl_->OpenSchema();
}

ResultStore::~ResultStore() = default;
ResultStore::ResultStore(ResultStore&&) noexcept = default;
ResultStore& ResultStore::operator=(ResultStore&&) noexcept = default;

const std::filesystem::path& ResultStore::path() const { return impl_->db.path(); }

std::string ResultStore::JournalMode() const {
  return impl_->db.QueryText("PRAGMA journal_mode", "read journal mode");
}

int64_t ResultStore::SchemaVersion() const { return impl_->schema_version; }

// ------------------------------------------------------------------ jobs

int64_t ResultStore::CreateJob(const std::string& name, const nlohmann::json& spec) {
  const std::string op = fmt::format("create job '{}'", name);
  sqlite::Transaction tx(impl_->db, op);
  {
    auto find = impl_->db.Prepare("SELECT id FROM jobs WHERE name = ?1", op);
    find.Bind(1, name);
    if (find.Step()) {
      throw StoreError(fmt::format("{}: {}: a job of that name exists (id {})",
                                   impl_->db.path().string(), op, find.Int(0)));
    }
  }
  const double now = NowUnixSeconds();
  auto s = impl_->db.Prepare(
      "INSERT INTO jobs(name, spec_json, created_unix_s, updated_unix_s, status) "
      "VALUES (?1, ?2, ?3, ?3, ?4)",
      op);
  s.Bind(1, name).Bind(2, spec.dump()).Bind(3, now).Bind(4, ToString(JobStatus::kCreated));
  s.Run();
  const int64_t id = sqlite3_last_insert_rowid(impl_->db.handle());
  tx.Commit();
  return id;
}

std::optional<JobInfo> ResultStore::FindJob(const std::string& name) const {
  const std::string op = fmt::format("find job '{}'", name);
  auto s = impl_->db.Prepare(fmt::format("SELECT {} FROM jobs WHERE name = ?1", kJobColumns), op);
  s.Bind(1, name);
  if (!s.Step()) return std::nullopt;
  return impl_->ReadJob(s, op);
}

JobInfo ResultStore::Job(int64_t job) const {
  const std::string op = fmt::format("read job {}", job);
  auto s = impl_->db.Prepare(fmt::format("SELECT {} FROM jobs WHERE id = ?1", kJobColumns), op);
  s.Bind(1, job);
  if (!s.Step()) throw StoreError(fmt::format("{}: {}: no job with id {}", path().string(), op, job));
  return impl_->ReadJob(s, op);
}

std::vector<JobInfo> ResultStore::Jobs() const {
  auto s = impl_->db.Prepare(fmt::format("SELECT {} FROM jobs ORDER BY id", kJobColumns), "list jobs");
  std::vector<JobInfo> out;
  while (s.Step()) out.push_back(impl_->ReadJob(s, "list jobs"));
  return out;
}

void ResultStore::SetJobStatus(int64_t job, JobStatus status, const std::string& stop_reason) {
  const std::string op = fmt::format("set status of job {}", job);
  auto s = impl_->db.Prepare(
      "UPDATE jobs SET status = ?2, stop_reason = ?3, updated_unix_s = ?4 WHERE id = ?1", op);
  s.Bind(1, job).Bind(2, ToString(status)).Bind(3, stop_reason).Bind(4, NowUnixSeconds());
  s.Run();
  if (impl_->db.Changes() == 0) {
    throw StoreError(fmt::format("{}: {}: no job with id {}", path().string(), op, job));
  }
}

void ResultStore::SetJobResult(int64_t job, const nlohmann::json& result) {
  const std::string op = fmt::format("set result of job {}", job);
  auto s = impl_->db.Prepare("UPDATE jobs SET result_json = ?2, updated_unix_s = ?3 WHERE id = ?1", op);
  s.Bind(1, job).Bind(2, result.dump()).Bind(3, NowUnixSeconds());
  s.Run();
  if (impl_->db.Changes() == 0) {
    throw StoreError(fmt::format("{}: {}: no job with id {}", path().string(), op, job));
  }
}

void ResultStore::SetJobSpec(int64_t job, const nlohmann::json& spec) {
  const std::string op = fmt::format("set spec of job {}", job);
  auto s = impl_->db.Prepare("UPDATE jobs SET spec_json = ?2, updated_unix_s = ?3 WHERE id = ?1", op);
  s.Bind(1, job).Bind(2, spec.dump()).Bind(3, NowUnixSeconds());
  s.Run();
  if (impl_->db.Changes() == 0) {
    throw StoreError(fmt::format("{}: {}: no job with id {}", path().string(), op, job));
  }
}

void ResultStore::DeleteJob(int64_t job) {
  const std::string op = fmt::format("delete job {}", job);
  sqlite::Transaction tx(impl_->db, op);
  impl_->RequireJob(job, op);
  // The other tables go with it (ON DELETE CASCADE).
  auto s = impl_->db.Prepare("DELETE FROM jobs WHERE id = ?1", op);
  s.Bind(1, job);
  s.Run();
  tx.Commit();
}

void ResultStore::RecordJobRun(int64_t job, const JobRunRecord& run) {
  const std::string op = fmt::format("record a run of job {}", job);
  if (impl_->schema_version < 3) {
    throw StoreError(fmt::format("{}: {}: the store is read-only", path().string(), op));
  }
  sqlite::Transaction tx(impl_->db, op);
  impl_->RequireJob(job, op);
  auto s = impl_->db.Prepare(
      "INSERT INTO job_runs(job_id, sequence, started_unix_s, program_version, host, pid, command) "
      "VALUES (?1, (SELECT COALESCE(MAX(sequence), 0) + 1 FROM job_runs WHERE job_id = ?1), ?2, "
      "?3, ?4, ?5, ?6)",
      op);
  s.Bind(1, job).Bind(2, run.started_unix_s).Bind(3, run.program_version).Bind(4, run.host);
  s.Bind(5, run.pid).Bind(6, run.command);
  s.Run();
  tx.Commit();
}

std::vector<JobRunRecord> ResultStore::JobRuns(int64_t job) const {
  std::vector<JobRunRecord> out;
  if (impl_->schema_version < 3) return out;
  auto s = impl_->db.Prepare(
      "SELECT started_unix_s, program_version, host, pid, command FROM job_runs WHERE job_id = ?1 "
      "ORDER BY sequence",
      fmt::format("read runs of job {}", job));
  s.Bind(1, job);
  while (s.Step()) out.push_back({s.Double(0), s.Text(1), s.Text(2), s.Int(3), s.Text(4)});
  return out;
}

// --------------------------------------------------------- lock, inputs

namespace {

JobLock ReadJobLock(const sqlite::Statement& s) {
  JobLock lock;
  lock.pid = s.Int(0);
  lock.host = s.Text(1);
  lock.token = s.Text(2);
  lock.acquired_unix_s = s.Double(3);
  lock.heartbeat_unix_s = s.Double(4);
  return lock;
}

constexpr const char* kLockColumns = "pid, host, token, acquired_unix_s, heartbeat_unix_s";

}  // namespace

std::optional<JobLock> ResultStore::AcquireJobLock(int64_t job, const JobLock& claim,
                                                   const JobLockTakeover& may_take_over) {
  const std::string op = fmt::format("lock job {}", job);
  sqlite::Transaction tx(impl_->db, op);
  impl_->RequireJob(job, op);
  const double now = NowUnixSeconds();
  std::optional<JobLock> taken_over;
  {
    auto s = impl_->db.Prepare(
        fmt::format("SELECT {} FROM job_locks WHERE job_id = ?1", kLockColumns), op);
    s.Bind(1, job);
    if (s.Step()) {
      JobLock holder = ReadJobLock(s);
      if (holder.token != claim.token) {
        if (!may_take_over(holder, now - holder.heartbeat_unix_s)) {
          const std::string message = fmt::format(
              "{}: job {} is held by process {} on host '{}' (last heartbeat {:.0f} s ago)",
              path().string(), job, holder.pid, holder.host, now - holder.heartbeat_unix_s);
          throw JobLockedError(message, std::move(holder));
        }
        taken_over = std::move(holder);
      }
    }
  }
  auto s = impl_->db.Prepare(
      "INSERT OR REPLACE INTO job_locks(job_id, pid, host, token, acquired_unix_s, "
      "heartbeat_unix_s) VALUES (?1, ?2, ?3, ?4, ?5, ?5)",
      op);
  s.Bind(1, job).Bind(2, claim.pid).Bind(3, claim.host).Bind(4, claim.token).Bind(5, now);
  s.Run();
  tx.Commit();
  return taken_over;
}

bool ResultStore::HeartbeatJobLock(int64_t job, const std::string& token) {
  const std::string op = fmt::format("heartbeat of job {}", job);
  auto s = impl_->db.Prepare(
      "UPDATE job_locks SET heartbeat_unix_s = ?3 WHERE job_id = ?1 AND token = ?2", op);
  s.Bind(1, job).Bind(2, token).Bind(3, NowUnixSeconds());
  s.Run();
  return impl_->db.Changes() == 1;
}

void ResultStore::ReleaseJobLock(int64_t job, const std::string& token) {
  const std::string op = fmt::format("unlock job {}", job);
  auto s = impl_->db.Prepare("DELETE FROM job_locks WHERE job_id = ?1 AND token = ?2", op);
  s.Bind(1, job).Bind(2, token);
  s.Run();
}

std::optional<JobLock> ResultStore::JobLockHolder(int64_t job) const {
  if (impl_->schema_version < 2) return std::nullopt;
  auto s = impl_->db.Prepare(
      fmt::format("SELECT {} FROM job_locks WHERE job_id = ?1", kLockColumns),
      fmt::format("read lock of job {}", job));
  s.Bind(1, job);
  if (!s.Step()) return std::nullopt;
  return ReadJobLock(s);
}

void ResultStore::SetJobInputs(int64_t job, std::span<const InputFingerprint> inputs) {
  const std::string op = fmt::format("record inputs of job {}", job);
  sqlite::Transaction tx(impl_->db, op);
  impl_->RequireJob(job, op);
  {
    auto s = impl_->db.Prepare("DELETE FROM job_inputs WHERE job_id = ?1", op);
    s.Bind(1, job);
    s.Run();
  }
  for (const InputFingerprint& input : inputs) {
    auto s = impl_->db.Prepare(
        "INSERT INTO job_inputs(job_id, path, size_bytes, fnv1a64) VALUES (?1, ?2, ?3, ?4)", op);
    s.Bind(1, job).Bind(2, input.path).Bind(3, input.size_bytes);
    s.Bind(4, static_cast<int64_t>(input.fnv1a64));
    s.Run();
  }
  tx.Commit();
}

std::vector<InputFingerprint> ResultStore::JobInputs(int64_t job) const {
  std::vector<InputFingerprint> out;
  if (impl_->schema_version < 2) return out;
  auto s = impl_->db.Prepare(
      "SELECT path, size_bytes, fnv1a64 FROM job_inputs WHERE job_id = ?1 ORDER BY path",
      fmt::format("read inputs of job {}", job));
  s.Bind(1, job);
  while (s.Step()) {
    out.push_back({s.Text(0), s.Int(1), static_cast<uint64_t>(s.Int(2))});
  }
  return out;
}

// ----------------------------------------------------------- evaluations

void ResultStore::RecordEvaluations(int64_t job, std::span<const EvaluationRecord> records) {
  const std::string op = fmt::format("record evaluations of job {}", job);
  sqlite::Transaction tx(impl_->db, op);
  impl_->RequireJob(job, op);
  const double now = NowUnixSeconds();
  const std::string sql = fmt::format(
      "INSERT INTO evaluations(job_id, {}) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, "
      "?12, ?13, ?14, ?15, ?16, ?17, ?18)",
      kEvaluationColumns);
  for (const EvaluationRecord& r : records) {
    auto s = impl_->db.Prepare(sql, op);
    const nlohmann::json params(r.parameters);
    const nlohmann::json x(r.x);
    s.Bind(1, job).Bind(2, r.id).Bind(3, params.dump()).Bind(4, x.dump());
    s.Bind(5, r.status()).Bind(6, r.score).Bind(7, r.mean_iou);
    s.Bind(8, r.iou_min).Bind(9, r.iou_max).Bind(10, r.failure_frame);
    s.Bind(11, r.pruned_recording).Bind(12, r.pruned_frame).Bind(13, r.reason);
    s.Bind(14, r.eval_time_s).Bind(15, r.worker).Bind(16, r.attempt);
    if (r.detail.is_null()) {
      s.BindNull(17);
    } else {
      s.Bind(17, r.detail.dump());
    }
    s.Bind(18, now);
    try {
      s.Run();
    } catch (const StoreError&) {
      if (s.last_error() == SQLITE_CONSTRAINT_PRIMARYKEY) {
        throw StoreError(fmt::format("{}: {}: evaluation id {} is already recorded", path().string(),
                                     op, r.id));
      }
      throw;
    }
  }
  tx.Commit();
}

std::vector<EvaluationRecord> ResultStore::Evaluations(int64_t job) const {
  return impl_->ReadEvaluations(job, std::numeric_limits<int64_t>::min());
}

std::vector<EvaluationRecord> ResultStore::EvaluationsFrom(int64_t job, int64_t first_id) const {
  return impl_->ReadEvaluations(job, first_id);
}

std::optional<EvaluationRecord> ResultStore::Evaluation(int64_t job, int64_t id) const {
  auto s = impl_->db.Prepare(
      fmt::format("SELECT {} FROM evaluations WHERE job_id = ?1 AND id = ?2",
                  impl_->EvaluationColumns()),
      "read evaluation");
  s.Bind(1, job).Bind(2, id);
  if (!s.Step()) return std::nullopt;
  return impl_->ReadEvaluation(s, job);
}

int64_t ResultStore::EvaluationCount(int64_t job) const {
  auto s = impl_->db.Prepare("SELECT count(*) FROM evaluations WHERE job_id = ?1", "count evaluations");
  s.Bind(1, job);
  s.Step();
  return s.Int(0);
}

int64_t ResultStore::DeleteEvaluationsFrom(int64_t job, int64_t first_id) {
  const std::string op = fmt::format("delete evaluations of job {} from id {}", job, first_id);
  sqlite::Transaction tx(impl_->db, op);
  auto s = impl_->db.Prepare("DELETE FROM evaluations WHERE job_id = ?1 AND id >= ?2", op);
  s.Bind(1, job).Bind(2, first_id);
  s.Run();
  const int64_t n = impl_->db.Changes();
  tx.Commit();
  return n;
}

std::optional<EvaluationRecord> ResultStore::Best(int64_t job) const {
  auto s = impl_->db.Prepare(fmt::format("SELECT {} FROM evaluations WHERE job_id = ?1 AND "
                                         "status = 'ok' AND score IS NOT NULL ORDER BY score, id "
                                         "LIMIT 1",
                                         impl_->EvaluationColumns()),
                             "read best evaluation");
  s.Bind(1, job);
  if (!s.Step()) return std::nullopt;
  return impl_->ReadEvaluation(s, job);
}

// ----------------------------------------------------------- checkpoints

int64_t ResultStore::SaveCheckpoint(int64_t job, const CheckpointRecord& checkpoint) {
  const std::string op = fmt::format("save checkpoint of job {}", job);
  if (!checkpoint.state.is_object()) {
    throw StoreError(fmt::format("{}: {}: state must be a JSON object, found {}", path().string(), op,
                                 checkpoint.state.type_name()));
  }
  const std::string blob = checkpoint.state.dump();
  sqlite::Transaction tx(impl_->db, op);
  impl_->RequireJob(job, op);
  int64_t sequence = 1;
  {
    auto s = impl_->db.Prepare("SELECT coalesce(max(sequence), 0) + 1 FROM checkpoints WHERE job_id = ?1", op);
    s.Bind(1, job);
    s.Step();
    sequence = s.Int(0);
  }
  {
    auto s = impl_->db.Prepare(
        "INSERT INTO checkpoints(job_id, sequence, created_unix_s, evaluations_done, state_json, "
        "state_size, state_fnv1a64) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
        op);
    s.Bind(1, job).Bind(2, sequence).Bind(3, NowUnixSeconds()).Bind(4, checkpoint.evaluations_done);
    s.BindBlob(5, blob).Bind(6, static_cast<int64_t>(blob.size()));
    s.Bind(7, static_cast<int64_t>(Fnv1a64(blob)));
    s.Run();
  }
  {
    auto s = impl_->db.Prepare("DELETE FROM checkpoints WHERE job_id = ?1 AND sequence <= ?2", op);
    s.Bind(1, job).Bind(2, sequence - impl_->options.keep_checkpoints);
    s.Run();
  }
  tx.Commit();
  return sequence;
}

LatestCheckpointResult ResultStore::LatestCheckpoint(int64_t job) const {
  const std::string op = fmt::format("read checkpoints of job {}", job);
  auto s = impl_->db.Prepare(
      "SELECT sequence, created_unix_s, evaluations_done, state_json, state_size, state_fnv1a64 "
      "FROM checkpoints WHERE job_id = ?1 ORDER BY sequence DESC",
      op);
  s.Bind(1, job);
  LatestCheckpointResult out;
  while (s.Step()) {
    const int64_t sequence = s.Int(0);
    const std::string blob = s.Blob(3);
    const int64_t size = s.Int(4);
    const auto checksum = static_cast<uint64_t>(s.Int(5));
    const std::string where = fmt::format("{}: job {} checkpoint {}", path().string(), job, sequence);
    if (static_cast<int64_t>(blob.size()) != size) {
      out.warnings.push_back(fmt::format("{} is corrupted ({} bytes, {} written); skipped", where,
                                         blob.size(), size));
      continue;
    }
    if (Fnv1a64(blob) != checksum) {
      out.warnings.push_back(fmt::format("{} is corrupted (checksum mismatch); skipped", where));
      continue;
    }
    nlohmann::json state;
    try {
      state = nlohmann::json::parse(blob);
    } catch (const nlohmann::json::exception& e) {
      out.warnings.push_back(fmt::format("{} is corrupted (JSON: {}); skipped", where, e.what()));
      continue;
    }
    if (!state.is_object()) {
      out.warnings.push_back(fmt::format("{} is corrupted (state is a JSON {}, not an object); skipped",
                                         where, state.type_name()));
      continue;
    }
    CheckpointRecord c;
    c.sequence = sequence;
    c.created_unix_s = s.Double(1);
    c.evaluations_done = s.Int(2);
    c.state = std::move(state);
    out.checkpoint = std::move(c);
    break;
  }
  return out;
}

int64_t ResultStore::CheckpointCount(int64_t job) const {
  auto s = impl_->db.Prepare("SELECT count(*) FROM checkpoints WHERE job_id = ?1", "count checkpoints");
  s.Bind(1, job);
  s.Step();
  return s.Int(0);
}

// --------------------------------------------------------------- summary

JobSummary ResultStore::Summary(int64_t job) const {
  const std::string op = fmt::format("summarise job {}", job);
  impl_->RequireJob(job, op);
  JobSummary out;
  {
    auto s = impl_->db.Prepare(
        "SELECT count(*), coalesce(sum(status = 'ok'), 0), coalesce(sum(status = 'pruned'), 0), "
        "coalesce(avg(eval_time_s), 0), coalesce(sum(eval_time_s), 0), "
        "coalesce(min(recorded_unix_s), 0), coalesce(max(recorded_unix_s), 0) "
        "FROM evaluations WHERE job_id = ?1",
        op);
    s.Bind(1, job);
    s.Step();
    out.evaluations = s.Int(0);
    out.ok = s.Int(1);
    out.pruned = s.Int(2);
    out.failed = out.evaluations - out.ok - out.pruned;
    out.mean_eval_time_s = s.Double(3);
    out.total_eval_time_s = s.Double(4);
    out.first_recorded_unix_s = s.Double(5);
    out.last_recorded_unix_s = s.Double(6);
  }
  out.best = Best(job);
  out.checkpoints = CheckpointCount(job);
  return out;
}

}  // namespace calib
