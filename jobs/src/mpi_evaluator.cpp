#include "calib/jobs/mpi_evaluator.h"

#include "calib/jobs/pruning.h"

#include <fmt/format.h>
#include <mpi.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <stdexcept>
#include <thread>
#include <type_traits>

namespace calib {
namespace {

enum Tag : int { kReady = 101, kWork = 102, kResult = 103, kStop = 104, kNextJob = 105 };

// Packed bytes: trivially copyable values and length-prefixed strings.
class Writer {
 public:
  template <class T>
  void Put(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto* p = reinterpret_cast<const char*>(&value);
    bytes_.insert(bytes_.end(), p, p + sizeof(T));
  }
  void PutString(const std::string& s) {
    Put<uint64_t>(s.size());
    bytes_.insert(bytes_.end(), s.begin(), s.end());
  }
  template <class T>
  void PutVector(const std::vector<T>& values) {
    static_assert(std::is_trivially_copyable_v<T>);
    Put<uint64_t>(values.size());
    const auto* p = reinterpret_cast<const char*>(values.data());
    bytes_.insert(bytes_.end(), p, p + values.size() * sizeof(T));
  }
  const std::vector<char>& bytes() const { return bytes_; }

 private:
  std::vector<char> bytes_;
};

class Reader {
 public:
  explicit Reader(const std::vector<char>& bytes) : bytes_(bytes) {}
  template <class T>
  T Get() {
    static_assert(std::is_trivially_copyable_v<T>);
    Need(sizeof(T));
    T value;
    std::memcpy(&value, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }
  std::string GetString() {
    const auto n = Get<uint64_t>();
    Need(n);
    std::string s(bytes_.data() + pos_, n);
    pos_ += n;
    return s;
  }
  template <class T>
  std::vector<T> GetVector() {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto n = Get<uint64_t>();
    if (n > bytes_.size()) Need(n);  // before n * sizeof(T) can overflow
    Need(n * sizeof(T));
    std::vector<T> values(n);
    // An empty vector's data() may be null, which memcpy may not be given.
    if (n > 0) std::memcpy(values.data(), bytes_.data() + pos_, n * sizeof(T));
    pos_ += n * sizeof(T);
    return values;
  }

 private:
  void Need(size_t n) const {
    if (n > bytes_.size() - pos_) throw std::runtime_error("MPI message is truncated");
  }
  const std::vector<char>& bytes_;
  size_t pos_ = 0;
};

void Send(const Writer& w, int dest, int tag) {
  MPI_Send(w.bytes().data(), static_cast<int>(w.bytes().size()), MPI_BYTE, dest, tag,
           MPI_COMM_WORLD);
}

// Receives the message `status` announced (from MPI_Probe / MPI_Iprobe).
std::vector<char> Receive(const MPI_Status& probed) {
  int count = 0;
  MPI_Get_count(&probed, MPI_BYTE, &count);
  std::vector<char> bytes(count);
  MPI_Recv(bytes.data(), count, MPI_BYTE, probed.MPI_SOURCE, probed.MPI_TAG, MPI_COMM_WORLD,
           MPI_STATUS_IGNORE);
  return bytes;
}

// Waits for a message without spinning a core (blocking MPI_Probe polls
// busily in OpenMPI, which would steal a core from the evaluations).
MPI_Status WaitFor(int source, int tag) {
  MPI_Status status;
  int flag = 0;
  auto pause = std::chrono::microseconds(50);
  while (true) {
    MPI_Iprobe(source, tag, MPI_COMM_WORLD, &flag, &status);
    if (flag) return status;
    std::this_thread::sleep_for(pause);
    pause = std::min(pause * 2, std::chrono::microseconds(2000));
  }
}

void PutResult(Writer& w, const FinishedCandidate& f) {
  const ObjectiveResult& r = f.result;
  w.Put<int64_t>(f.id);
  w.Put<int32_t>(f.attempts);
  w.PutString(f.worker);
  w.PutString(ToString(r.status));
  w.Put<double>(r.score);
  w.Put<double>(r.iou.mean);
  w.Put<double>(r.iou.min);
  w.Put<double>(r.iou.max);
  w.Put<int32_t>(r.iou.worst_recording);
  w.Put<int32_t>(r.iou.worst_frame);
  w.Put<int32_t>(r.iou.frames_scored);
  w.Put<int32_t>(r.iou.frames_total);
  w.PutString(r.reason);
  w.Put<int32_t>(r.failure_frame);
  w.Put<int32_t>(r.failure_recording);
  w.Put<double>(r.eval_seconds);
  w.PutVector(r.trace);
  w.PutVector(r.recording_frames);
}

FinishedCandidate GetResult(Reader& in) {
  FinishedCandidate f;
  ObjectiveResult& r = f.result;
  f.id = in.Get<int64_t>();
  f.attempts = in.Get<int32_t>();
  f.worker = in.GetString();
  r.status = CandidateStatusFromString(in.GetString());
  r.score = in.Get<double>();
  r.iou.mean = in.Get<double>();
  r.iou.min = in.Get<double>();
  r.iou.max = in.Get<double>();
  r.iou.worst_recording = in.Get<int32_t>();
  r.iou.worst_frame = in.Get<int32_t>();
  r.iou.frames_scored = in.Get<int32_t>();
  r.iou.frames_total = in.Get<int32_t>();
  r.reason = in.GetString();
  r.failure_frame = in.Get<int32_t>();
  r.failure_recording = in.Get<int32_t>();
  r.eval_seconds = in.Get<double>();
  r.trace = in.GetVector<double>();
  r.recording_frames = in.GetVector<int>();
  return f;
}

}  // namespace

bool LaunchedByMpi() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK", "PMI_RANK"}) {
    if (std::getenv(name) != nullptr) return true;
  }
  return false;
}

