// docs/recording.md describes what the recording reader takes: every key of
// its recording.json table and every column of its track.csv table is one
// LoadRecording reads (a wrong value there is an error naming it), so the
// page cannot list a key the reader ignores.

#include "calib/evaluator/recording.h"

#include "support/process_support.h"
#include "support/test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace calib {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The backquoted names in the first column of the table under `heading`,
// skipping templates such as `<name>_x`.
std::vector<std::string> TableNames(const std::string& page, const std::string& heading) {
  std::vector<std::string> names;
  const size_t start = page.find("\n" + heading + "\n");
  if (start == std::string::npos) {
    ADD_FAILURE() << "docs/recording.md has no section '" << heading << "'";
    return names;
  }
  const size_t end = page.find("\n## ", start + 1);
  std::istringstream section(page.substr(start, end - start));
  const std::regex name("`([^`]+)`");
  for (std::string line; std::getline(section, line);) {
    if (line.rfind("| `", 0) != 0) continue;
    const std::string first = line.substr(1, line.find('|', 1) - 1);
    for (std::sregex_iterator it(first.begin(), first.end(), name), done; it != done; ++it) {
      const std::string n = (*it)[1];
      if (n.find('<') == std::string::npos) names.push_back(n);
    }
  }
  return names;
}

// A copy of the bundled example (every required key, a force sensor).
fs::path CopyExample(const std::string& name) {
  const fs::path dir = testing::ScratchDir(name) / "rec";
  fs::copy(fs::path(CALIB_SOURCE_DIR) / "examples" / "push_centre", dir, fs::copy_options::recursive);
  return dir;
}

std::string LoadError(const fs::path& dir) {
  try {
    LoadRecording(dir);
  } catch (const RecordingError& e) {
    return e.what();
  }
  return "";
}

const std::string kPage = testing::ReadText(fs::path(CALIB_SOURCE_DIR) / "docs" / "recording.md");

TEST(RecordingDoc, EveryListedKeyIsReadByTheReader) {
  const std::vector<std::string> keys = TableNames(kPage, "## recording.json");
  EXPECT_GE(keys.size(), 12u) << "the table lists every key of shared/spec/dataset.md";
  for (const std::string& key : keys) {
    const fs::path dir = CopyExample("recording_doc_key");
    json doc = json::parse(testing::ReadText(dir / "recording.json"));
    // A value of the wrong type: the reader names every key it reads.
    const json wrong = key == "object" ? json(5) : json{{"wrong", true}};
    const size_t dot = key.find('.');
    if (dot == std::string::npos) {
      doc[key] = wrong;
    } else {
      doc[key.substr(0, dot)][key.substr(dot + 1)] = wrong;
    }
    std::ofstream(dir / "recording.json") << doc.dump(2);
    EXPECT_NE(LoadError(dir).find("key '" + key + "'"), std::string::npos)
        << "docs/recording.md lists '" << key << "', but a wrong value there is not named: "
        << LoadError(dir);
  }
}

TEST(RecordingDoc, EveryListedColumnIsReadByTheReader) {
  const std::vector<std::string> columns = TableNames(kPage, "## track.csv");
  EXPECT_EQ(columns, (std::vector<std::string>{"frame", "force_x", "force_y"}));
  for (const std::string& column : columns) {
    const fs::path dir = CopyExample("recording_doc_column");
    std::string track = testing::ReadText(dir / "track.csv");
    const size_t at = track.find(column);
    ASSERT_LT(at, track.find('\n')) << "the example's header lacks " << column;
    track.replace(at, column.size(), "unread");  // the column renamed away
    std::ofstream(dir / "track.csv") << track;
    EXPECT_NE(LoadError(dir).find("column '" + column + "'"), std::string::npos)
        << "docs/recording.md lists column '" << column << "', but its absence is not named: "
        << LoadError(dir);
  }
}

}  // namespace
}  // namespace calib
