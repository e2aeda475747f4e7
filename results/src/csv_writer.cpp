#include "calib/results/csv_writer.h"

#include <csv.h>

namespace calib::csv_writer {

File Open(const std::filesystem::path& path) { return File(std::fopen(path.c_str(), "w")); }

void WriteRecord(std::FILE* out, const std::vector<std::string>& fields) {
  for (size_t i = 0; i < fields.size(); ++i) {
    if (i > 0) std::fputc(',', out);
    if (fields[i].find_first_of(",\"\r\n") != std::string::npos) {
      csv_fwrite(out, fields[i].data(), fields[i].size());
    } else {
      std::fputs(fields[i].c_str(), out);
    }
  }
  std::fputc('\n', out);
}

bool Close(File file) {
  const bool write_error = std::ferror(file.get()) != 0;
  return std::fclose(file.release()) == 0 && !write_error;
}

}  // namespace calib::csv_writer
