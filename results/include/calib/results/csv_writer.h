#pragma once
// Writing CSV files (the results store's exports, the frame reports, the
// loop benchmark's table): one record per line, fields that hold a
// separator, quote or line break quoted by libcsv (their quotes doubled),
// the rest written as they are.

#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace calib::csv_writer {

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

/// Opens `path` for writing; null when it cannot be opened.
File Open(const std::filesystem::path& path);

/// Writes one record.
void WriteRecord(std::FILE* out, const std::vector<std::string>& fields);

/// Closes the file; false when a write or the close failed.
bool Close(File file);

}  // namespace calib::csv_writer
