// Fuzz target: recording.json (ParseRecordingJson, the reader LoadRecording
// uses; docs/recording.md). The recording is taken to have a 64 x 48 video
// of 3 frames in a folder of its own, so the roi and clamp checks run too.
// Expected: a filled Recording, or RecordingError.

#include "calib/evaluator/recording.h"
#include "fuzz_support.h"

#include <cstdio>
#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace calib;
  static const std::filesystem::path folder = [] {
    const std::filesystem::path f = fuzz::TempDir() / "recording";
    std::filesystem::create_directories(f);
    return f;
  }();
  Recording rec;
  rec.folder = folder;
  rec.frame_width = 64;
  rec.frame_height = 48;
  rec.num_frames = 3;
  try {
    ParseRecordingJson(fuzz::Text(data, size), folder / "recording.json", &rec);
  } catch (const RecordingError&) {
    return 0;
  } catch (...) {
    fuzz::Unexpected("fuzz_recording_json");
  }
  // What the rest of the program relies on once the reader accepted it.
  const PixelRect& r = rec.roi;
  const bool roi_ok = r.width > 0 && r.height > 0 && r.x >= 0 && r.y >= 0 &&
                      r.x + r.width <= rec.frame_width && r.y + r.height <= rec.frame_height;
  if (!roi_ok || !(rec.fps > 0.0) || rec.video_path.empty() || rec.track_path.empty()) {
    std::fprintf(stderr, "fuzz_recording_json: accepted an unusable recording.json\n");
    std::abort();
  }
  return 0;
}
