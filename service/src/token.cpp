#include "calib/service/token.h"

#include <fmt/format.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <random>
#include <stdexcept>

namespace calib::service {
namespace {

namespace fs = std::filesystem;

std::string NewToken() {
  std::random_device random;  // the kernel's generator (getrandom / /dev/urandom)
  std::string hex;
  for (int i = 0; i < 8; ++i) hex += fmt::format("{:08x}", random());
  return hex;
}

}  // namespace

std::string ReadToken(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot read the service token", path.string()));
  std::string token;
  in >> token;
  if (token.empty()) throw std::runtime_error(fmt::format("{}: the service token file is empty", path.string()));
  return token;
}

Token LoadOrCreateToken(const fs::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    if ((st.st_mode & 077) != 0) {
      throw std::runtime_error(fmt::format(
          "{}: the service token may be read by others (mode {:o}); make it 0600 (chmod 600)",
          path.string(), st.st_mode & 0777));
    }
    return {ReadToken(path), false};
  }
  if (path.has_parent_path()) fs::create_directories(path.parent_path());
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0600);
  if (fd < 0) {
    throw std::runtime_error(fmt::format("{}: cannot create the service token: {}", path.string(),
                                         std::strerror(errno)));
  }
  const std::string token = NewToken();
  const std::string line = token + "\n";
  const bool written = ::write(fd, line.data(), line.size()) == static_cast<ssize_t>(line.size());
  ::close(fd);
  if (!written) {
    fs::remove(path);
    throw std::runtime_error(fmt::format("{}: cannot write the service token", path.string()));
  }
  return {token, true};
}

}  // namespace calib::service
