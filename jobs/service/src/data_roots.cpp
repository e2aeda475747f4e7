#include "calib/service/data_roots.h"

#include "calib/service/service_error.h"

#include <fmt/format.h>

namespace calib::service {
namespace {

namespace fs = std::filesystem;

// Whether `path` (links resolved) is `root` or below it.
bool Within(const fs::path& path, const fs::path& root) {
  const fs::path rel = path.lexically_relative(root);
  return !rel.empty() && *rel.begin() != ".." && !rel.is_absolute();
}

fs::path Resolved(const fs::path& path) {
  std::error_code ec;
  fs::path resolved = fs::weakly_canonical(path, ec);
  return ec ? path.lexically_normal() : resolved;
}

}  // namespace

void RequireInsideDataRoots(const fs::path& path, const std::vector<fs::path>& roots,
                            const std::string& field) {
  const fs::path resolved = Resolved(path);
  std::string listed;
  for (const fs::path& root : roots) {
    if (Within(resolved, Resolved(root))) return;
    listed += (listed.empty() ? "" : ", ") + root.string();
  }
  throw ServiceError(
      403, "spec",
      fmt::format("{} = '{}': outside the server's data roots ({}); recordings are read only "
                  "from there (paths relative to {}, no '..' out, no link out)",
                  field, path.string(), listed, roots.empty() ? "-" : roots.front().string()));
}

void RequireRecordingsInsideDataRoots(const std::vector<fs::path>& train,
                                      const std::vector<fs::path>& holdout,
                                      const std::vector<fs::path>& roots) {
  for (size_t i = 0; i < train.size(); ++i) {
    RequireInsideDataRoots(train[i], roots, fmt::format("train[{}]", i));
  }
  for (size_t i = 0; i < holdout.size(); ++i) {
    RequireInsideDataRoots(holdout[i], roots, fmt::format("holdout[{}]", i));
  }
}

fs::path PathInside(const fs::path& folder, const std::string& relative, const std::string& field) {
  const fs::path rel(relative);
  if (relative.empty() || rel.is_absolute()) {
    throw ServiceError(400, field,
                       fmt::format("{} = '{}': must be a relative path", field, relative));
  }
  for (const fs::path& part : rel) {
    if (part == "..") {
      throw ServiceError(400, field, fmt::format("{} = '{}': '..' is not allowed", field, relative));
    }
  }
  const fs::path path = folder / rel;
  if (!Within(Resolved(path), Resolved(folder))) {
    throw ServiceError(403, field,
                       fmt::format("{} = '{}': leads out of the job's folder", field, relative));
  }
  return path;
}

}  // namespace calib::service
