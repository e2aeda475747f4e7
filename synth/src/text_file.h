#pragma once
// The synthetic recordings' text files (recording.json, track.csv,
// truth.json, a family's manifest and scenarios), written whole.

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

namespace calib::synth {

/// Writes `text` to `path` as it is; throws std::runtime_error naming the
/// path when it cannot.
inline void WriteText(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error(fmt::format("{}: cannot write", path.string()));
}

}  // namespace calib::synth
