#pragma once
// A recording in the format of shared/spec/dataset.md ("sponge-recording/1"):
// recording.json, a video (file or image-sequence pattern) and track.csv.

#include "calib/core/types.h"

#include <array>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace calib {

/// Thrown for a malformed recording; what() names the file and the key, row,
/// column or value at fault.
class RecordingError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Inclusive HSV range, OpenCV convention (H 0..179, S and V 0..255).
struct HsvRange {
  std::array<int, 3> lower{0, 0, 0};
  std::array<int, 3> upper{179, 255, 255};
};

/// An integer pixel rectangle [x, x + width) x [y, y + height).
struct PixelRect {
  int x = 0;
  int y = 0;
  int width = 0;
  int height = 0;
};

/// The track of one obstacle: a rigid disc per frame.
struct ObstacleTrack {
  std::string name;
  std::vector<Disc> discs;  ///< one per frame
};

struct Recording {
  std::filesystem::path folder;
  std::filesystem::path video_path;   ///< resolved against folder
  std::filesystem::path track_path;   ///< resolved against folder
  double fps = 0.0;
  std::optional<double> mm_per_px;
  HsvRange object_hsv;
  std::optional<std::string> force_obstacle;
  PixelRect roi;                      ///< the whole frame when absent in the file
  std::vector<PixelRect> clamps;
  std::string notes;

  int frame_width = 0;                ///< from the video
  int frame_height = 0;
  int num_frames = 0;                 ///< video frames == track rows

  std::vector<ObstacleTrack> obstacles;  ///< in the column order of track.csv
  /// Force on the object by force_obstacle, newtons, image axes; one per frame
  /// when force_obstacle is set, empty otherwise.
  std::vector<Vec2> forces;

  /// Index into obstacles of force_obstacle, or -1.
  int ForceObstacleIndex() const;
};

/// Reads and validates a recording folder. Opens the video to count its
/// frames and read the frame size (it does not decode every frame). Throws
/// RecordingError naming the file and key / row / column on any malformed
/// input: missing required key, wrong type, missing or unreadable file, bad
/// or non-finite number, row-count mismatch (naming both counts), missing
/// force columns when force_obstacle is set, a force_obstacle that names no
/// obstacle, a roi or clamp outside the frame.
Recording LoadRecording(const std::filesystem::path& folder);

/// LoadRecording's reading of recording.json, on its text in memory (tests,
/// the fuzz targets in fuzz/). rec->folder must be set (the video and track
/// paths are resolved and must stay inside it) and so must the frame size
/// (the roi and clamps are checked against it; the roi defaults to the whole
/// frame). `file` names the text in messages. Throws RecordingError as
/// LoadRecording does.
void ParseRecordingJson(std::string_view text, const std::filesystem::path& file, Recording* rec);

/// LoadRecording's reading of track.csv, on its text in memory: fills
/// rec->obstacles and rec->forces. rec's num_frames, frame size,
/// force_obstacle and video_path (named in messages) must be set. Throws
/// RecordingError as LoadRecording does.
void ParseTrackCsv(std::string_view text, const std::filesystem::path& file, Recording* rec);

/// The name a recording goes by in reports, logs and output folders: the
/// name of its folder, whichever way the folder is written ("push_centre" for
/// examples/push_centre, examples/push_centre/ or /data/push_centre/.); the
/// path as given when it names no folder ("/"). Pass Recording::folder or a
/// folder as a job spec lists it.
std::string RecordingDisplayName(const std::filesystem::path& folder);

}  // namespace calib
