#include "support/csv_support.h"

#include <csv.h>
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

namespace calib::testing {

CsvRows ParseCsv(const std::string& text) {
  struct State {
    CsvRows rows;
    std::vector<std::string> row;
  } state;
  csv_parser parser;
  csv_init(&parser, CSV_STRICT | CSV_APPEND_NULL);
  const auto on_field = [](void* data, size_t, void* out) {
    static_cast<State*>(out)->row.emplace_back(static_cast<const char*>(data));
  };
  const auto on_row = [](int, void* out) {
    auto* s = static_cast<State*>(out);
    s->rows.push_back(std::move(s->row));
    s->row.clear();
  };
  EXPECT_EQ(csv_parse(&parser, text.data(), text.size(), on_field, on_row, &state), text.size())
      << csv_strerror(csv_error(&parser));
  csv_fini(&parser, on_field, on_row, &state);
  csv_free(&parser);
  return state.rows;
}

CsvRows ParseCsvFile(const std::filesystem::path& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path << ": cannot open";
  std::stringstream buffer;
  buffer << in.rdbuf();
  return ParseCsv(buffer.str());
}

}  // namespace calib::testing
