// The results store: schema and WAL mode, bit-exact round trips, the derived
// best, checkpoints with fallback past corrupted ones, exports that parse
// back, persistence across reopening, the job lock, input fingerprints, the
// migration of version 1, 2 and 3 stores, pruned evaluations, and errors
// naming the database.

#include "calib/results/store.h"

#include "support/csv_support.h"
#include "support/sqlite_support.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

namespace calib {
namespace {

namespace fs = std::filesystem;

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "message: " << (text) << "\nmissing: " << (part)

const nlohmann::json kSpec = {{"name", "job"}, {"seed", 7}, {"budget", {{"evaluations", 10}}}};

EvaluationRecord MakeRecord(int64_t id, double score, bool ok = true) {
  EvaluationRecord r;
  r.id = id;
  // Values with long expansions, to catch any loss of bits.
  r.parameters = {{"k_D", 100.0 / 3.0 + id},      {"k_d", 0.1 * id + 1e-17},
                  {"k_A", std::sqrt(2.0) * 1e5},  {"k_phi", 1.0 / 7.0},
                  {"mass", 0.2},                  {"tau", std::nextafter(0.3, 1.0)}};
  r.x = {1.0 / 3.0, std::nextafter(0.5, 0.0), 0.0, 1.0};
  r.ok = ok;
  r.score = ok ? score : std::numeric_limits<double>::quiet_NaN();
  r.mean_iou = ok ? 0.9 + 1e-3 / (id + 1) : 0.5;
  r.iou_min = 0.81234567890123;
  r.iou_max = 0.99999999999;
  r.failure_frame = ok ? -1 : 17;
  r.reason = ok ? "" : "triangle 3 inverted, \"quoted\", at frame 17";
  r.eval_time_s = 0.125 + id * 1e-3;
  r.worker = "rank 0 thread " + std::to_string(id % 2);
  r.attempt = ok ? 1 : 2;
  if (id % 2 == 0) r.detail = {{"recordings", {{"push_centre", score}}}};
  return r;
}

// A pruned evaluation (jobs/pruning.h): its score so far at recording 1,
// frame 41.
EvaluationRecord MakePrunedRecord(int64_t id, double score) {
  EvaluationRecord r = MakeRecord(id, score);
  r.ok = false;
  r.pruned = true;
  r.mean_iou = r.iou_min = r.iou_max = std::numeric_limits<double>::quiet_NaN();
  r.pruned_recording = 1;
  r.pruned_frame = 41;
  r.reason = "pruned at recording 1 frame 41";
  return r;
}

void ExpectSame(const EvaluationRecord& a, const EvaluationRecord& b) {
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(a.parameters, b.parameters) << "parameters must round-trip bit for bit";
  EXPECT_EQ(a.x, b.x) << "x must round-trip bit for bit";
  EXPECT_EQ(a.ok, b.ok);
  EXPECT_EQ(a.pruned, b.pruned);
  EXPECT_EQ(a.pruned_recording, b.pruned_recording);
  EXPECT_EQ(a.pruned_frame, b.pruned_frame);
  if (std::isnan(a.score)) {
    EXPECT_TRUE(std::isnan(b.score));
  } else {
    EXPECT_EQ(a.score, b.score);
  }
  const auto same = [](double x, double y) { return x == y || (std::isnan(x) && std::isnan(y)); };
  EXPECT_TRUE(same(a.mean_iou, b.mean_iou)) << a.mean_iou << " != " << b.mean_iou;
  EXPECT_TRUE(same(a.iou_min, b.iou_min));
  EXPECT_TRUE(same(a.iou_max, b.iou_max));
  EXPECT_EQ(a.failure_frame, b.failure_frame);
  EXPECT_EQ(a.reason, b.reason);
  EXPECT_EQ(a.eval_time_s, b.eval_time_s);
  EXPECT_EQ(a.worker, b.worker);
  EXPECT_EQ(a.attempt, b.attempt);
  EXPECT_EQ(a.detail, b.detail);
}

using testing::ParseCsvFile;
using testing::RawSql;
using Rows = testing::CsvRows;

TEST(ResultStore, CreatesTheSchemaInWalMode) {
  const fs::path db = testing::ScratchDir("store_schema") / "r.sqlite";
  ResultStore store(db);
  EXPECT_EQ(store.JournalMode(), "wal");
  EXPECT_TRUE(store.Jobs().empty());
  const int64_t job = store.CreateJob("job", kSpec);
  const JobInfo info = store.Job(job);
  EXPECT_EQ(info.name, "job");
  EXPECT_EQ(info.spec, kSpec);
  EXPECT_EQ(info.status, JobStatus::kCreated);
  EXPECT_GT(info.created_unix_s, 1.6e9);
  EXPECT_TRUE(info.result.is_null());
  ASSERT_TRUE(store.FindJob("job").has_value());
  EXPECT_EQ(store.FindJob("job")->id, job);
  EXPECT_FALSE(store.FindJob("other").has_value());
  try {
    store.CreateJob("job", kSpec);
    FAIL() << "duplicate name accepted";
  } catch (const StoreError& e) {
    EXPECT_CONTAINS(e.what(), db.string());
    EXPECT_CONTAINS(e.what(), "create job 'job'");
  }
}

TEST(ResultStore, JobStatusAndResultAreKept) {
  const fs::path db = testing::ScratchDir("store_status") / "r.sqlite";
  ResultStore store(db);
  const int64_t job = store.CreateJob("job", kSpec);
  store.SetJobStatus(job, JobStatus::kStopped, "wall time of 60 s used");
  store.SetJobResult(job, {{"holdout_mean_iou", 0.93}});
  nlohmann::json spec2 = kSpec;
  spec2["seed"] = 8;
  store.SetJobSpec(job, spec2);
  const JobInfo info = store.Job(job);
  EXPECT_EQ(info.status, JobStatus::kStopped);
  EXPECT_EQ(info.stop_reason, "wall time of 60 s used");
  EXPECT_EQ(info.result["holdout_mean_iou"], 0.93);
  EXPECT_EQ(info.spec["seed"], 8);
  EXPECT_THROW(store.SetJobStatus(job + 10, JobStatus::kRunning), StoreError);
  for (JobStatus s : {JobStatus::kCreated, JobStatus::kRunning, JobStatus::kStopped,
                      JobStatus::kFinished, JobStatus::kAborted, JobStatus::kFailed}) {
    EXPECT_EQ(JobStatusFromString(ToString(s)), s);
  }
  EXPECT_THROW(JobStatusFromString("paused"), std::invalid_argument);
}

TEST(ResultStore, EvaluationsRoundTripBitExact) {
  const fs::path db = testing::ScratchDir("store_round_trip") / "r.sqlite";
  ResultStore store(db);
  const int64_t job = store.CreateJob("job", kSpec);
  std::vector<EvaluationRecord> batch = {MakeRecord(2, 1234.5), MakeRecord(0, 987654321.0),
                                         MakeRecord(1, 0.0, false), MakeRecord(3, 1.0 / 3.0)};
  store.RecordEvaluations(job, batch);
  const std::vector<EvaluationRecord> back = store.Evaluations(job);
  ASSERT_EQ(back.size(), 4u);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(back[i].id, i) << "ordered by id";
  ExpectSame(back[0], batch[1]);
  ExpectSame(back[1], batch[2]);
  ExpectSame(back[2], batch[0]);
  ExpectSame(back[3], batch[3]);
  EXPECT_GT(back[0].recorded_unix_s, 1.6e9);
  EXPECT_EQ(store.EvaluationCount(job), 4);
  ASSERT_TRUE(store.Evaluation(job, 1).has_value());
  ExpectSame(*store.Evaluation(job, 1), batch[2]);
  EXPECT_FALSE(store.Evaluation(job, 9).has_value());
  const auto tail = store.EvaluationsFrom(job, 2);
  ASSERT_EQ(tail.size(), 2u);
  EXPECT_EQ(tail[0].id, 2);
}

TEST(ResultStore, ABatchIsAllOrNothing) {
  const fs::path db = testing::ScratchDir("store_atomic") / "r.sqlite";
  ResultStore store(db);
  const int64_t job = store.CreateJob("job", kSpec);
  store.RecordEvaluations(job, std::vector<EvaluationRecord>{MakeRecord(0, 5.0)});
  try {
    store.RecordEvaluations(job, std::vector<EvaluationRecord>{MakeRecord(1, 4.0), MakeRecord(0, 3.0)});
    FAIL() << "duplicate id accepted";
  } catch (const StoreError& e) {
    EXPECT_CONTAINS(e.what(), db.string());
    EXPECT_CONTAINS(e.what(), "evaluation id 0 is already recorded");
  }
  EXPECT_EQ(store.EvaluationCount(job), 1) << "id 1 of the failed batch must be rolled back";
  EXPECT_THROW(store.RecordEvaluations(job + 5, std::vector<EvaluationRecord>{MakeRecord(9, 1.0)}),
               StoreError);
}

TEST(ResultStore, BestIsTheLowestOkScoreTiesToLowestId) {
  const fs::path db = testing::ScratchDir("store_best") / "r.sqlite";
  ResultStore store(db);
  const int64_t job = store.CreateJob("job", kSpec);
  EXPECT_FALSE(store.Best(job).has_value());
  store.RecordEvaluations(job, std::vector<EvaluationRecord>{MakeRecord(0, 0.0, false)});
  EXPECT_FALSE(store.Best(job).has_value()) << "a failed evaluation is never best";
  store.RecordEvaluations(job, std::vector<EvaluationRecord>{MakeRecord(1, 50.0), MakeRecord(2, 20.0)});
  EXPECT_EQ(store.Best(job)->id, 2);
  store.RecordEvaluations(job, std::vector<EvaluationRecord>{MakeRecord(4, 20.0), MakeRecord(3, 30.0)});
  EXPECT_EQ(store.Best(job)->id, 2) << "a tie goes to the lower id";
  store.RecordEvaluations(job, std::vector<EvaluationRecord>{MakeRecord(5, -1.0)});
  EXPECT_EQ(store.Best(job)->id, 5);
  EXPECT_EQ(store.DeleteEvaluationsFrom(job, 4), 2);
  EXPECT_EQ(store.Best(job)->id, 2) << "best is derived, so truncation moves it back";

  const JobSummary summary = store.Summary(job);
  EXPECT_EQ(summary.evaluations, 4);
  EXPECT_EQ(summary.ok, 3);
  EXPECT_EQ(summary.failed, 1);
  ASSERT_TRUE(summary.best.has_value());
  EXPECT_EQ(summary.best->score, 20.0);
  EXPECT_NEAR(summary.mean_eval_time_s, 0.125 + 1.5e-3, 1e-12);
  EXPECT_LE(summary.first_recorded_unix_s, summary.last_recorded_unix_s);
  const std::string report = summary.Report();
  EXPECT_CONTAINS(report, "4 (3 ok, 1 failed)");
  EXPECT_CONTAINS(report, "best: score 20 (candidate 2)");
  EXPECT_CONTAINS(report, "k_D=");
}

TEST(ResultStore, JobsAreKeptApart) {
  const fs::path db = testing::ScratchDir("store_jobs_apart") / "r.sqlite";
  ResultStore store(db);
  const int64_t a = store.CreateJob("a", kSpec);
  const int64_t b = store.CreateJob("b", kSpec);
  store.RecordEvaluations(a, std::vector<EvaluationRecord>{MakeRecord(0, 5.0), MakeRecord(1, 3.0)});
  store.RecordEvaluations(b, std::vector<EvaluationRecord>{MakeRecord(0, 1.0)});
  EXPECT_EQ(store.EvaluationCount(a), 2);
  EXPECT_EQ(store.EvaluationCount(b), 1);
  EXPECT_EQ(store.Best(a)->score, 3.0);
  EXPECT_EQ(store.Jobs().size(), 2u);
}

TEST(ResultStore, CheckpointsSaveAndLoadKeepingTheNewest) {
  const fs::path db = testing::ScratchDir("store_checkpoints") / "r.sqlite";
  StoreOptions options;
  options.keep_checkpoints = 2;
  ResultStore store(db, options);
  const int64_t job = store.CreateJob("job", kSpec);
  EXPECT_FALSE(store.LatestCheckpoint(job).checkpoint.has_value());
  for (int i = 1; i <= 4; ++i) {
    CheckpointRecord c;
    c.evaluations_done = 10 * i;
    c.state = {{"optimizer", {{"mean", {0.1 * i, 1.0 / 3.0}}}}, {"rng", "12345678901234567890"},
               {"counter", i}};
    EXPECT_EQ(store.SaveCheckpoint(job, c), i);
  }
  EXPECT_EQ(store.CheckpointCount(job), 2);
  const LatestCheckpointResult latest = store.LatestCheckpoint(job);
  ASSERT_TRUE(latest.checkpoint.has_value());
  EXPECT_TRUE(latest.warnings.empty());
  EXPECT_EQ(latest.checkpoint->sequence, 4);
  EXPECT_EQ(latest.checkpoint->evaluations_done, 40);
  EXPECT_EQ(latest.checkpoint->state["counter"], 4);
  EXPECT_EQ(latest.checkpoint->state["optimizer"]["mean"][1].get<double>(), 1.0 / 3.0);
  EXPECT_GT(latest.checkpoint->created_unix_s, 1.6e9);
  CheckpointRecord bad;
  bad.state = nlohmann::json::array();
  EXPECT_THROW(store.SaveCheckpoint(job, bad), StoreError);
}

class CorruptedCheckpoint : public ::testing::TestWithParam<std::string> {};

TEST_P(CorruptedCheckpoint, FallsBackToThePreviousGoodOneAndLosesNothing) {
  const fs::path db = testing::ScratchDir("store_corrupt_" + std::to_string(
                                              std::hash<std::string>{}(GetParam()) % 100000)) /
                      "r.sqlite";
  int64_t job = 0;
  {
    ResultStore store(db);
    job = store.CreateJob("job", kSpec);
    for (int i = 0; i < 3; ++i) {
      store.RecordEvaluations(job, std::vector<EvaluationRecord>{MakeRecord(2 * i, 10.0 - i),
                                                                 MakeRecord(2 * i + 1, 20.0 + i)});
      CheckpointRecord c;
      c.evaluations_done = 2 * (i + 1);
      c.state = {{"generation", i}, {"rng", {1, 2, 3, i}}};
      store.SaveCheckpoint(job, c);
    }
  }
  RawSql(db, GetParam());
  ResultStore store(db);
  const LatestCheckpointResult latest = store.LatestCheckpoint(job);
  ASSERT_TRUE(latest.checkpoint.has_value());
  EXPECT_EQ(latest.checkpoint->sequence, 2);
  EXPECT_EQ(latest.checkpoint->evaluations_done, 4);
  EXPECT_EQ(latest.checkpoint->state["generation"], 1);
  ASSERT_EQ(latest.warnings.size(), 1u);
  EXPECT_CONTAINS(latest.warnings[0], db.string());
  EXPECT_CONTAINS(latest.warnings[0], "checkpoint 3 is corrupted");
  EXPECT_EQ(store.EvaluationCount(job), 6) << "no evaluation is lost";
  EXPECT_EQ(store.CheckpointCount(job), 3) << "the corrupted checkpoint is left for inspection";
  EXPECT_EQ(store.Best(job)->id, 4);
}

INSTANTIATE_TEST_SUITE_P(
    ResultStore, CorruptedCheckpoint,
    ::testing::Values(
        // One byte flipped: same size, checksum mismatch.
        "UPDATE checkpoints SET state_json = CAST(replace(CAST(state_json AS TEXT), "
        "'\"generation\":2', '\"generation\":3') AS BLOB) WHERE sequence = 3",
        // Truncated JSON.
        "UPDATE checkpoints SET state_json = substr(state_json, 1, 9) WHERE sequence = 3",
        // Truncated with its size column updated too: the checksum catches it.
        "UPDATE checkpoints SET state_json = CAST('{\"generation\":' AS BLOB), state_size = 14 "
        "WHERE sequence = 3",
        // Emptied.
        "UPDATE checkpoints SET state_json = zeroblob(0) WHERE sequence = 3"));

TEST(ResultStore, AllCheckpointsCorruptedGivesNoneWithWarnings) {
  const fs::path db = testing::ScratchDir("store_all_corrupt") / "r.sqlite";
  int64_t job = 0;
  {
    ResultStore store(db);
    job = store.CreateJob("job", kSpec);
    store.SaveCheckpoint(job, CheckpointRecord{0, 0.0, 0, {{"a", 1}}});
    store.SaveCheckpoint(job, CheckpointRecord{0, 0.0, 0, {{"a", 2}}});
  }
  RawSql(db, "UPDATE checkpoints SET state_json = CAST('{}' AS BLOB)");
  ResultStore store(db);
  const LatestCheckpointResult latest = store.LatestCheckpoint(job);
  EXPECT_FALSE(latest.checkpoint.has_value());
  EXPECT_EQ(latest.warnings.size(), 2u);
}

TEST(ResultStore, CsvExportParsesBack) {
  const fs::path dir = testing::ScratchDir("store_csv");
  ResultStore store(dir / "r.sqlite");
  const int64_t job = store.CreateJob("job", kSpec);
  std::vector<EvaluationRecord> records = {MakeRecord(0, 12.5), MakeRecord(1, 0.0, false),
                                           MakeRecord(2, 1.0 / 3.0)};
  store.RecordEvaluations(job, records);
  store.ExportCsv(job, dir / "e.csv");
  EXPECT_THROW(store.ExportCsv(job + 1, dir / "x.csv"), StoreError);
  try {
    store.ExportCsv(job, dir / "no" / "e.csv");
    FAIL() << "wrote into a missing folder";
  } catch (const StoreError& e) {
    EXPECT_CONTAINS(e.what(), (dir / "no" / "e.csv").string());
  }
  const Rows rows = ParseCsvFile(dir / "e.csv");
  ASSERT_EQ(rows.size(), 4u) << "a header and one row per evaluation";
  const std::vector<std::string>& h = rows[0];
  auto column = [&](const std::string& name) {
    const auto it = std::find(h.begin(), h.end(), name);
    EXPECT_NE(it, h.end()) << name;
    return static_cast<size_t>(it - h.begin());
  };
  for (size_t i = 0; i < records.size(); ++i) {
    const auto& row = rows[i + 1];
    ASSERT_EQ(row.size(), h.size());
    const EvaluationRecord& r = records[i];
    EXPECT_EQ(std::stoll(row[column("id")]), r.id);
    EXPECT_EQ(row[column("status")], r.ok ? "ok" : "failed");
    if (r.ok) {
      EXPECT_EQ(std::stod(row[column("score")]), r.score);
    } else {
      EXPECT_EQ(row[column("score")], "");
    }
    EXPECT_EQ(std::stod(row[column("mean_iou")]), r.mean_iou);
    EXPECT_EQ(row[column("reason")], r.reason) << "quotes and commas survive";
    EXPECT_EQ(row[column("worker")], r.worker);
    for (const auto& [name, value] : r.parameters) {
      EXPECT_EQ(std::stod(row[column(name)]), value) << name << " must read back exactly";
    }
  }
}

TEST(ResultStore, JsonExportParsesBack) {
  const fs::path dir = testing::ScratchDir("store_json");
  ResultStore store(dir / "r.sqlite");
  const int64_t job = store.CreateJob("job", kSpec);
  store.RecordEvaluations(job, std::vector<EvaluationRecord>{MakeRecord(0, 12.5), MakeRecord(1, 0.0, false)});
  store.SetJobStatus(job, JobStatus::kFinished, "budget used");
  store.ExportJson(job, dir / "e.json");
  std::ifstream in(dir / "e.json");
  const nlohmann::json doc = nlohmann::json::parse(in);
  EXPECT_EQ(doc["job"]["name"], "job");
  EXPECT_EQ(doc["job"]["status"], "finished");
  EXPECT_EQ(doc["job"]["spec"], kSpec);
  ASSERT_EQ(doc["evaluations"].size(), 2u);
  EXPECT_EQ(doc["evaluations"][0]["score"].get<double>(), 12.5);
  EXPECT_TRUE(doc["evaluations"][1]["score"].is_null());
  EXPECT_EQ(doc["evaluations"][1]["reason"], MakeRecord(1, 0.0, false).reason);
  EXPECT_EQ(doc["evaluations"][0]["parameters"].get<ParameterValues>(), MakeRecord(0, 12.5).parameters);
  EXPECT_EQ(doc["summary"]["ok"], 1);
  EXPECT_EQ(doc["summary"]["failed"], 1);
  EXPECT_EQ(doc["summary"]["best"]["id"], 0);
}

TEST(ResultStore, BestParameterFileIsReadableBySimulate) {
  const fs::path dir = testing::ScratchDir("store_best_file");
  ResultStore store(dir / "r.sqlite");
  const int64_t job = store.CreateJob("job", kSpec);
  EXPECT_THROW(store.WriteBestParameterFile(job, dir / "best.json"), StoreError);
  store.RecordEvaluations(job, std::vector<EvaluationRecord>{MakeRecord(0, 12.5), MakeRecord(1, 2.5)});
  store.WriteBestParameterFile(job, dir / "best.json");
  const ParameterValues loaded = LoadParameterFile(dir / "best.json", BaseModelParameterSpecs());
  EXPECT_EQ(loaded, MakeRecord(1, 2.5).parameters);
}

TEST(ResultStore, ReopeningKeepsEverything) {
  const fs::path db = testing::ScratchDir("store_reopen") / "r.sqlite";
  std::vector<EvaluationRecord> records = {MakeRecord(0, 3.0), MakeRecord(1, 0.0, false)};
  int64_t job = 0;
  {
    ResultStore store(db);
    job = store.CreateJob("job", kSpec);
    store.RecordEvaluations(job, records);
    store.SaveCheckpoint(job, CheckpointRecord{0, 0.0, 2, {{"k", "v"}}});
    store.SetJobStatus(job, JobStatus::kRunning);
  }
  ResultStore store(db);
  EXPECT_EQ(store.JournalMode(), "wal");
  EXPECT_EQ(store.FindJob("job")->status, JobStatus::kRunning);
  const auto back = store.Evaluations(job);
  ASSERT_EQ(back.size(), 2u);
  ExpectSame(back[0], records[0]);
  ExpectSame(back[1], records[1]);
  EXPECT_EQ(store.LatestCheckpoint(job).checkpoint->state["k"], "v");
  // A read-only store sees the same.
  StoreOptions read_only;
  read_only.read_only = true;
  ResultStore reader(db, read_only);
  EXPECT_EQ(reader.EvaluationCount(job), 2);
  EXPECT_THROW(reader.CreateJob("x", kSpec), StoreError);
}

TEST(ResultStore, BadPathIsNamed) {
  const fs::path db = testing::ScratchDir("store_bad_path") / "no" / "such" / "folder" / "r.sqlite";
  try {
    ResultStore store(db);
    FAIL() << "opened " << db;
  } catch (const StoreError& e) {
    EXPECT_CONTAINS(e.what(), db.string());
    EXPECT_CONTAINS(e.what(), "cannot open results store");
  }
  StoreOptions read_only;
  read_only.read_only = true;
  const fs::path absent = testing::ScratchDir("store_absent") / "absent.sqlite";
  EXPECT_THROW(ResultStore(absent, read_only), StoreError);
}

TEST(ResultStore, ForeignFilesAreRejected) {
  const fs::path dir = testing::ScratchDir("store_foreign");
  std::ofstream(dir / "text.sqlite") << "this is not a database, just some text that is long enough\n";
  try {
    ResultStore store(dir / "text.sqlite");
    FAIL() << "opened a text file";
  } catch (const StoreError& e) {
    EXPECT_CONTAINS(e.what(), (dir / "text.sqlite").string());
  }
  RawSql(dir / "other.sqlite", "CREATE TABLE t(a)");
  try {
    ResultStore store(dir / "other.sqlite");
    FAIL() << "opened another program's database";
  } catch (const StoreError& e) {
    EXPECT_CONTAINS(e.what(), "not a calib results store");
  }
  RawSql(dir / "future.sqlite", "CREATE TABLE t(a); PRAGMA application_id=1128352834; PRAGMA user_version=9");
  try {
    ResultStore store(dir / "future.sqlite");
    FAIL() << "opened a newer schema";
  } catch (const StoreError& e) {
    EXPECT_CONTAINS(e.what(), "schema version 9");
  }
}

JobLock Claim(int64_t pid, const std::string& token) {
  JobLock claim;
  claim.pid = pid;
  claim.host = "host-a";
  claim.token = token;
  return claim;
}

TEST(ResultStore, AJobLockIsHeldUntilReleasedOrTakenOver) {
  const fs::path db = testing::ScratchDir("store_lock") / "r.sqlite";
  ResultStore store(db);
  const int64_t job = store.CreateJob("job", kSpec);
  EXPECT_FALSE(store.JobLockHolder(job).has_value());
  const auto never = [](const JobLock&, double) { return false; };
  EXPECT_FALSE(store.AcquireJobLock(job, Claim(101, "first"), never).has_value());
  ASSERT_TRUE(store.JobLockHolder(job).has_value());
  EXPECT_EQ(store.JobLockHolder(job)->pid, 101);
  EXPECT_EQ(store.JobLockHolder(job)->host, "host-a");
  EXPECT_GT(store.JobLockHolder(job)->heartbeat_unix_s, 1.6e9);
  // The holder may claim it again; another process may not.
  EXPECT_FALSE(store.AcquireJobLock(job, Claim(101, "first"), never).has_value());
  try {
    ResultStore(db).AcquireJobLock(job, Claim(202, "second"), never);
    FAIL() << "a held job was locked twice";
  } catch (const JobLockedError& e) {
    EXPECT_CONTAINS(e.what(), db.string());
    EXPECT_CONTAINS(e.what(), "held by process 101 on host 'host-a'");
    EXPECT_EQ(e.holder().token, "first");
  }
  EXPECT_TRUE(store.HeartbeatJobLock(job, "first"));
  EXPECT_FALSE(store.HeartbeatJobLock(job, "second"));
  // A holder the policy calls stopped is taken over, and its heartbeat then fails.
  double age_seen = -1.0;
  const auto stopped = [&](const JobLock& holder, double age_s) {
    age_seen = age_s;
    return holder.pid == 101;
  };
  const std::optional<JobLock> taken = store.AcquireJobLock(job, Claim(202, "second"), stopped);
  ASSERT_TRUE(taken.has_value());
  EXPECT_EQ(taken->pid, 101);
  EXPECT_GE(age_seen, 0.0);
  EXPECT_FALSE(store.HeartbeatJobLock(job, "first")) << "the old holder lost the lock";
  store.ReleaseJobLock(job, "first");  // not its lock any more: nothing happens
  EXPECT_EQ(store.JobLockHolder(job)->pid, 202);
  store.ReleaseJobLock(job, "second");
  EXPECT_FALSE(store.JobLockHolder(job).has_value());
}

TEST(ResultStore, InputFingerprintsRoundTrip) {
  const fs::path db = testing::ScratchDir("store_inputs") / "r.sqlite";
  ResultStore store(db);
  const int64_t job = store.CreateJob("job", kSpec);
  EXPECT_TRUE(store.JobInputs(job).empty());
  const std::vector<InputFingerprint> inputs = {
      {"rec/track.csv", 1234, 0xfedcba9876543210ULL}, {"rec/recording.json", 55, 7}};
  store.SetJobInputs(job, inputs);
  const std::vector<InputFingerprint> back = ResultStore(db).JobInputs(job);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].path, "rec/recording.json");  // by path
  EXPECT_EQ(back[1].path, "rec/track.csv");
  EXPECT_EQ(back[1].size_bytes, 1234);
  EXPECT_EQ(back[1].fnv1a64, 0xfedcba9876543210ULL) << "all 64 bits kept";
  store.SetJobInputs(job, std::span(inputs).first(1));
  EXPECT_EQ(store.JobInputs(job).size(), 1u) << "replaced, not added to";
}

