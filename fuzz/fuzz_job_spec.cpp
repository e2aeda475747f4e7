// Fuzz target: the job spec reader (YAML or JSON text, ParseJobSpec, the
// reader behind LoadJobSpec). Expected: a JobSpec, or JobSpecError. A spec
// that parses must also come back from its canonical JSON (ToJson), as the
// results store keeps it for resume: a JobSpecError there is a finding too.

#include "calib/jobs/job_spec.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace calib;
  // Recordings are resolved, not opened: the recording reader has targets
  // of its own.
  JobSpecParseOptions options;
  options.recordings = RecordingCheck::kNone;
  const std::filesystem::path base = "/nonexistent/fuzz";
  JobSpec spec;
  try {
    spec = ParseJobSpec(fuzz::Text(data, size), "fuzz.yaml", base, options);
  } catch (const JobSpecError&) {
    return 0;
  } catch (...) {
    fuzz::Unexpected("fuzz_job_spec");
  }
  try {
    const nlohmann::json canonical = ToJson(spec);
    const JobSpec again = ParseJobSpec(canonical, "fuzz.yaml (canonical)", base, options);
    if (ToJson(again) != canonical) {
      std::fprintf(stderr, "fuzz_job_spec: the canonical JSON does not round-trip:\n%s\n%s\n",
                   canonical.dump().c_str(), ToJson(again).dump().c_str());
      std::abort();
    }
  } catch (...) {
    fuzz::Unexpected("fuzz_job_spec (canonical JSON)");
  }
  return 0;
}
