// Fuzz target: track.csv (ParseTrackCsv, the reader LoadRecording uses;
// docs/recording.md). The first byte says what recording.json and the video
// said: bits 0-3 the frame count - 1 (1..16 frames of 64 x 48), bit 4
// force_obstacle = "pusher". The rest is the file. Expected: the obstacle
// tracks (and forces), or RecordingError.

#include "calib/evaluator/recording.h"
#include "fuzz_support.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace calib;
  if (size < 1) return 0;
  Recording rec;
  rec.folder = "/nonexistent/fuzz";
  rec.video_path = rec.folder / "video.mp4";
  rec.track_path = rec.folder / "track.csv";
  rec.frame_width = 64;
  rec.frame_height = 48;
  rec.num_frames = 1 + (data[0] & 15);
  if (data[0] & 16) rec.force_obstacle = "pusher";
  try {
    ParseTrackCsv(fuzz::Text(data + 1, size - 1), rec.track_path, &rec);
  } catch (const RecordingError&) {
    return 0;
  } catch (...) {
    fuzz::Unexpected("fuzz_track_csv");
  }
  // What the simulator relies on once the reader accepted it.
  bool ok = !rec.force_obstacle || static_cast<int>(rec.forces.size()) == rec.num_frames;
  for (const ObstacleTrack& o : rec.obstacles) {
    ok = ok && static_cast<int>(o.discs.size()) == rec.num_frames;
    for (const Disc& d : o.discs) {
      ok = ok && std::isfinite(d.centre.x()) && std::isfinite(d.centre.y()) &&
           std::isfinite(d.radius_px) && d.radius_px >= 0.0;
    }
  }
  for (const Vec2& f : rec.forces) ok = ok && std::isfinite(f.x()) && std::isfinite(f.y());
  if (!ok) {
    std::fprintf(stderr, "fuzz_track_csv: accepted an unusable track\n");
    std::abort();
  }
  return 0;
}
