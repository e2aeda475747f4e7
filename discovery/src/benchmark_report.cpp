// benchmark.json and benchmark.csv of the loop benchmark (benchmark_report.h).

#include "calib/discovery/benchmark_report.h"

#include "calib/discovery/hypotheses.h"
#include "calib/results/csv_writer.h"
#include "json_io.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <stdexcept>

namespace calib {
namespace {

using nlohmann::json;

constexpr const char* kFormat = "calib-loop-benchmark/1";

}  // namespace

json ToJson(const LoopBenchmarkReport& report) {
  json objects = json::array();
  for (const ObjectOutcome& o : report.outcomes) objects.push_back(ToJson(o));
  return {{"format", kFormat},
          {"family",
           {{"dir", report.family_dir},
            {"name", report.family_name},
            {"spec", report.family_spec},
            {"seed", report.family_seed}}},
          {"command", report.command},
          {"objects", objects},
          {"aggregate", ToJson(report.aggregate)}};
}

LoopBenchmarkReport LoopBenchmarkReportFromJson(const json& doc, const std::string& source) {
  const json_io::Keys top(doc, source, "");
  if (top.Text("format") != kFormat) top.FailValue("format", fmt::format("not \"{}\"", kFormat));
  LoopBenchmarkReport r;
  const json_io::Keys family = top.Child("family");
  r.family_dir = family.Text("dir");
  r.family_name = family.Text("name");
  r.family_spec = family.Text("spec");
  r.family_seed = family.Count("seed");
  r.command = top.Text("command");
  const size_t n = top.Array("objects").size();
  for (size_t i = 0; i < n; ++i) {
    r.outcomes.push_back(
        ObjectOutcomeFromJson(doc["objects"][i], fmt::format("{}: objects[{}]", source, i)));
  }
  r.aggregate = AggregateOutcomes(r.outcomes, TracedEffects());
  return r;
}

void WriteBenchmarkCsv(const std::filesystem::path& path,
                       const std::vector<ObjectOutcome>& outcomes) {
  csv_writer::File file = csv_writer::Open(path);
  if (!file) throw std::runtime_error(fmt::format("{}: cannot open for writing", path.string()));
  const std::vector<std::string>& effects = TracedEffects();
  csv_writer::WriteRecord(file.get(), OutcomeCsvHeader(effects));
  for (const ObjectOutcome& o : outcomes)
    csv_writer::WriteRecord(file.get(), OutcomeCsvRow(o, effects));
  if (!csv_writer::Close(std::move(file))) {
    throw std::runtime_error(fmt::format("{}: write failed", path.string()));
  }
}

void WriteBenchmarkJson(const std::filesystem::path& path, const LoopBenchmarkReport& report) {
  json_io::WriteFile(path, ToJson(report));
}

}  // namespace calib
