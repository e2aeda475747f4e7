#pragma once
// Helpers shared by the tests: where ../shared is, and a scratch folder.

#include <filesystem>
#include <string>

namespace calib::testing {

/// The shared/ folder beside the repository (CALIB_SHARED_DIR, set by ctest).
std::filesystem::path SharedDir();

/// The real recordings folder, shared/data/real.
std::filesystem::path RealRecordingsDir();

/// A fresh, empty folder for this test under the system temp folder.
std::filesystem::path ScratchDir(const std::string& name);

}  // namespace calib::testing

#include "calib/core/mesh.h"
#include "calib/core/parameters.h"
#include "calib/core/scene.h"

#include <cstdint>
#include <functional>
#include <vector>

namespace calib::testing {

/// A rectangular patch of nx x ny lattice cells of `spacing` px with its
/// top-left corner at `origin`, each cell split into two triangles along
/// alternating diagonals (a symmetric pattern).
Mesh MakeGridMesh(int nx, int ny, double spacing, const Vec2& origin = Vec2::Zero());

/// Stiff, damped base parameters for small test meshes (settle in a few
/// hundred substeps), with the given translation share.
ModelParameters StiffTestParameters(double translation = 0.0);

/// A scene of `frames` frames at `fps` with no obstacle, clamp or force.
Scene StillScene(int frames, double fps = 30.0);

/// The same with one obstacle at disc(f) in frame f; with `force`, the force
/// sensor is on that obstacle and reads force(f), without it there is none.
Scene OneDiscScene(int frames, double fps, const std::function<Disc(int)>& disc,
                   const std::function<Vec2(int)>& force = {});

/// `base` with every point moved by up to `amount` in x and y, drawn from
/// `seed` the same way on every standard library.
std::vector<Vec2> Jittered(const std::vector<Vec2>& base, double amount, uint64_t seed);

}  // namespace calib::testing
