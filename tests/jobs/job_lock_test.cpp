// One process per job (job_lock.h) and the recordings a job started with
// (job_inputs.h), through RunJob with a cheap synthetic objective on a copy
// of a bundled recording:
//  - a second run or resume of a job held by a live process is refused,
//    naming the holder, and changes nothing of the job;
//  - a holder whose heartbeat stopped, or a process on this host that no
//    longer exists, is taken over;
//  - the heartbeat is renewed, and a holder taken over notices;
//  - a job left running is shown as interrupted once its holder stopped;
//  - resume refuses a recording whose files changed, naming each file;
//  - resume of a finished job writes its report again.

#include "calib/jobs/job_commands.h"
#include "calib/jobs/job_inputs.h"
#include "calib/jobs/job_lock.h"
#include "calib/jobs/job_report.h"
#include "jobs/job_test_support.h"
#include "support/process_support.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <functional>
#include <thread>

namespace calib {
namespace {

namespace fs = std::filesystem;

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "text: " << (text) << "\nmissing: " << (part)

// A synthetic job whose train recording is a copy of examples/push_centre
// in `dir` (read for its fingerprints only), its store dir/r.sqlite.
JobSpec LockJobSpec(const fs::path& dir) {
  fs::copy(fs::path(CALIB_SOURCE_DIR) / "examples" / "push_centre", dir / "rec",
           fs::copy_options::recursive);
  JobSpec spec = testing::SyntheticJobSpec("{name: random}", "budget: {evaluations: 8}", "locked");
  spec.base_dir = dir;
  spec.train = {dir / "rec"};
  spec.results.store = dir / "r.sqlite";
  spec.results.out_dir = dir / "out";
  return spec;
}

JobCommandOptions LockOptions() { return testing::SyntheticJobCommandOptions(); }

// The job created (status created, nothing run) and its id.
int64_t CreateJob(const JobSpec& spec) {
  ResultStore store(spec.results.store);
  return store.CreateJob(spec.name, ToJson(spec));
}

JobLock OtherProcess(int64_t pid, const std::string& host) {
  JobLock claim;
  claim.pid = pid;
  claim.host = host;
  claim.token = "other";
  return claim;
}

const JobLockTakeover kNever = [](const JobLock&, double) { return false; };

// The pid of a process of this host that has ended.
int64_t EndedProcessId() {
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  int status = 0;
  ::waitpid(child, &status, 0);
  return child;
}

// Whether `condition` holds within 10 s (a loaded machine may be slow to
// schedule the heartbeat thread).
bool Eventually(const std::function<bool()>& condition) {
  for (int i = 0; i < 1000; ++i) {
    if (condition()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return condition();
}

TEST(JobLock, ASecondRunOrResumeOfAHeldJobIsRefusedNamingTheHolder) {
  const fs::path dir = testing::ScratchDir("job_lock_held");
  const JobSpec spec = LockJobSpec(dir);
  const int64_t job = CreateJob(spec);
  ResultStore store(spec.results.store);
  const HeldJobLock held(store, job, spec.name);  // a live holder: this process
  for (const JobStart start : {JobStart::kRun, JobStart::kResume}) {
    try {
      RunJob(spec, start, LockOptions());
      ADD_FAILURE() << "a held job was run";
    } catch (const JobLockedError& e) {
      EXPECT_CONTAINS(e.what(), "job 'locked' is held by process " + std::to_string(::getpid()) +
                                    " on host '" + ThisHostName() + "'");
      EXPECT_CONTAINS(e.what(), "calib resume");
    }
  }
  EXPECT_EQ(store.Job(job).status, JobStatus::kCreated) << "the refused run marks nothing";
  EXPECT_EQ(store.EvaluationCount(job), 0);
  EXPECT_CONTAINS(JobStatusText(store, store.Job(job)), "created");
}

TEST(JobLock, ALiveHolderOnAnotherHostIsRefusedUntilItsHeartbeatIsStale) {
  const fs::path dir = testing::ScratchDir("job_lock_stale");
  const JobSpec spec = LockJobSpec(dir);
  const int64_t job = CreateJob(spec);
  ResultStore(spec.results.store).AcquireJobLock(job, OtherProcess(4242, "elsewhere"), kNever);
  JobCommandOptions options = LockOptions();
  try {
    RunJob(spec, JobStart::kRun, options);  // its heartbeat is fresh (60 s allowed)
    ADD_FAILURE() << "a job held on another host was run";
  } catch (const JobLockedError& e) {
    EXPECT_CONTAINS(e.what(), "held by process 4242 on host 'elsewhere'");
    EXPECT_CONTAINS(e.what(), "more than 60 s is taken over");
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  options.lock.heartbeat_s = 0.05;
  options.lock.stale_after_s = 0.3;  // now older than this
  const JobCommandResult result = RunJob(spec, JobStart::kRun, options);
  EXPECT_EQ(result.run.status, JobStatus::kFinished);
  EXPECT_FALSE(ResultStore(spec.results.store).JobLockHolder(job).has_value())
      << "released at the end";
}

TEST(JobLock, AnEndedProcessOnThisHostIsTakenOverAtOnce) {
  const fs::path dir = testing::ScratchDir("job_lock_killed");
  const JobSpec spec = LockJobSpec(dir);
  const int64_t job = CreateJob(spec);
  ResultStore store(spec.results.store);
  store.AcquireJobLock(job, OtherProcess(EndedProcessId(), ThisHostName()), kNever);
  store.SetJobStatus(job, JobStatus::kRunning);  // as a SIGKILL leaves it
  EXPECT_CONTAINS(JobStatusText(store, store.Job(job)), "interrupted (left running by process");
  EXPECT_CONTAINS(JobStatusText(store, store.Job(job)), "calib resume");
  const JobCommandResult result = RunJob(spec, JobStart::kResume, LockOptions());
  EXPECT_EQ(result.run.status, JobStatus::kFinished);
}

TEST(JobLock, TheHeartbeatIsRenewedAndATakenOverHolderNoticesItLostTheLock) {
  const fs::path dir = testing::ScratchDir("job_lock_heartbeat");
  const JobSpec spec = LockJobSpec(dir);
  const int64_t job = CreateJob(spec);
  ResultStore store(spec.results.store);
  JobLockOptions options;
  options.heartbeat_s = 0.02;
  options.stale_after_s = 10.0;
  const HeldJobLock held(store, job, spec.name, options);
  const double acquired = store.JobLockHolder(job)->acquired_unix_s;
  store.SetJobStatus(job, JobStatus::kRunning);
  EXPECT_TRUE(Eventually([&] { return store.JobLockHolder(job)->heartbeat_unix_s > acquired; }));
  EXPECT_CONTAINS(JobStatusText(store, store.Job(job)),
                  "running, by process " + std::to_string(::getpid()));
  EXPECT_FALSE(held.lost());
  store.AcquireJobLock(job, OtherProcess(4242, "elsewhere"),
                       [](const JobLock&, double) { return true; });
  EXPECT_TRUE(Eventually([&] { return held.lost(); }));
}

TEST(JobLock, AJobLeftRunningWithNoHolderIsShownInterrupted) {
  const fs::path dir = testing::ScratchDir("job_lock_status");
  const JobSpec spec = LockJobSpec(dir);
  const int64_t job = CreateJob(spec);
  ResultStore store(spec.results.store);
  store.SetJobStatus(job, JobStatus::kRunning);
  EXPECT_CONTAINS(JobStatusText(store, store.Job(job)), "interrupted (left running, and no process");
  EXPECT_CONTAINS(JobResultsText(store, job), "status: interrupted");
}

TEST(JobLock, BadOptionsAreNamed) {
  std::string error;
  JobLockOptions options;
  options.stale_after_s = options.heartbeat_s;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_CONTAINS(error, "JobLockOptions::stale_after_s");
  options = {};
  options.heartbeat_s = 0.0;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_CONTAINS(error, "JobLockOptions::heartbeat_s = 0");
}

// Runs the job to a stop (a wall time of nothing), then changes `file` of
// the recording with `change` and resumes: the message names the file.
void ExpectResumeRefusesAChangeTo(const std::string& label, const std::string& file,
                                  const std::function<void(const fs::path&)>& change,
                                  const std::string& message) {
  const fs::path dir = testing::ScratchDir("job_inputs_" + label);
  const JobSpec spec = LockJobSpec(dir);
  JobCommandOptions options = LockOptions();
  options.wall_time_s = 1e-9;
  ASSERT_EQ(RunJob(spec, JobStart::kRun, options).run.status, JobStatus::kStopped) << label;
  options.wall_time_s.reset();
  change(dir / "rec" / file);
  try {
    RunJob(spec, JobStart::kResume, options);
    ADD_FAILURE() << label << ": resumed on a changed recording";
  } catch (const std::invalid_argument& e) {
    EXPECT_CONTAINS(e.what(), "job 'locked': the recordings changed since the job started");
    EXPECT_CONTAINS(e.what(), message);
  }
  ResultStore store(spec.results.store);
  EXPECT_EQ(store.FindJob("locked")->status, JobStatus::kStopped) << label << ": left as it was";
}

TEST(JobInputs, ResumeRefusesAChangedTrackNamingIt) {
  ExpectResumeRefusesAChangeTo(
      "track", "track.csv",
      [](const fs::path& f) {
        std::string text = testing::ReadText(f);
        const size_t digit = text.find_first_of("123456789", text.find('\n'));
        text[digit] = text[digit] == '1' ? '2' : '1';  // the same size, another value
        std::ofstream(f, std::ios::binary) << text;
      },
      "rec/track.csv changed (same size, other content)");
}

TEST(JobInputs, ResumeRefusesAChangedRecordingJsonNamingIt) {
  ExpectResumeRefusesAChangeTo(
      "json", "recording.json",
      [](const fs::path& f) {
        std::string text = testing::ReadText(f);
        text.replace(text.find("Synthetic"), 9, "Different recording");
        std::ofstream(f, std::ios::binary) << text;
      },
      "rec/recording.json changed (");
}

TEST(JobInputs, ResumeRefusesAChangedVideoNamingIt) {
  ExpectResumeRefusesAChangeTo(
      "video", "video.mp4",
      [](const fs::path& f) { std::ofstream(f, std::ios::binary | std::ios::app) << '\0'; },
      "rec/video.mp4 changed (");
}

TEST(JobInputs, EveryVanishedOrNewFileIsNamed) {
  JobSpec spec = testing::SyntheticJobSpec("{name: random}");
  const std::vector<InputFingerprint> then = {{"a/track.csv", 10, 1}, {"a/video.mp4", 20, 2}};
  const std::vector<InputFingerprint> now = {{"a/track.csv", 11, 1}, {"a/frames/000.png", 5, 3}};
  try {
    CheckJobInputsUnchanged(spec, then, now);
    FAIL() << "changes accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_CONTAINS(e.what(), "a/track.csv changed (11 bytes, was 10)");
    EXPECT_CONTAINS(e.what(), "a/video.mp4 is no longer read");
    EXPECT_CONTAINS(e.what(), "a/frames/000.png is new");
  }
  EXPECT_NO_THROW(CheckJobInputsUnchanged(spec, then, then));
}

TEST(JobInputs, ResumeOfAnUnchangedJobGoesOn) {
  const fs::path dir = testing::ScratchDir("job_inputs_same");
  const JobSpec spec = LockJobSpec(dir);
  JobCommandOptions options = LockOptions();
  options.wall_time_s = 1e-9;
  ASSERT_EQ(RunJob(spec, JobStart::kRun, options).run.status, JobStatus::kStopped);
  EXPECT_FALSE(ResultStore(spec.results.store).JobInputs(1).empty());
  options.wall_time_s.reset();
  EXPECT_EQ(RunJob(spec, JobStart::kResume, options).run.status, JobStatus::kFinished);
}

TEST(JobCommands, ResumeOfAFinishedJobWritesItsReportAgain) {
  // A report folder that could not be written when the job finished (or was
  // deleted since) is had without running anything again.
  const fs::path dir = testing::ScratchDir("job_report_again");
  const JobSpec spec = LockJobSpec(dir);
  JobCommandOptions options = LockOptions();
  ASSERT_EQ(RunJob(spec, JobStart::kRun, options).run.status, JobStatus::kFinished);
  EXPECT_FALSE(fs::exists(spec.results.out_dir / "summary.txt"));
  options.write_report = true;
  options.report_simulations = false;
  const JobCommandResult again = RunJob(spec, JobStart::kResume, options);
  EXPECT_EQ(again.run.status, JobStatus::kCreated) << "nothing run";
  EXPECT_CONTAINS(again.run.stop_reason, "the job is already finished");
  ASSERT_TRUE(again.report.has_value());
  EXPECT_TRUE(fs::exists(spec.results.out_dir / "summary.txt"));
  EXPECT_TRUE(fs::exists(spec.results.out_dir / "evaluations.csv"));
}

}  // namespace
}  // namespace calib
