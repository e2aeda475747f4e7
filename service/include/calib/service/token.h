#pragma once
// The token every request to the service carries (Authorization: Bearer
// TOKEN). Made on the server's first start from 32 random bytes (64 hex
// digits) and kept in a file only its owner may read (mode 0600).

#include <filesystem>
#include <string>

namespace calib::service {

struct Token {
  std::string value;
  bool created = false;  ///< made now (the server prints it this once)
};

/// Reads the token at `path`, or makes one there (creating its folder) when
/// there is none. Throws std::runtime_error naming the file when it cannot
/// be read or written, is empty, or may be read by others than its owner.
Token LoadOrCreateToken(const std::filesystem::path& path);

/// Reads the token at `path` (a client). Throws std::runtime_error naming
/// the file.
std::string ReadToken(const std::filesystem::path& path);

}  // namespace calib::service