TEST(ResultStore, AVersion1StoreIsMigratedWhenOpenedForWriting) {
  const fs::path dir = testing::ScratchDir("store_v1");
  {
    ResultStore store(dir / "r.sqlite");
    const int64_t job = store.CreateJob("job", kSpec);
    store.RecordEvaluations(job, std::vector<EvaluationRecord>{MakeRecord(0, 5.0)});
  }
  // What a version 1 build wrote: no job_locks, no job_inputs (nor what
  // version 3 adds).
  RawSql(dir / "r.sqlite",
         "DROP TABLE job_locks; DROP TABLE job_inputs; DROP TABLE job_runs; DROP TABLE job_queue; "
         "PRAGMA user_version=1");
  StoreOptions read_only;
  read_only.read_only = true;
  {
    ResultStore reader(dir / "r.sqlite", read_only);
    EXPECT_EQ(reader.SchemaVersion(), 1);
    const int64_t job = reader.FindJob("job")->id;
    EXPECT_EQ(reader.EvaluationCount(job), 1);
    EXPECT_FALSE(reader.JobLockHolder(job).has_value());
    EXPECT_TRUE(reader.JobInputs(job).empty());
  }
  ResultStore store(dir / "r.sqlite");
  EXPECT_EQ(store.SchemaVersion(), 5);
  const int64_t job = store.FindJob("job")->id;
  EXPECT_EQ(store.EvaluationCount(job), 1) << "nothing lost";
  EXPECT_FALSE(store.AcquireJobLock(job, Claim(1, "t"), [](const JobLock&, double) { return false; })
                   .has_value());
  EXPECT_EQ(ResultStore(dir / "r.sqlite", read_only).SchemaVersion(), 5);
}

