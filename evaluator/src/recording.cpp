#include "calib/evaluator/recording.h"

#include "calib/evaluator/media.h"

#include <csv.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string_view>
#include <system_error>

namespace calib {
namespace {

// The largest frame rate a recording may state (high-speed cameras reach
// 1e4-1e5 fps).
constexpr double kMaxFps = 1e6;
// How far from the frame, in frame sizes, an obstacle coordinate or radius
// may lie.
constexpr double kMaxObstacleReachFrames = 100.0;
// The largest track.csv read (a row per frame: hours of video are a few MB).
constexpr uintmax_t kMaxTrackBytes = 256u << 20;

using nlohmann::json;
namespace fs = std::filesystem;

constexpr const char* kFormat = "sponge-recording/1";

[[noreturn]] void Fail(const fs::path& file, const std::string& what) {
  throw RecordingError(fmt::format("{}: {}", file.string(), what));
}

// `relative` (the value of key `key` of recording.json `file`) resolved in
// the recording's folder; a path that is absolute or leaves the folder
// (dataset.md: paths relative to the folder), also through a symbolic link
// in it, is an error naming the key. (A link to the recording folder itself
// is fine: both sides are resolved.)
fs::path InsideFolder(const fs::path& file, const std::string& key, const fs::path& folder,
                      const std::string& relative) {
  const fs::path given(relative);
  const fs::path normal = given.lexically_normal();
  const auto outside = [&](const std::string& how) {
    Fail(file, fmt::format("key '{}' = '{}': must be a path inside the recording folder{}", key,
                           relative, how));
  };
  if (given.is_absolute() || normal.empty() || *normal.begin() == "..") outside("");
  const fs::path resolved = (folder / normal).lexically_normal();
  // weakly_canonical resolves the links of the part that exists (an image
  // sequence's pattern does not).
  std::error_code ec;
  const fs::path real_folder = fs::weakly_canonical(folder, ec);
  const fs::path real_path = ec ? fs::path() : fs::weakly_canonical(resolved, ec);
  if (!ec) {
    const fs::path inside = real_path.lexically_relative(real_folder);
    if (inside.empty() || *inside.begin() == "..") {
      outside(fmt::format(" (a symbolic link leads to {})", real_path.string()));
    }
  }
  return resolved;
}

std::string TypeName(const json& v) { return v.type_name(); }

// ---------------------------------------------------------------------------
// recording.json

/// Reads a JSON number that must be a finite double.
double ReadNumber(const fs::path& file, const std::string& key, const json& v) {
  if (!v.is_number()) {
    Fail(file, fmt::format("key '{}' must be a number, found {} ({})", key, TypeName(v), v.dump()));
  }
  const double x = v.get<double>();
  if (!std::isfinite(x)) Fail(file, fmt::format("key '{}' must be finite, found {}", key, x));
  return x;
}

/// Reads a JSON number that must be an integer representable as int.
int ReadInt(const fs::path& file, const std::string& key, const json& v) {
  const double x = ReadNumber(file, key, v);
  if (x != std::floor(x) || x < std::numeric_limits<int>::min() ||
      x > std::numeric_limits<int>::max()) {
    Fail(file, fmt::format("key '{}' must be an integer, found {}", key, v.dump()));
  }
  return static_cast<int>(x);
}

std::string ReadString(const fs::path& file, const std::string& key, const json& v) {
  if (!v.is_string()) {
    Fail(file, fmt::format("key '{}' must be a string, found {} ({})", key, TypeName(v), v.dump()));
  }
  return v.get<std::string>();
}

const json& Require(const fs::path& file, const json& object, const std::string& parent,
                    const std::string& key) {
  const auto it = object.find(key);
  const std::string full = parent.empty() ? key : parent + "." + key;
  if (it == object.end()) Fail(file, fmt::format("missing required key '{}'", full));
  return *it;
}

/// The value at `key`, or nullptr when it is absent or null.
const json* Optional(const json& object, const std::string& key) {
  const auto it = object.find(key);
  if (it == object.end() || it->is_null()) return nullptr;
  return &*it;
}

/// An [x, y, width, height] array; its fit in the frame is checked later.
PixelRect ReadRect(const fs::path& file, const std::string& key, const json& v) {
  if (!v.is_array() || v.size() != 4) {
    Fail(file,
         fmt::format("key '{}' must be an array [x, y, width, height], found {}", key, v.dump()));
  }
  PixelRect r;
  r.x = ReadInt(file, key + "[0]", v[0]);
  r.y = ReadInt(file, key + "[1]", v[1]);
  r.width = ReadInt(file, key + "[2]", v[2]);
  r.height = ReadInt(file, key + "[3]", v[3]);
  return r;
}

std::array<int, 3> ReadHsv(const fs::path& file, const std::string& key, const json& v) {
  if (!v.is_array() || v.size() != 3) {
    Fail(file, fmt::format("key '{}' must be an array [H, S, V], found {}", key, v.dump()));
  }
  static constexpr std::array<int, 3> kMax{179, 255, 255};
  static constexpr std::array<const char*, 3> kChannel{"H", "S", "V"};
  std::array<int, 3> hsv{};
  for (int c = 0; c < 3; ++c) {
    const std::string elem = fmt::format("{}[{}]", key, c);
    hsv[c] = ReadInt(file, elem, v[c]);
    if (hsv[c] < 0 || hsv[c] > kMax[c]) {
      Fail(file, fmt::format("key '{}' = {} out of range: {} must be in 0..{}", elem, hsv[c],
                             kChannel[c], kMax[c]));
    }
  }
  return hsv;
}

void CheckRectInFrame(const fs::path& file, const std::string& key, const PixelRect& r, int width,
                      int height) {
  if (r.width <= 0 || r.height <= 0) {
    Fail(file, fmt::format("key '{}' = [{}, {}, {}, {}] has a non-positive size", key, r.x, r.y,
                           r.width, r.height));
  }
  if (r.x < 0 || r.y < 0 || int64_t{r.x} + r.width > width || int64_t{r.y} + r.height > height) {
    Fail(file, fmt::format("key '{}' = [{}, {}, {}, {}] is not inside the {} x {} frame", key, r.x,
                           r.y, r.width, r.height, width, height));
  }
}

std::string ReadJsonFile(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) Fail(file, "cannot open file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

/// Fills everything of `rec` that recording.json (`text`, read from `file`)
/// holds; the roi is left empty when absent and the rectangles are checked
/// against the frame later (CheckRects).
void ReadMetadata(const fs::path& file, std::string_view text, Recording* rec, bool* has_roi) {
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::exception& e) {
    Fail(file, fmt::format("invalid JSON: {}", e.what()));
  }
  if (!doc.is_object())
    Fail(file, fmt::format("top level must be an object, found {}", TypeName(doc)));

  const std::string format = ReadString(file, "format", Require(file, doc, "", "format"));
  if (format != kFormat) {
    Fail(file,
         fmt::format("key 'format' = \"{}\" is not supported; expected \"{}\"", format, kFormat));
  }
  const std::string video = ReadString(file, "video", Require(file, doc, "", "video"));
  const std::string track = ReadString(file, "track", Require(file, doc, "", "track"));
  if (video.empty()) Fail(file, "key 'video' is empty");
  if (track.empty()) Fail(file, "key 'track' is empty");
  rec->video_path = InsideFolder(file, "video", rec->folder, video);
  rec->track_path = InsideFolder(file, "track", rec->folder, track);

  rec->fps = ReadNumber(file, "fps", Require(file, doc, "", "fps"));
  if (rec->fps <= 0.0) Fail(file, fmt::format("key 'fps' = {} must be > 0", rec->fps));
  if (rec->fps > kMaxFps) {
    // Past any camera's rate: the frame time would underflow the
    // simulation's substeps and be blamed on every candidate.
    Fail(file, fmt::format("key 'fps' = {} must be <= {}", rec->fps, kMaxFps));
  }

  const json& object = Require(file, doc, "", "object");
  if (!object.is_object()) {
    Fail(file, fmt::format("key 'object' must be an object, found {}", TypeName(object)));
  }
  rec->object_hsv.lower =
      ReadHsv(file, "object.color_hsv_lower", Require(file, object, "object", "color_hsv_lower"));
  rec->object_hsv.upper =
      ReadHsv(file, "object.color_hsv_upper", Require(file, object, "object", "color_hsv_upper"));
  for (int c = 0; c < 3; ++c) {
    if (rec->object_hsv.lower[c] > rec->object_hsv.upper[c]) {
      Fail(file, fmt::format("key 'object.color_hsv_lower[{0}]' = {1} exceeds "
                             "'object.color_hsv_upper[{0}]' = {2}; the range is inclusive and "
                             "must have lower <= upper",
                             c, rec->object_hsv.lower[c], rec->object_hsv.upper[c]));
    }
  }

  if (const json* v = Optional(doc, "mm_per_px")) {
    const double mm = ReadNumber(file, "mm_per_px", *v);
    if (mm <= 0.0) Fail(file, fmt::format("key 'mm_per_px' = {} must be > 0", mm));
    rec->mm_per_px = mm;
  }
  if (const json* v = Optional(doc, "force_obstacle")) {
    rec->force_obstacle = ReadString(file, "force_obstacle", *v);
  }
  *has_roi = false;
  if (const json* v = Optional(doc, "roi")) {
    rec->roi = ReadRect(file, "roi", *v);
    *has_roi = true;
  }
  if (const json* v = Optional(doc, "clamps")) {
    if (!v->is_array()) {
      Fail(file, fmt::format("key 'clamps' must be an array of [x, y, width, height], found {}",
                             TypeName(*v)));
    }
    for (size_t i = 0; i < v->size(); ++i) {
      rec->clamps.push_back(ReadRect(file, fmt::format("clamps[{}]", i), (*v)[i]));
    }
  }
  if (const json* v = Optional(doc, "notes")) rec->notes = ReadString(file, "notes", *v);
}

/// The roi (the whole frame when recording.json gives none) and the clamps
/// checked against the frame size.
void CheckRects(const fs::path& file, bool has_roi, Recording* rec) {
  if (has_roi) {
    CheckRectInFrame(file, "roi", rec->roi, rec->frame_width, rec->frame_height);
  } else {
    rec->roi = PixelRect{0, 0, rec->frame_width, rec->frame_height};
  }
  for (size_t i = 0; i < rec->clamps.size(); ++i) {
    CheckRectInFrame(file, fmt::format("clamps[{}]", i), rec->clamps[i], rec->frame_width,
                     rec->frame_height);
  }
}

// ---------------------------------------------------------------------------
// video

bool IsImagePattern(const fs::path& video) {
  return video.filename().string().find('%') != std::string::npos;
}

/// Reads the frame size and count of the video. The count is the container's
/// where it states one, else the number of frames that can be grabbed.
void ReadVideoInfo(const fs::path& video, Recording* rec) {
  if (!IsImagePattern(video) && !fs::is_regular_file(video)) {
    Fail(video, "video file does not exist");
  }
  VideoReader cap(video);
  if (!cap.IsOpen()) Fail(video, "cannot open video (cv::VideoCapture)");
  int width = static_cast<int>(cap.StatedWidth());
  int height = static_cast<int>(cap.StatedHeight());
  const double stated = cap.StatedFrameCount();
  int count = 0;
  if (stated > 0 && std::isfinite(stated)) {
    count = static_cast<int>(std::llround(stated));
    if (width <= 0 || height <= 0) {
      cv::Mat frame;
      if (cap.Read(frame)) {
        width = frame.cols;
        height = frame.rows;
      }
    }
  } else {
    cv::Mat frame;
    if (cap.Read(frame)) {
      width = frame.cols;
      height = frame.rows;
      count = 1;
      while (cap.Grab()) ++count;
    }
  }
  if (count <= 0) Fail(video, "video holds no frames");
  if (width <= 0 || height <= 0) {
    Fail(video, fmt::format("cannot read the frame size (found {} x {})", width, height));
  }
  rec->frame_width = width;
  rec->frame_height = height;
  rec->num_frames = count;
}

// ---------------------------------------------------------------------------
// track.csv

/// Header and data rows of a CSV file, as parsed by libcsv.
struct CsvTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
};

struct CsvState {
  std::vector<std::string> current;
  std::vector<std::vector<std::string>> all;
};

void CsvOnField(void* data, size_t len, void* user) {
  auto* state = static_cast<CsvState*>(user);
  state->current.emplace_back(static_cast<const char*>(data), len);
}

void CsvOnRow(int /*terminator*/, void* user) {
  auto* state = static_cast<CsvState*>(user);
  state->all.push_back(std::move(state->current));
  state->current.clear();
}

std::string Trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return {};
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

std::string ReadTrackFile(const fs::path& file) {
  // Read whole: only a regular file of bounded size (not a device or a
  // pipe that never ends).
  std::error_code ec;
  if (fs::exists(file, ec) && !fs::is_regular_file(file, ec)) Fail(file, "not a regular file");
  const uintmax_t size = fs::file_size(file, ec);
  if (!ec && size > kMaxTrackBytes) {
    Fail(file, fmt::format("{} bytes: a track may hold at most {} bytes", size, kMaxTrackBytes));
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) Fail(file, "cannot open file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

CsvTable ParseCsv(const fs::path& file, std::string_view text) {
  csv_parser parser;
  if (csv_init(&parser, CSV_STRICT | CSV_STRICT_FINI) != 0) Fail(file, "cannot initialise libcsv");
  CsvState state;
  const size_t parsed = csv_parse(&parser, text.data(), text.size(), CsvOnField, CsvOnRow, &state);
  const bool parse_ok =
      parsed == text.size() && csv_fini(&parser, CsvOnField, CsvOnRow, &state) == 0;
  const std::string error = csv_strerror(csv_error(&parser));
  csv_free(&parser);
  if (!parse_ok) {
    const auto line = 1 + std::count(text.begin(), text.begin() + parsed, '\n');
    Fail(file, fmt::format("CSV parse error at line {} (byte {}): {}", line, parsed, error));
  }
  if (state.all.empty()) Fail(file, "empty file: expected a header row");
  CsvTable table;
  for (const std::string& name : state.all.front()) table.header.push_back(Trim(name));
  table.rows.assign(std::make_move_iterator(state.all.begin() + 1),
                    std::make_move_iterator(state.all.end()));
  return table;
}

/// Where a cell is, for messages: data row `row` (0-based, as the frame
/// index) is line row + 2 of the file.
std::string CellName(int row, const std::string& column) {
  return fmt::format("row {} (line {}), column '{}'", row, row + 2, column);
}

double ParseCell(const fs::path& file, const CsvTable& table, int row, int col) {
  const std::string cell = Trim(table.rows[row][col]);
  const std::string& name = table.header[col];
  double x = 0.0;
  const char* end = cell.data() + cell.size();
  const auto [ptr, ec] = std::from_chars(cell.data(), end, x);
  if (cell.empty() || ec != std::errc() || ptr != end) {
    Fail(file, fmt::format("{}: bad number '{}'", CellName(row, name), cell));
  }
  if (!std::isfinite(x)) {
    Fail(file, fmt::format("{}: non-finite value '{}'", CellName(row, name), cell));
  }
  return x;
}

/// Obstacle columns: name and the column indices of its _x, _y and _r.
struct ObstacleColumns {
  std::string name;
  std::array<int, 3> col{-1, -1, -1};
};

/// Every `<name>_x, <name>_y, <name>_r` set is one obstacle, ordered by the
/// first of its columns; `force_x, force_y` are the force, never an obstacle.
std::vector<ObstacleColumns> FindObstacles(const fs::path& file, const CsvTable& table) {
  static constexpr std::array<const char*, 3> kSuffix{"_x", "_y", "_r"};
  std::vector<ObstacleColumns> obstacles;
  std::map<std::string, size_t> index;
  for (int c = 0; c < static_cast<int>(table.header.size()); ++c) {
    const std::string& name = table.header[c];
    for (int k = 0; k < 3; ++k) {
      if (name.size() <= 2 || !name.ends_with(kSuffix[k])) continue;
      const std::string base = name.substr(0, name.size() - 2);
      if (base == "force") continue;
      auto [it, inserted] = index.emplace(base, obstacles.size());
      if (inserted) obstacles.push_back({base, {-1, -1, -1}});
      obstacles[it->second].col[k] = c;
    }
  }
  for (const ObstacleColumns& o : obstacles) {
    for (int k = 0; k < 3; ++k) {
      if (o.col[k] < 0) {
        Fail(file, fmt::format("obstacle '{0}' lacks column '{0}{1}': an obstacle needs all of "
                               "'{0}_x', '{0}_y', '{0}_r'",
                               o.name, kSuffix[k]));
      }
    }
  }
  return obstacles;
}

int FindColumn(const CsvTable& table, const std::string& name) {
  for (int c = 0; c < static_cast<int>(table.header.size()); ++c) {
    if (table.header[c] == name) return c;
  }
  return -1;
}

void ReadTrack(const fs::path& file, std::string_view text, Recording* rec) {
  const CsvTable table = ParseCsv(file, text);
  for (size_t c = 0; c < table.header.size(); ++c) {
    for (size_t d = 0; d < c; ++d) {
      if (table.header[c] == table.header[d] && !table.header[c].empty()) {
        Fail(file, fmt::format("header names column '{}' twice (columns {} and {})",
                               table.header[c], d, c));
      }
    }
  }
  const int frame_col = FindColumn(table, "frame");
  if (frame_col < 0) Fail(file, "missing required column 'frame' in the header");

  const int num_rows = static_cast<int>(table.rows.size());
  for (int r = 0; r < num_rows; ++r) {
    if (table.rows[r].size() != table.header.size()) {
      Fail(file, fmt::format("row {} (line {}) has {} fields; the header has {}", r, r + 2,
                             table.rows[r].size(), table.header.size()));
    }
  }
  if (num_rows != rec->num_frames) {
    Fail(file, fmt::format("has {} data rows but the video {} has {} frames", num_rows,
                           rec->video_path.string(), rec->num_frames));
  }
  for (int r = 0; r < num_rows; ++r) {
    const double frame = ParseCell(file, table, r, frame_col);
    if (frame != r) {
      Fail(file, fmt::format("{}: frame {} out of order; expected {} (frames run 0..n-1)",
                             CellName(r, "frame"), Trim(table.rows[r][frame_col]), r));
    }
  }

  for (const ObstacleColumns& o : FindObstacles(file, table)) {
    ObstacleTrack track;
    track.name = o.name;
    track.discs.resize(num_rows);
    for (int r = 0; r < num_rows; ++r) {
      Disc& disc = track.discs[r];
      disc.centre = Vec2(ParseCell(file, table, r, o.col[0]), ParseCell(file, table, r, o.col[1]));
      disc.radius_px = ParseCell(file, table, r, o.col[2]);
      if (disc.radius_px < 0.0) {
        Fail(file, fmt::format("{}: radius {} must be >= 0", CellName(r, table.header[o.col[2]]),
                               disc.radius_px));
      }
      // A disc far outside the frame cannot touch the object: a coordinate
      // there is a unit or export error, not a position.
      const double reach = kMaxObstacleReachFrames * std::max(rec->frame_width, rec->frame_height);
      for (int k = 0; k < 3; ++k) {
        const double v = k == 0 ? disc.centre.x() : k == 1 ? disc.centre.y() : disc.radius_px;
        if (std::abs(v) > reach) {
          Fail(file, fmt::format("{}: {} lies more than {} frame sizes ({} px) from the frame",
                                 CellName(r, table.header[o.col[k]]), v, kMaxObstacleReachFrames,
                                 reach));
        }
      }
    }
    rec->obstacles.push_back(std::move(track));
  }

  if (!rec->force_obstacle) return;
  if (rec->ForceObstacleIndex() < 0) {
    std::string names;
    for (const ObstacleTrack& o : rec->obstacles)
      names += (names.empty() ? "'" : ", '") + o.name + "'";
    Fail(file, fmt::format("force_obstacle '{}' (from recording.json) names no obstacle triple "
                           "'{}_x, {}_y, {}_r'; obstacles found: {}",
                           *rec->force_obstacle, *rec->force_obstacle, *rec->force_obstacle,
                           *rec->force_obstacle, names.empty() ? "none" : names));
  }
  const int fx = FindColumn(table, "force_x");
  const int fy = FindColumn(table, "force_y");
  if (fx < 0 || fy < 0) {
    Fail(file, fmt::format("missing column '{}': required because force_obstacle is '{}'",
                           fx < 0 ? "force_x" : "force_y", *rec->force_obstacle));
  }
  rec->forces.resize(num_rows);
  for (int r = 0; r < num_rows; ++r) {
    rec->forces[r] = Vec2(ParseCell(file, table, r, fx), ParseCell(file, table, r, fy));
  }
}

}  // namespace

int Recording::ForceObstacleIndex() const {
  if (!force_obstacle) return -1;
  for (size_t i = 0; i < obstacles.size(); ++i) {
    if (obstacles[i].name == *force_obstacle) return static_cast<int>(i);
  }
  return -1;
}

Recording LoadRecording(const std::filesystem::path& folder) {
  Recording rec;
  std::error_code ec;
  const fs::path absolute = fs::absolute(folder, ec);
  rec.folder = (ec ? folder : absolute).lexically_normal();
  if (!fs::is_directory(rec.folder)) Fail(rec.folder, "recording folder does not exist");
  const fs::path json_path = rec.folder / "recording.json";

  bool has_roi = false;
  ReadMetadata(json_path, ReadJsonFile(json_path), &rec, &has_roi);
  ReadVideoInfo(rec.video_path, &rec);
  CheckRects(json_path, has_roi, &rec);
  ReadTrack(rec.track_path, ReadTrackFile(rec.track_path), &rec);
  return rec;
}

void ParseRecordingJson(std::string_view text, const std::filesystem::path& file, Recording* rec) {
  bool has_roi = false;
  ReadMetadata(file, text, rec, &has_roi);
  CheckRects(file, has_roi, rec);
}

void ParseTrackCsv(std::string_view text, const std::filesystem::path& file, Recording* rec) {
  ReadTrack(file, text, rec);
}

std::string RecordingDisplayName(const std::filesystem::path& folder) {
  // Normalised as LoadRecording stores Recording::folder: "a/b/." and
  // "a/b/c/.." are a/b/, and a trailing slash leaves an empty filename.
  std::error_code ec;
  const fs::path absolute = fs::absolute(folder, ec);
  fs::path normal = (ec ? folder : absolute).lexically_normal();
  if (normal.filename().empty()) normal = normal.parent_path();
  const std::string name = normal.filename().string();
  return name.empty() ? folder.string() : name;
}

}  // namespace calib