MpiSession::MpiSession(int* argc, char*** argv) {
  int provided = 0;
  MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

MpiSession::~MpiSession() { MPI_Finalize(); }

void MpiSession::Abort(int code) {
  MPI_Abort(MPI_COMM_WORLD, code);
  std::abort();  // MPI_Abort does not return
}

MpiBatchEvaluator::MpiBatchEvaluator(int size) : size_(size) {
  if (size_ < 2) {
    throw std::invalid_argument(
        fmt::format("MPI manager needs at least one worker rank; world size = {}", size_));
  }
}

MpiBatchEvaluator::~MpiBatchEvaluator() { StopWorkers(); }

std::string MpiBatchEvaluator::Describe() const {
  return fmt::format("MPI: manager and {} worker rank{}", size_ - 1, size_ == 2 ? "" : "s");
}

void MpiBatchEvaluator::WaitForWorkers() {
  std::string errors;
  for (int i = 1; i < size_; ++i) {
    const MPI_Status status = WaitFor(MPI_ANY_SOURCE, kReady);
    const std::vector<char> bytes = Receive(status);
    Reader in(bytes);
    const int32_t code = in.Get<int32_t>();
    const std::string message = in.GetString();
    if (code != 0) errors += fmt::format("\n  rank {}: {}", status.MPI_SOURCE, message);
  }
  if (!errors.empty()) throw std::runtime_error("MPI workers could not start:" + errors);
}

void MpiBatchEvaluator::StopWorkers() {
  if (stopped_) return;
  stopped_ = true;
  const Writer empty;
  for (int rank = 1; rank < size_; ++rank) Send(empty, rank, kStop);
}

void MpiBatchEvaluator::Evaluate(
    std::span<const PendingCandidate> batch, int max_attempts, const PruneBounds* prune,
    const std::function<bool()>& should_stop,
    const std::function<void(std::vector<FinishedCandidate>&&)>& on_done, double tick_s) {
  if (stopped_) throw std::logic_error("MPI workers were already stopped");
  std::deque<int> idle;
  for (int rank = 1; rank < size_; ++rank) idle.push_back(rank);
  size_t next = 0;
  int running = 0;
  bool stop = false;
  using Clock = std::chrono::steady_clock;
  auto last_report = Clock::now();
  auto pause = std::chrono::microseconds(50);
  while (true) {
    if (!stop && should_stop()) stop = true;
    // Starts in batch order, none after a stop: what finishes is a prefix.
    while (!stop && next < batch.size() && !idle.empty()) {
      const PendingCandidate& c = batch[next++];
      const EarlyStop stop = prune ? prune->StartFor(c.id) : EarlyStop{};
      Writer w;
      w.Put<int64_t>(c.id);
      w.Put<int32_t>(max_attempts);
      w.Put<double>(stop.stop_above);
      w.Put<uint8_t>(stop.trace ? 1 : 0);
      w.Put<uint64_t>(c.values.size());
      for (const auto& [name, value] : c.values) {
        w.PutString(name);
        w.Put<double>(value);
      }
      Send(w, idle.front(), kWork);
      idle.pop_front();
      ++running;
    }
    if (running == 0) break;
    MPI_Status status;
    int flag = 0;
    MPI_Iprobe(MPI_ANY_SOURCE, kResult, MPI_COMM_WORLD, &flag, &status);
    if (flag) {
      const std::vector<char> bytes = Receive(status);
      Reader in(bytes);
      std::vector<FinishedCandidate> done;
      done.push_back(GetResult(in));
      --running;
      idle.push_back(status.MPI_SOURCE);
      on_done(std::move(done));
      last_report = Clock::now();
      pause = std::chrono::microseconds(50);
    } else {
      if (std::chrono::duration<double>(Clock::now() - last_report).count() >= tick_s) {
        on_done({});
        last_report = Clock::now();
      }
      std::this_thread::sleep_for(pause);
      pause = std::min(pause * 2, std::chrono::microseconds(1000));
    }
  }
}

int64_t RunMpiWorker(const std::function<std::unique_ptr<Objective>()>& make_objective,
                     int rank) {
  std::unique_ptr<Objective> objective;
  std::unique_ptr<ObjectiveWorker> worker;
  {
    Writer ready;
    try {
      objective = make_objective();
      worker = objective->MakeWorker();
      ready.Put<int32_t>(0);
      ready.PutString("");
    } catch (const std::exception& e) {
      ready.Put<int32_t>(1);
      ready.PutString(e.what());
    }
    Send(ready, 0, kReady);
  }
  const std::string label = fmt::format("rank {}", rank);
  int64_t evaluated = 0;
  while (true) {
    const MPI_Status status = WaitFor(0, MPI_ANY_TAG);
    const std::vector<char> bytes = Receive(status);
    if (status.MPI_TAG == kStop) break;
    if (status.MPI_TAG != kWork || !worker) continue;
    Reader in(bytes);
    PendingCandidate candidate;
    candidate.id = in.Get<int64_t>();
    const int32_t max_attempts = in.Get<int32_t>();
    EarlyStop stop;
    stop.stop_above = in.Get<double>();
    stop.trace = in.Get<uint8_t>() != 0;
    const auto n = in.Get<uint64_t>();
    for (uint64_t i = 0; i < n; ++i) {
      std::string name = in.GetString();
      candidate.values[name] = in.Get<double>();
    }
    const FinishedCandidate done =
        EvaluateWithRetries(*worker, candidate, stop, max_attempts, label);
    Writer w;
    PutResult(w, done);
    Send(w, 0, kResult);
    ++evaluated;
  }
  return evaluated;
}

void SendNextJob(int size, int32_t index) {
  for (int rank = 1; rank < size; ++rank) {
    MPI_Send(&index, 1, MPI_INT32_T, rank, kNextJob, MPI_COMM_WORLD);
  }
}

int32_t ReceiveNextJob() {
  (void)WaitFor(0, kNextJob);
  int32_t index = -1;
  MPI_Recv(&index, 1, MPI_INT32_T, 0, kNextJob, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
  return index;
}

}  // namespace calib