TEST(ResultStore, AVersion2StoreIsMigratedAndKeepsEverything) {
  const fs::path dir = testing::ScratchDir("store_v2");
  {
    ResultStore store(dir / "r.sqlite");
    const int64_t job = store.CreateJob("job", kSpec);
    store.RecordEvaluations(job, std::vector<EvaluationRecord>{MakeRecord(0, 5.0), MakeRecord(1, 4.0)});
    CheckpointRecord cp;
    cp.evaluations_done = 2;
    cp.state = {{"k", 1}};
    store.SaveCheckpoint(job, cp);
  }
  // What a version 2 build wrote: no job_runs, no job_queue.
  RawSql(dir / "r.sqlite", "DROP TABLE job_runs; DROP TABLE job_queue; PRAGMA user_version=2");
  StoreOptions read_only;
  read_only.read_only = true;
  {
    ResultStore reader(dir / "r.sqlite", read_only);
    EXPECT_EQ(reader.SchemaVersion(), 2);
    EXPECT_TRUE(reader.JobRuns(reader.FindJob("job")->id).empty()) << "read as it is";
  }
  ResultStore store(dir / "r.sqlite");
  EXPECT_EQ(store.SchemaVersion(), 5);
  const int64_t job = store.FindJob("job")->id;
  EXPECT_EQ(store.EvaluationCount(job), 2) << "nothing lost";
  EXPECT_EQ(store.Best(job)->id, 1);
  EXPECT_EQ(store.CheckpointCount(job), 1);
  store.RecordJobRun(job, {1.5e9, "calib 1.2.3", "host-a", 42, "resume"});
  const std::vector<JobRunRecord> runs = store.JobRuns(job);
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_EQ(runs[0].started_unix_s, 1.5e9);
  EXPECT_EQ(runs[0].program_version, "calib 1.2.3");
  EXPECT_EQ(runs[0].host, "host-a");
  EXPECT_EQ(runs[0].pid, 42);
  EXPECT_EQ(runs[0].command, "resume");
}

