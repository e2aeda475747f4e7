#pragma once
// The files a job reads, fingerprinted, so that `calib resume` refuses a
// data set changed under the job instead of mixing the scores of two data
// sets in one history. The spec itself is compared as canonical JSON
// (job_commands.h): its file may change where the history cannot.

#include "calib/jobs/job_spec.h"
#include "calib/results/store.h"

#include <vector>

namespace calib {

/// Every file the job's train and holdout recordings are read from:
/// recording.json, the track, the video (every image of an image sequence),
/// each with its size and FNV-1a 64 of its bytes. Paths relative to
/// spec.base_dir where they lie below it, absolute otherwise; sorted.
/// Throws JobSpecError naming the recording when it cannot be read
/// (CheckRecordings).
std::vector<InputFingerprint> FingerprintJobInputs(const JobSpec& spec);

/// Throws std::invalid_argument naming every file that changed, vanished or
/// appeared between `recorded` (when the job started) and `now`.
void CheckJobInputsUnchanged(const JobSpec& spec, const std::vector<InputFingerprint>& recorded,
                             const std::vector<InputFingerprint>& now);

}  // namespace calib
