#include "support/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <system_error>
#include <vector>
#include <unistd.h>

namespace calib::testing {

std::filesystem::path SharedDir() {
  if (const char* env = std::getenv("CALIB_SHARED_DIR"); env != nullptr && *env != '\0') {
    return env;
  }
  return std::filesystem::path(CALIB_SOURCE_DIR) / ".." / "shared";
}

Scene StillScene(int frames, double fps) {
  Scene scene;
  scene.frame_time_s = 1.0 / fps;
  scene.num_frames = frames;
  return scene;
}

Scene OneDiscScene(int frames, double fps, const std::function<Disc(int)>& disc,
                   const std::function<Vec2(int)>& force) {
  Scene scene = StillScene(frames, fps);
  scene.num_obstacles = 1;
  if (force) scene.force_obstacle = 0;
  for (int f = 0; f < frames; ++f) {
    scene.obstacle_discs.push_back(disc(f));
    if (force) scene.forces.push_back(force(f));
  }
  return scene;
}

std::filesystem::path RealRecordingsDir() { return SharedDir() / "data" / "real"; }

namespace {

// Removes the scratch folders of tests that did not fail, so that repeated runs do
// not fill the temp folder; a failed test's folders stay for a look, and
// CALIB_KEEP_SCRATCH=1 keeps every folder. A folder made outside a test (a
// suite's shared fixture) lives until the program ends.
class ScratchCleaner final : public ::testing::EmptyTestEventListener {
 public:
  void Add(const std::filesystem::path& dir, bool in_test) {
    (in_test ? test_dirs_ : program_dirs_).push_back(dir);
  }

 private:
  void OnTestEnd(const ::testing::TestInfo& info) override {
    Finish(test_dirs_, !info.result()->Failed());
  }
  void OnTestProgramEnd(const ::testing::UnitTest& unit) override {
    Finish(program_dirs_, !unit.Failed());
  }
  static void Finish(std::vector<std::filesystem::path>& dirs, bool ok) {
    const char* keep = std::getenv("CALIB_KEEP_SCRATCH");
    const bool remove = ok && (keep == nullptr || *keep == '\0' || *keep == '0');
    for (const auto& dir : dirs) {
      std::error_code ignored;
      if (remove) std::filesystem::remove_all(dir, ignored);
      else std::fprintf(stderr, "scratch kept: %s\n", dir.c_str());
    }
    dirs.clear();
  }

  std::vector<std::filesystem::path> test_dirs_;
  std::vector<std::filesystem::path> program_dirs_;
};

ScratchCleaner& Cleaner() {
  // Owned by gtest's listener list once appended.
  static ScratchCleaner* cleaner = [] {
    auto* c = new ScratchCleaner;
    ::testing::UnitTest::GetInstance()->listeners().Append(c);
    return c;
  }();
  return *cleaner;
}

}  // namespace

std::filesystem::path ScratchDir(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string id = name;
  if (info != nullptr) id += std::string("_") + info->test_suite_name() + "_" + info->name();
  std::replace(id.begin(), id.end(), '/', '_');  // a parameterised test's names hold slashes
  const auto dir = std::filesystem::temp_directory_path() /
                   ("calib_test_" + std::to_string(::getpid()) + "_" + id);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  Cleaner().Add(dir, info != nullptr);
  return dir;
}

}  // namespace calib::testing

namespace calib::testing {

Mesh MakeGridMesh(int nx, int ny, double spacing, const Vec2& origin) {
  std::vector<Vec2> positions;
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) positions.push_back(origin + spacing * Vec2(i, j));
  }
  auto id = [nx](int i, int j) { return j * (nx + 1) + i; };
  std::vector<std::array<int, 3>> triangles;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      if ((i + j) % 2 == 0) {
        triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
        triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
      } else {
        triangles.push_back({id(i, j), id(i + 1, j), id(i, j + 1)});
        triangles.push_back({id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)});
      }
    }
  }
  return BuildMesh(std::move(positions), std::move(triangles));
}

ModelParameters StiffTestParameters(double translation) {
  ModelParameters p;
  p.k_distance = 50.0;
  p.k_damping = 0.5;
  p.k_area = 20.0;
  p.k_angle = 5.0;
  p.mass = 0.05;
  p.translation = translation;
  return p;
}

std::vector<Vec2> Jittered(const std::vector<Vec2>& base, double amount, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<Vec2> out = base;
  for (Vec2& p : out) {
    // Not std::uniform_real_distribution: its output differs between
    // standard libraries.
    const double u = static_cast<double>(rng() >> 11) * 0x1.0p-53;
    const double w = static_cast<double>(rng() >> 11) * 0x1.0p-53;
    p += amount * Vec2(2.0 * u - 1.0, 2.0 * w - 1.0);
  }
  return out;
}

}  // namespace calib::testing
