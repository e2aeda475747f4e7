// The service's job queue in the results store: priority then submission
// order, one entry per name, state changes, and what a restart finds.

#include "calib/results/job_queue.h"
#include "calib/results/store.h"
#include "support/sqlite_support.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

namespace calib {
namespace {

namespace fs = std::filesystem;

const nlohmann::json kQueuedSpec = {{"name", "x"}};

TEST(JobQueue, HandsOutByPriorityThenSubmissionOrder) {
  const fs::path dir = testing::ScratchDir("queue_order");
  JobQueue queue(dir / "s.sqlite");
  const int64_t a = queue.Add("a", QueueKind::kJob, kQueuedSpec, 0, false);
  const int64_t b = queue.Add("b", QueueKind::kJob, kQueuedSpec, 5, false);
  const int64_t c = queue.Add("c", QueueKind::kJob, kQueuedSpec, 0, true);
  const int64_t d = queue.Add("d", QueueKind::kJob, kQueuedSpec, 5, false);
  std::vector<int64_t> order;
  while (const std::optional<QueueEntry> e = queue.ClaimNext()) {
    EXPECT_EQ(e->state, QueueState::kRunning);
    order.push_back(e->id);
  }
  EXPECT_EQ(order, (std::vector<int64_t>{b, d, a, c}));
  EXPECT_TRUE(queue.Find("c")->resume);
  EXPECT_FALSE(queue.Find("a")->resume);
  EXPECT_EQ(queue.Find("a")->state, QueueState::kRunning) << "claimed entries are running";
}

TEST(JobQueue, ANameIsQueuedOnce) {
  const fs::path dir = testing::ScratchDir("queue_names");
  JobQueue queue(dir / "s.sqlite");
  queue.Add("a", QueueKind::kJob, kQueuedSpec, 0, false);
  try {
    queue.Add("a", QueueKind::kJob, kQueuedSpec, 1, false);
    ADD_FAILURE() << "a second entry of one name was queued";
  } catch (const StoreError& e) {
    EXPECT_NE(std::string(e.what()).find("queue job 'a': a job of that name is in the queue"),
              std::string::npos)
        << e.what();
  }
}

TEST(JobQueue, OutlivesTheProcessAndRequeuesWhatWasRunning) {
  const fs::path dir = testing::ScratchDir("queue_restart");
  int64_t running = 0, done = 0, queued = 0;
  {
    JobQueue queue(dir / "s.sqlite");
    running = queue.Add("running", QueueKind::kJob, kQueuedSpec, 9, false);
    done = queue.Add("done", QueueKind::kJob, kQueuedSpec, 8, false);
    queued = queue.Add("queued", QueueKind::kJob, {{"name", "queued"}, {"seed", 3}}, 0, false);
    ASSERT_EQ(queue.ClaimNext()->id, running);
    ASSERT_EQ(queue.ClaimNext()->id, done);
    queue.Set(done, QueueState::kDone, "finished", false);
  }
  JobQueue queue(dir / "s.sqlite");  // as a restarted server does
  EXPECT_EQ(queue.RequeueRunning(), 1);
  const std::optional<QueueEntry> first = queue.ClaimNext();
  ASSERT_TRUE(first.has_value());
  EXPECT_EQ(first->id, running);
  EXPECT_TRUE(first->resume) << "a job left running resumes from its checkpoint";
  EXPECT_EQ(queue.ClaimNext()->id, queued);
  EXPECT_FALSE(queue.ClaimNext().has_value()) << "a done entry is not handed out again";
  EXPECT_EQ(queue.Find("done")->message, "finished");
  EXPECT_EQ(queue.Find("queued")->spec["seed"], 3);
  queue.Remove(done);
  EXPECT_FALSE(queue.Find("done").has_value());
  EXPECT_EQ(queue.Entries().size(), 2u);
  EXPECT_EQ(ResultStore(dir / "s.sqlite").SchemaVersion(),
            ResultStore(dir / "fresh.sqlite").SchemaVersion())
      << "the queue lives in a results store of the current schema";
}

TEST(JobQueue, KeepsEachEntrysKindAndReadsAVersion4QueueAsJobs) {
  const fs::path dir = testing::ScratchDir("queue_kinds");
  {
    JobQueue queue(dir / "s.sqlite");
    queue.Add("loop", QueueKind::kLoop, kQueuedSpec, 0, false);
    queue.Add("comparison", QueueKind::kComparison, kQueuedSpec, 0, false);
    EXPECT_EQ(queue.Find("loop")->kind, QueueKind::kLoop);
    EXPECT_EQ(queue.ClaimNext()->kind, QueueKind::kLoop);
    EXPECT_EQ(queue.Find("comparison")->kind, QueueKind::kComparison);
  }
  for (const QueueKind kind : {QueueKind::kJob, QueueKind::kLoop, QueueKind::kComparison}) {
    EXPECT_EQ(QueueKindFromString(ToString(kind)), kind);
  }
  try {
    (void)QueueKindFromString("batch");
    ADD_FAILURE() << "an unknown kind was read";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("batch"), std::string::npos) << e.what();
  }
  // What a version 4 build wrote: a queue without kinds, whose entries are
  // jobs.
  {
    JobQueue queue(dir / "v4.sqlite");
    queue.Add("old", QueueKind::kJob, kQueuedSpec, 0, false);
  }
  testing::RawSql(dir / "v4.sqlite",
                  "ALTER TABLE job_queue DROP COLUMN kind; PRAGMA user_version=4;");
  JobQueue queue(dir / "v4.sqlite");
  EXPECT_EQ(queue.Find("old")->kind, QueueKind::kJob);
  EXPECT_EQ(ResultStore(dir / "v4.sqlite").SchemaVersion(), ResultStore(dir / "fresh.sqlite").SchemaVersion());
}

}  // namespace
}  // namespace calib
