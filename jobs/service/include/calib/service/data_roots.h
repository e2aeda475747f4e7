#pragma once
// Recordings a submitted job may read: those inside the server's data roots.
// A path is inside a root when, with every symbolic link resolved, it lies
// in the root's folder (itself with its links resolved): a `..` that climbs
// out, a link that points out or an absolute path elsewhere is refused.

#include <filesystem>
#include <string>
#include <vector>

namespace calib::service {

/// Throws ServiceError (403, field `field`) naming the path and the roots
/// when `path` (absolute) lies outside every root.
void RequireInsideDataRoots(const std::filesystem::path& path,
                            const std::vector<std::filesystem::path>& roots,
                            const std::string& field);

/// RequireInsideDataRoots for every recording of a spec, named `train[i]`
/// and `holdout[i]`.
void RequireRecordingsInsideDataRoots(const std::vector<std::filesystem::path>& train,
                                      const std::vector<std::filesystem::path>& holdout,
                                      const std::vector<std::filesystem::path>& roots);

/// `relative` (a request's path below `folder`) as a path in `folder`:
/// ServiceError 400 for an absolute path or a `..` component, 403 for one
/// that leaves `folder` through a link.
std::filesystem::path PathInside(const std::filesystem::path& folder, const std::string& relative,
                                 const std::string& field);

}  // namespace calib::service