TEST(ResultStore, AVersion3StoreIsMigratedAndKeepsEveryEvaluationBitExact) {
  const fs::path dir = testing::ScratchDir("store_v3");
  const std::vector<EvaluationRecord> records = {MakeRecord(0, 5.0), MakeRecord(1, 0.0, false),
                                                 MakeRecord(2, 1.0 / 3.0)};
  {
    ResultStore store(dir / "r.sqlite");
    store.RecordEvaluations(store.CreateJob("job", kSpec), records);
  }
  // What a version 3 build wrote: evaluations only ok or failed, no pruned
  // frame.
  RawSql(dir / "r.sqlite", R"sql(
CREATE TABLE v3(
  job_id INTEGER NOT NULL REFERENCES jobs(id) ON DELETE CASCADE, id INTEGER NOT NULL,
  parameters_json TEXT NOT NULL, x_json TEXT NOT NULL,
  status TEXT NOT NULL CHECK (status IN ('ok', 'failed')), score REAL, mean_iou REAL,
  iou_min REAL, iou_max REAL, failure_frame INTEGER NOT NULL, reason TEXT NOT NULL,
  eval_time_s REAL NOT NULL, worker TEXT NOT NULL, attempt INTEGER NOT NULL, detail_json TEXT,
  recorded_unix_s REAL NOT NULL, PRIMARY KEY (job_id, id)) WITHOUT ROWID;
INSERT INTO v3 SELECT job_id, id, parameters_json, x_json, status, score, mean_iou, iou_min,
  iou_max, failure_frame, reason, eval_time_s, worker, attempt, detail_json, recorded_unix_s
  FROM evaluations;
DROP TABLE evaluations;
ALTER TABLE v3 RENAME TO evaluations;
CREATE INDEX evaluations_by_score ON evaluations(job_id, status, score, id);
PRAGMA user_version=3;
)sql");
  StoreOptions read_only;
  read_only.read_only = true;
  {
    ResultStore reader(dir / "r.sqlite", read_only);
    EXPECT_EQ(reader.SchemaVersion(), 3);
    const std::vector<EvaluationRecord> back = reader.Evaluations(reader.FindJob("job")->id);
    ASSERT_EQ(back.size(), 3u) << "read as it is";
    for (size_t i = 0; i < back.size(); ++i) ExpectSame(back[i], records[i]);
  }
  ResultStore store(dir / "r.sqlite");
  EXPECT_EQ(store.SchemaVersion(), 5);
  const int64_t job = store.FindJob("job")->id;
  const std::vector<EvaluationRecord> back = store.Evaluations(job);
  ASSERT_EQ(back.size(), 3u) << "nothing lost";
  for (size_t i = 0; i < back.size(); ++i) ExpectSame(back[i], records[i]);
  store.RecordEvaluations(job, std::vector<EvaluationRecord>{MakePrunedRecord(3, 9.0)});
  ExpectSame(*store.Evaluation(job, 3), MakePrunedRecord(3, 9.0));
}

