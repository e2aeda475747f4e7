#pragma once
// Reading CSV back in tests (libcsv, strict): the reports and exports the
// product writes must parse.

#include <filesystem>
#include <string>
#include <vector>

namespace calib::testing {

using CsvRows = std::vector<std::vector<std::string>>;

/// Every record of `text`, fields unquoted. A parse error fails the test.
CsvRows ParseCsv(const std::string& text);

/// ParseCsv of the file's contents.
CsvRows ParseCsvFile(const std::filesystem::path& path);

}  // namespace calib::testing
