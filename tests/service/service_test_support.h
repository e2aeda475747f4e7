#pragma once
// The service's tests (tests/service/): `calib serve` in a child process on
// an ephemeral loopback port with an HTTP client holding its token, and the
// histories of a store's jobs.

#include "calib/results/store.h"
#include "support/process_support.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

namespace calib::testing {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "text: " << (text) << "\nmissing: " << (part)

inline const std::string kCalib = CALIB_EXE;
inline const fs::path kExamples = fs::path(CALIB_SOURCE_DIR) / "examples";

inline std::vector<EvaluationRecord> History(const fs::path& db, const std::string& name) {
  StoreOptions options;
  options.read_only = true;
  ResultStore store(db, options);
  const std::optional<JobInfo> job = store.FindJob(name);
  if (!job) return {};
  return store.Evaluations(job->id);
}

inline std::vector<EvaluationRecord> Prefix(std::vector<EvaluationRecord> history, size_t n) {
  history.resize(std::min(n, history.size()));
  return history;
}

// `calib serve` in a child process, and an HTTP client with its token.
class Server {
 public:
  Server(const fs::path& state, const fs::path& logs, std::vector<std::string> extra = {})
      : state_(state) {
    fs::create_directories(logs);
    fs::remove(state / "port");
    std::vector<std::string> argv = {kCalib,        "serve",        "--port",
                                     "0",           "--port-file",  (state / "port").string(),
                                     "--state-dir", state.string(), "--data-root",
                                     kExamples.string(), "--jobs", "2", "--threads-per-job", "1",
                                     "--no-video"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    process_ = std::make_unique<ChildProcess>(argv, logs);
    const auto deadline = Clock::now() + std::chrono::seconds(60);
    while (!fs::exists(state / "port")) {
      if (process_->Exited() || Clock::now() > deadline) {
        ADD_FAILURE() << "the server did not start: " << process_->Wait(1).err;
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    std::ifstream(state / "port") >> port_;
    std::ifstream(state / "token") >> token_;
  }

  int port() const { return port_; }
  const std::string& token() const { return token_; }
  std::string url() const { return fmt::format("http://127.0.0.1:{}", port_); }
  ChildProcess& process() { return *process_; }
  fs::path store() const { return state_ / "service.sqlite"; }
  /// `calib ARGS... --server URL --token-file TOKEN`: a command-line client
  /// (submit, status, cancel, jobs) of this server, run to its end.
  ProcessResult RunClient(const std::vector<std::string>& args, const fs::path& log_dir) const {
    std::vector<std::string> argv = {kCalib};
    argv.insert(argv.end(), args.begin(), args.end());
    argv.insert(argv.end(), {"--server", url(), "--token-file", (state_ / "token").string()});
    return RunProcess(argv, log_dir);
  }
  /// A job's report folder, or a loop's or a comparison's own folder.
  fs::path folder(const std::string& name) const { return state_ / "jobs" / name; }

  httplib::Client Client(const std::string& token) const {
    httplib::Client client("127.0.0.1", port_);
    if (!token.empty()) client.set_bearer_token_auth(token.c_str());
    client.set_read_timeout(60);
    return client;
  }
  httplib::Client Client() const { return Client(token_); }

  nlohmann::json Get(const std::string& path) const {
    httplib::Client client = Client();
    const httplib::Result r = client.Get(path.c_str());
    if (!r) {
      ADD_FAILURE() << "GET " << path << ": " << httplib::to_string(r.error());
      return nullptr;
    }
    EXPECT_EQ(r->status, 200) << "GET " << path << ": " << r->body;
    return nlohmann::json::parse(r->body, nullptr, false);
  }

  nlohmann::json Submit(const std::string& yaml, int priority = 0) const {
    return Submit("job", yaml, priority);
  }

  // A spec of a kind ("job", "loop", "comparison"): YAML text or a JSON
  // object; the answer of a 201.
  nlohmann::json Submit(const std::string& kind, const nlohmann::json& spec, int priority = 0) const {
    httplib::Client client = Client();
    const nlohmann::json body = {{"kind", kind}, {"spec", spec}, {"priority", priority}};
    const httplib::Result r = client.Post("/api/v1/jobs", body.dump(), "application/json");
    if (!r) {
      ADD_FAILURE() << "POST /api/v1/jobs: " << httplib::to_string(r.error());
      return nullptr;
    }
    EXPECT_EQ(r->status, 201) << r->body;
    return nlohmann::json::parse(r->body, nullptr, false);
  }

  // Waits until the job's queue state is done (or cancelled); its status.
  nlohmann::json WaitDone(const std::string& name, double timeout_s = 120) const {
    const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
    while (Clock::now() < deadline) {
      const nlohmann::json job = Get("/api/v1/jobs/" + name);
      if (job.is_null() || job.is_discarded()) return job;
      if (job["state"] == "done" || job["state"] == "cancelled") return job;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    ADD_FAILURE() << name << ": not done after " << timeout_s << " s";
    return nullptr;
  }

  // Waits until the job has recorded at least `n` evaluations.
  void WaitEvaluations(const std::string& name, size_t n) const {
    const auto deadline = Clock::now() + std::chrono::seconds(120);
    while (Clock::now() < deadline) {
      try {
        if (History(store(), name).size() >= n) return;
      } catch (const StoreError&) {
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    ADD_FAILURE() << name << ": fewer than " << n << " evaluations after 120 s";
  }

 private:
  fs::path state_;
  std::unique_ptr<ChildProcess> process_;
  int port_ = 0;
  std::string token_;
};

}  // namespace calib::testing
