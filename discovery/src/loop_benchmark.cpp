// The loop benchmark: the loop on every object of a family (loop_benchmark.h).

#include "calib/discovery/loop_benchmark.h"

#include "calib/discovery/benchmark_html.h"
#include "calib/discovery/hypotheses.h"
#include "calib/search/factory.h"
#include "json_io.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <map>
#include <optional>
#include <stdexcept>

namespace calib {
namespace {

namespace fs = std::filesystem;

std::string AbsolutePath(const fs::path& p) { return fs::absolute(p).lexically_normal().string(); }

bool Lists(const std::vector<std::string>& list, const std::string& s) {
  return std::find(list.begin(), list.end(), s) != list.end();
}

// The report of an earlier run of the same command, or nothing (no report,
// another command, or a file that does not read back: a run killed while
// writing it).
std::optional<LoopReport> EarlierReport(const fs::path& report_json, const std::string& command,
                                        const LoopLog& log) {
  std::error_code ec;
  if (!fs::is_regular_file(report_json, ec)) return std::nullopt;
  try {
    LoopReport report = ReadLoopReportJson(report_json);
    if (report.command == command) return report;
    if (log) log(fmt::format("{}: made with other options; running again", report_json.string()));
  } catch (const std::exception& e) {
    if (log) log(fmt::format("{}: unreadable ({}); running again", report_json.string(), e.what()));
  }
  return std::nullopt;
}

std::string OutcomeLine(const ObjectOutcome& o) {
  if (!o.ok()) return o.status + ": " + o.error;
  return fmt::format("kept {}; held-out {:.0f} -> {:.0f} ({:+.1f} %); {:.1f} s",
                     o.effects_kept.empty() ? std::string("nothing")
                                            : fmt::format("{}", fmt::join(o.effects_kept, ", ")),
                     o.holdout_xor_before, o.holdout_xor_after, 100.0 * o.HoldoutChange(),
                     o.run_time_s);
}

}  // namespace

bool LoopBenchmarkOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (family_dir.empty())
    return fail("LoopBenchmarkOptions::family_dir is empty. Violated: a family folder.");
  if (out_dir.empty())
    return fail("LoopBenchmarkOptions::out_dir is empty. Violated: an output folder.");
  if (limit_per_cell < 0) {
    return fail(
        fmt::format("LoopBenchmarkOptions::limit_per_cell = {}. Violated: limit_per_cell >= 0.",
                    limit_per_cell));
  }
  const std::vector<std::string> optimizers = search::OptimizerNames();
  if (!Lists(optimizers, loop.optimizer)) {
    return fail(fmt::format("loop benchmark: --optimizer {}: unknown (known: {})", loop.optimizer,
                            fmt::join(optimizers, ", ")));
  }
  return html.IsValid(error);
}

std::vector<FamilyObject> SelectFamilyObjects(const FamilyManifest& manifest,
                                              const std::vector<std::string>& only,
                                              const std::vector<std::string>& cells,
                                              int limit_per_cell) {
  std::vector<std::string> ids, known_cells;
  for (const FamilyObject& o : manifest.objects) {
    ids.push_back(o.id);
    if (!Lists(known_cells, o.cell)) known_cells.push_back(o.cell);
  }
  for (const std::string& id : only) {
    if (!Lists(ids, id)) {
      throw std::invalid_argument(fmt::format("--only {}: no such object in {}", id,
                                              (manifest.dir / "family.json").string()));
    }
  }
  for (const std::string& cell : cells) {
    if (!Lists(known_cells, cell)) {
      throw std::invalid_argument(fmt::format("--cells {}: no such cell in {} (cells: {})", cell,
                                              (manifest.dir / "family.json").string(),
                                              fmt::join(known_cells, ", ")));
    }
  }
  std::vector<FamilyObject> selected;
  std::map<std::string, int> per_cell;
  for (const FamilyObject& o : manifest.objects) {
    if (!only.empty() && !Lists(only, o.id)) continue;
    if (!cells.empty() && !Lists(cells, o.cell)) continue;
    if (limit_per_cell > 0 && per_cell[o.cell] >= limit_per_cell) continue;
    ++per_cell[o.cell];
    selected.push_back(o);
  }
  return selected;
}

std::string LoopCommandLine(const LoopOptions& o) {
  std::vector<std::string> words = {"calib", "loop", "--train"};
  for (const fs::path& p : o.train) words.push_back(AbsolutePath(p));
  if (!o.holdout.empty()) {
    words.push_back("--holdout");
    for (const fs::path& p : o.holdout) words.push_back(AbsolutePath(p));
  }
  words.push_back("--out");
  words.push_back(AbsolutePath(o.out_dir));
  std::string line = fmt::format("{}", fmt::join(words, " "));
  line += fmt::format(
      " --seed {} --budget {} --effect-budget {} --optimizer {} --max-effects {} --tries {}"
      " --min-confidence {} --fdr {} --held-out-stretch {} --equally-good-fits {} --restarts {}"
      " --overlays {} {} --contact-friction {}"
      " --integrator {}",
      o.seed, o.budget, o.effect_budget, o.optimizer, o.max_effects, o.tries_per_round,
      o.min_confidence, o.false_discovery_rate, o.held_out_stretch, o.equally_good_fits,
      o.restarts, o.overlays_per_recording,
      o.simulation.outline_contact ? "--outline-contact" : "--node-contact",
      o.simulation.contact_friction, ToString(o.simulation.integrator));
  line += fmt::format(" --min-drop {}", o.min_relative_drop);  // it changes the decisions
  line += fmt::format(" --refit-candidates {}", o.refit_candidates);  // so does this
  // Only where it is not the default, so that the lines of loops run before
  // the option existed still match.
  if (o.rank_by_rate) line += " --rank-by rate";
  if (o.effect_restarts != 1) line += fmt::format(" --effect-restarts {}", o.effect_restarts);
  if (!o.write_html) line += " --no-html";
  return line;
}