TEST(ResultStore, APrunedEvaluationIsNeitherOkNorFailedNorBest) {
  const fs::path dir = testing::ScratchDir("store_pruned");
  ResultStore store(dir / "r.sqlite");
  const int64_t job = store.CreateJob("job", kSpec);
  const std::vector<EvaluationRecord> records = {MakeRecord(0, 5.0), MakeRecord(1, 0.0, false),
                                                 MakePrunedRecord(2, 1.0)};
  store.RecordEvaluations(job, records);
  const std::vector<EvaluationRecord> back = store.Evaluations(job);
  ASSERT_EQ(back.size(), 3u);
  ExpectSame(back[2], records[2]);
  EXPECT_EQ(std::string(back[2].status()), "pruned");
  EXPECT_EQ(store.Best(job)->id, 0) << "a pruned score is a lower bound, never the best";
  const JobSummary summary = store.Summary(job);
  EXPECT_EQ(summary.ok, 1);
  EXPECT_EQ(summary.failed, 1);
  EXPECT_EQ(summary.pruned, 1);
  EXPECT_CONTAINS(summary.Report(), "evaluations: 3 (1 ok, 1 failed, 1 pruned)");

  store.ExportCsv(job, dir / "e.csv");
  const Rows rows = ParseCsvFile(dir / "e.csv");
  ASSERT_EQ(rows.size(), 4u);
  const auto column = [&](const std::string& name) {
    return static_cast<size_t>(std::find(rows[0].begin(), rows[0].end(), name) - rows[0].begin());
  };
  ASSERT_LT(column("pruned_frame"), rows[0].size());
  EXPECT_EQ(rows[3][column("status")], "pruned");
  EXPECT_EQ(rows[3][column("score")], "1");
  EXPECT_EQ(rows[3][column("pruned_recording")], "1");
  EXPECT_EQ(rows[3][column("pruned_frame")], "41");
  EXPECT_EQ(rows[1][column("pruned_frame")], "-1");

  store.ExportJson(job, dir / "e.json");
  std::ifstream in(dir / "e.json");
  const nlohmann::json doc = nlohmann::json::parse(in);
  EXPECT_EQ(doc["summary"]["pruned"], 1);
  EXPECT_EQ(doc["summary"]["failed"], 1);
  EXPECT_EQ(doc["evaluations"][2]["status"], "pruned");
  EXPECT_EQ(doc["evaluations"][2]["pruned_recording"], 1);
  EXPECT_EQ(doc["evaluations"][2]["pruned_frame"], 41);
  EXPECT_FALSE(doc["evaluations"][1].contains("pruned_frame"));
}

