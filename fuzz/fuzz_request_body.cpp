// Fuzz target: the bodies of the service's requests (calib serve). The
// bytes are read as the HTTP layer reads a body (nlohmann::json::parse;
// what does not parse is answered 400 there), then handed to the
// operations that take a body, in-process:
//  - JobService::Submit, POST /api/v1/jobs ({"spec": object or YAML text,
//    "priority": integer}): the spec parsed and checked, its recordings
//    looked for inside the data root and read. A submission it accepts is
//    then deleted, so that every input meets the same queue;
//  - JobService::ExtendBudget, POST /api/v1/jobs/NAME/budget
//    ({"evaluations": N}), on a cancelled job made at start-up; a budget it
//    accepts queues that job again, and it is cancelled at once.
// Expected: ServiceError (the service's answer to a request it refuses).
// Anything else thrown is a finding.
//
// The data root is the repository's examples/ folder, so a spec naming
// push_centre is accepted. The service's workers are stopped before the
// first input: accepted jobs are queued, never run.

#include "calib/service/job_service.h"
#include "calib/service/service_error.h"
#include "fuzz_support.h"

#include <nlohmann/json.hpp>

#include <memory>
#include <string>

namespace {

using calib::service::JobService;
using calib::service::ServiceError;

// The job ExtendBudget works on: a valid submission, cancelled.
constexpr const char* kStoppedJob = "fuzz_stopped";

JobService& Service() {
  static std::unique_ptr<JobService> service = [] {
    calib::service::ServiceOptions options;
    options.data_roots = {std::filesystem::path(CALIB_SOURCE_DIR) / "examples"};
    options.state_dir = calib::fuzz::TempDir() / "service";
    options.write_report = false;
    auto made = std::make_unique<JobService>(options);
    made->Stop();
    // The base model's parameters, as examples/jobs/push_centre_cmaes.yaml.
    const nlohmann::json submission = {
        {"spec",
         {{"name", kStoppedJob},
          {"train", {"push_centre"}},
          {"parameters",
           {{{"name", "k_D"}, {"lower", 10}, {"upper", 5000}, {"scale", "log"}},
            {{"name", "k_d"}, {"lower", 0.01}, {"upper", 50}, {"scale", "log"}},
            {{"name", "k_A"}, {"lower", 1}, {"upper", 5000}, {"scale", "log"}},
            {{"name", "k_phi"}, {"lower", 0.1}, {"upper", 1000}, {"scale", "log"}},
            {{"name", "mass"}, {"fixed", 0.2}},
            {{"name", "tau"}, {"lower", 0}, {"upper", 0.5}}}},
          {"optimizer", {{"name", "random"}}},
          {"budget", {{"evaluations", 8}}}}}};
    made->Submit(submission);
    made->Cancel(kStoppedJob);
    return made;
  }();
  return *service;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  JobService& service = Service();
  nlohmann::json body;
  try {
    body = nlohmann::json::parse(calib::fuzz::Text(data, size));
  } catch (const nlohmann::json::exception&) {
    return 0;  // HttpApi answers 400: "the body is not JSON"
  }
  try {
    const nlohmann::json accepted = service.Submit(body);
    service.Delete(accepted.at("name").get<std::string>());
  } catch (const ServiceError&) {
  } catch (...) {
    calib::fuzz::Unexpected("fuzz_request_body (submit)");
  }
  try {
    service.ExtendBudget(kStoppedJob, body);
    service.Cancel(kStoppedJob);
  } catch (const ServiceError&) {
  } catch (...) {
    calib::fuzz::Unexpected("fuzz_request_body (budget)");
  }
  return 0;
}
