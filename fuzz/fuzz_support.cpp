#include "fuzz_support.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <typeinfo>

#include <cxxabi.h>

namespace calib::fuzz {
namespace {

std::filesystem::path* temp_dir = nullptr;

void RemoveTempDir() {
  std::error_code ec;
  if (temp_dir != nullptr) std::filesystem::remove_all(*temp_dir, ec);
}

}  // namespace

const std::filesystem::path& TempDir() {
  if (temp_dir == nullptr) {
    temp_dir = new std::filesystem::path(std::filesystem::temp_directory_path() /
                                         ("calib-fuzz-" + std::to_string(::getpid())));
    std::filesystem::create_directories(*temp_dir);
    std::atexit(RemoveTempDir);
  }
  return *temp_dir;
}

void Unexpected(const char* target) {
  const std::type_info* type = abi::__cxa_current_exception_type();
  int status = 0;
  char* name = type ? abi::__cxa_demangle(type->name(), nullptr, nullptr, &status) : nullptr;
  std::string what = "(not a std::exception)";
  try {
    throw;
  } catch (const std::exception& e) {
    what = e.what();
  } catch (...) {
  }
  std::fprintf(stderr, "%s: unexpected exception %s: %s\n", target,
               name ? name : (type ? type->name() : "?"), what.c_str());
  std::abort();
}

}  // namespace calib::fuzz
