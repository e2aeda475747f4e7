#include "calib/jobs/job_inputs.h"

#include "calib/evaluator/recording.h"
#include "calib/evaluator/segmentation.h"
#include "calib/evaluator/segmentation_cache.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <map>
#include <stdexcept>

namespace calib {
namespace {

namespace fs = std::filesystem;

InputFingerprint Fingerprint(const JobSpec& spec, const fs::path& file) {
  InputFingerprint out;
  const fs::path relative = file.lexically_relative(spec.base_dir);
  const bool below = !relative.empty() && *relative.begin() != "..";
  out.path = (below ? relative : file).generic_string();
  out.size_bytes = static_cast<int64_t>(fs::file_size(file));
  out.fnv1a64 = HashFileContent(file);
  return out;
}

}  // namespace

std::vector<InputFingerprint> FingerprintJobInputs(const JobSpec& spec) {
  CheckRecordings(spec);  // a recording that cannot be read is named by its field
  std::map<std::string, InputFingerprint> by_path;  // a recording may be listed twice
  for (const auto* folders : {&spec.train, &spec.holdout}) {
    for (const fs::path& folder : *folders) {
      const Recording rec = LoadRecording(folder);
      std::vector<fs::path> files = {rec.folder / "recording.json", rec.track_path};
      for (const fs::path& f : VideoFiles(rec.video_path)) files.push_back(f);
      for (const fs::path& f : files) {
        InputFingerprint fp = Fingerprint(spec, f.lexically_normal());
        by_path[fp.path] = std::move(fp);
      }
    }
  }
  std::vector<InputFingerprint> out;
  out.reserve(by_path.size());
  for (auto& [path, fp] : by_path) out.push_back(std::move(fp));
  return out;
}

void CheckJobInputsUnchanged(const JobSpec& spec, const std::vector<InputFingerprint>& recorded,
                             const std::vector<InputFingerprint>& now) {
  std::map<std::string, const InputFingerprint*> current;
  for (const InputFingerprint& fp : now) current[fp.path] = &fp;
  std::vector<std::string> changes;
  for (const InputFingerprint& was : recorded) {
    const auto it = current.find(was.path);
    if (it == current.end()) {
      changes.push_back(fmt::format("{} is no longer read (gone, or the recording names another "
                                    "file)",
                                    was.path));
      continue;
    }
    const InputFingerprint& is = *it->second;
    if (is.size_bytes != was.size_bytes) {
      changes.push_back(
          fmt::format("{} changed ({} bytes, was {})", was.path, is.size_bytes, was.size_bytes));
    } else if (is.fnv1a64 != was.fnv1a64) {
      changes.push_back(fmt::format("{} changed (same size, other content)", was.path));
    }
    current.erase(it);
  }
  for (const auto& [path, fp] : current) changes.push_back(fmt::format("{} is new", path));
  if (changes.empty()) return;
  throw std::invalid_argument(fmt::format(
      "{}: job '{}': the recordings changed since the job started: {}. A resumed job must see the "
      "data set it started with; restore it, or start a new job (another name or store)",
      spec.source, spec.name, fmt::join(changes, "; ")));
}

}  // namespace calib