LoopOptions ObjectLoopOptions(const LoopOptions& loop, const FamilyManifest& manifest,
                              const FamilyObject& object, const fs::path& out_dir) {
  LoopOptions o = loop;
  o.train = {manifest.RecordingPath(object, 0)};
  o.holdout.clear();
  for (size_t i = 1; i < object.recordings.size(); ++i)
    o.holdout.push_back(manifest.RecordingPath(object, i));
  o.out_dir = out_dir / "objects" / object.id;
  o.command = LoopCommandLine(o);
  return o;
}

LoopBenchmarkResult RunLoopBenchmark(const LoopBenchmarkOptions& options, const LoopLog& log) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  const FamilyManifest manifest = ReadFamilyManifest(options.family_dir);
  const std::vector<FamilyObject> objects =
      SelectFamilyObjects(manifest, options.only, options.cells, options.limit_per_cell);
  const ObjectLoopRunner run =
      options.run_object ? options.run_object : [](const LoopOptions& o, const LoopLog& l) {
        return RunLoop(o, l).report;
      };

  LoopBenchmarkResult result;
  LoopBenchmarkReport& report = result.report;
  report.family_dir = AbsolutePath(options.family_dir);
  report.family_name = manifest.name;
  report.family_spec = manifest.spec;
  report.family_seed = manifest.seed;
  report.command = options.command;
  for (size_t k = 0; k < objects.size(); ++k) {
    const FamilyObject& object = objects[k];
    if (!object.not_made.empty()) {
      if (log) {
        log(fmt::format("[{}/{}] {}: not made by the generator ({}); left out", k + 1, objects.size(),
                        object.id, object.not_made));
      }
      report.outcomes.push_back(NotMadeObject(object));
      ++result.not_made;
      continue;
    }
    const LoopOptions loop = ObjectLoopOptions(options.loop, manifest, object, options.out_dir);
    // Bad options are the command's error, not every object's.
    if (!loop.IsValid(&error)) throw std::invalid_argument(error);
    std::error_code ec;
    fs::create_directories(loop.out_dir, ec);
    if (ec) {
      throw std::runtime_error(
          fmt::format("{}: cannot create: {}", loop.out_dir.string(), ec.message()));
    }
    ObjectOutcome outcome;
    if (std::optional<LoopReport> earlier =
            EarlierReport(loop.out_dir / "report.json", loop.command, log)) {
      outcome = SummariseObject(object, *earlier);
      outcome.resumed = true;
      ++result.resumed;
    } else {
      if (log) log(fmt::format("[{}/{}] {}: running the loop", k + 1, objects.size(), object.id));
      const auto start = std::chrono::steady_clock::now();
      LoopLog object_log;
      if (log) object_log = [&](const std::string& line) { log(object.id + ": " + line); };
      try {
        outcome = SummariseObject(object, run(loop, object_log));
      } catch (const std::exception& e) {
        const double elapsed =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        outcome = FailedObject(object, e.what(), elapsed);
        ++result.failed;
      }
      ++result.ran;
    }
    json_io::WriteFile(loop.out_dir / "summary.json", ToJson(outcome));
    if (log) {
      log(fmt::format("[{}/{}] {}{}: {}", k + 1, objects.size(), object.id,
                      outcome.resumed ? " (read back)" : "", OutcomeLine(outcome)));
    }
    report.outcomes.push_back(std::move(outcome));
  }
  report.aggregate = AggregateOutcomes(report.outcomes, TracedEffects());
  result.json = options.out_dir / "benchmark.json";
  result.csv = options.out_dir / "benchmark.csv";
  WriteBenchmarkJson(result.json, report);
  WriteBenchmarkCsv(result.csv, report.outcomes);
  ConfidenceRates rates = report.aggregate.confidence_rates;
  rates.family = report.family_name;
  rates.family_spec = report.family_spec;
  rates.family_seed = report.family_seed;
  rates.command = report.command;
  result.confidence_rates = options.out_dir / "confidence_rates.json";
  json_io::WriteFile(result.confidence_rates, ToJson(rates));
  if (options.write_html) {
    result.html = options.out_dir / "benchmark.html";
    WriteBenchmarkHtml(result.html, report, options.html);
  }
  return result;
}

}  // namespace calib
