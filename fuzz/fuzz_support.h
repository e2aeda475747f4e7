#pragma once
// Shared by the fuzz targets (fuzz/*.cpp). Each target hands the fuzzer's
// bytes to one parser and catches only the parser's documented error type:
// that is the expected outcome of bad input. Any other exception goes to
// Unexpected(), which names it and aborts, so libFuzzer records the input
// as a crash, as it does for a sanitizer report.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

namespace calib::fuzz {

/// The fuzzer's bytes as a string.
inline std::string Text(const uint8_t* data, size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

/// A folder of this process's own under the system's temporary folder,
/// created on first use and removed at exit.
const std::filesystem::path& TempDir();

/// Call from a catch (...) block: prints the exception's type and message
/// and aborts (a finding).
[[noreturn]] void Unexpected(const char* target);

}  // namespace calib::fuzz