TEST(ResultStore, DeleteJobRemovesEverythingOfItAndNothingElse) {
  const fs::path dir = testing::ScratchDir("store_delete");
  ResultStore store(dir / "r.sqlite");
  const int64_t gone = store.CreateJob("gone", kSpec);
  const int64_t kept = store.CreateJob("kept", kSpec);
  for (const int64_t job : {gone, kept}) {
    store.RecordEvaluations(job, std::vector<EvaluationRecord>{MakeRecord(0, 5.0)});
    CheckpointRecord cp;
    cp.evaluations_done = 1;
    cp.state = {{"k", 1}};
    store.SaveCheckpoint(job, cp);
    store.RecordJobRun(job, {1.0, "calib", "h", 1, "run"});
    store.SetJobInputs(job, std::vector<InputFingerprint>{{"rec/recording.json", 10, 7}});
  }
  store.DeleteJob(gone);
  EXPECT_FALSE(store.FindJob("gone").has_value());
  EXPECT_EQ(store.EvaluationCount(gone), 0);
  EXPECT_EQ(store.CheckpointCount(gone), 0);
  EXPECT_TRUE(store.JobRuns(gone).empty());
  EXPECT_TRUE(store.JobInputs(gone).empty());
  EXPECT_EQ(store.EvaluationCount(kept), 1);
  EXPECT_EQ(store.CheckpointCount(kept), 1);
  EXPECT_EQ(store.JobRuns(kept).size(), 1u);
  EXPECT_EQ(store.JobInputs(kept).size(), 1u);
  EXPECT_THROW(store.DeleteJob(gone), StoreError) << "an unknown id is named";
  const int64_t again = store.CreateJob("gone", kSpec);
  EXPECT_EQ(store.EvaluationCount(again), 0) << "the name is free again";
}

}  // namespace
}  // namespace calib
