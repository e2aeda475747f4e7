#pragma once
// The loop benchmark behind `calib loop-benchmark FAMILY_DIR --out DIR`
// (docs/loop.md, "Loop benchmark"): runs the closed loop (loop.h) on every
// object of a family of recordings (family_manifest.h), trained on the
// object's first recording and judged on the others, and measures how often
// it keeps the effect the object has, keeps one it does not have, or keeps
// the effect it can be mistaken for (benchmark_aggregate.h).
//
// Per object the loop writes DIR/objects/<id>/ (report.json, report.html,
// store.sqlite) and the benchmark DIR/objects/<id>/summary.json as soon as
// it finishes; at the end DIR/benchmark.json, DIR/benchmark.csv,
// DIR/benchmark.html and DIR/confidence_rates.json (the first round's
// confidences as rates, with the family and the command: the file
// discovery/confidence_rates.json is, for the tuning family). Resumable: an object whose report.json was made by
// the same `calib loop` command (LoopCommandLine, kept in the report) is
// read back, not rerun. A loop that throws is recorded as that object's
// error, and the benchmark goes on. An object the generator did not make
// (family.json's not_made) is recorded as not made, with its reason.

#include "calib/discovery/benchmark_report.h"
#include "calib/discovery/family_manifest.h"
#include "calib/discovery/loop.h"
#include "calib/discovery/report_html.h"

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace calib {

/// Runs one object's loop (RunLoop by default; tests inject their own). It
/// writes options.out_dir/report.json as RunLoop does, and may throw.
using ObjectLoopRunner = std::function<LoopReport(const LoopOptions& options, const LoopLog& log)>;

struct LoopBenchmarkOptions {
  std::filesystem::path family_dir;  ///< holds family.json
  std::filesystem::path out_dir;     ///< objects/, benchmark.json, .csv, .html
  /// Every object's loop options; train, holdout, out_dir and command are
  /// set per object.
  LoopOptions loop;
  std::vector<std::string> only;   ///< object ids to run (empty: all)
  std::vector<std::string> cells;  ///< cells to run (empty: all)
  int limit_per_cell = 0;          ///< the first N selected objects of each cell; 0: all
  std::string command;             ///< the command line, for the report
  HtmlReportOptions html;
  bool write_html = true;       ///< benchmark.html
  ObjectLoopRunner run_object;  ///< null: RunLoop

  /// False with a message naming the option and the rule (the loop's
  /// options are checked by RunLoop per object).
  bool IsValid(std::string* error) const;
};

struct LoopBenchmarkResult {
  LoopBenchmarkReport report;
  int ran = 0;      ///< objects whose loop ran (failed ones included)
  int resumed = 0;  ///< objects read back from an earlier report.json
  int failed = 0;   ///< objects whose loop threw
  int not_made = 0;  ///< objects the generator did not make (family.json's not_made)
  std::filesystem::path json;
  std::filesystem::path csv;
  std::filesystem::path html;  ///< empty when not written
  std::filesystem::path confidence_rates;
};

/// The objects of `manifest` selected by `only` (ids; an unknown id throws
/// std::invalid_argument naming it), `cells` (likewise) and
/// `limit_per_cell`, in manifest order.
std::vector<FamilyObject> SelectFamilyObjects(const FamilyManifest& manifest,
                                              const std::vector<std::string>& only,
                                              const std::vector<std::string>& cells,
                                              int limit_per_cell);

/// `loop` for one object: train = its first recording, holdout = the
/// others, out_dir = `out_dir`/objects/<id>, command = LoopCommandLine.
LoopOptions ObjectLoopOptions(const LoopOptions& loop, const FamilyManifest& manifest,
                              const FamilyObject& object, const std::filesystem::path& out_dir);

/// The `calib loop` command line that makes the same report as `options`:
/// recordings and out_dir as absolute paths, then every option that
/// changes what the loop computes or writes (not --threads, --cache-dir,
/// --quiet). Two option sets with the same line give the same report
/// numbers; the benchmark compares it with a report's `command` to resume.
std::string LoopCommandLine(const LoopOptions& options);

/// Runs the benchmark. Throws for bad options (std::invalid_argument), a
/// bad manifest (naming the file, object and key) and unwritable outputs;
/// a failing loop is recorded, not thrown.
LoopBenchmarkResult RunLoopBenchmark(const LoopBenchmarkOptions& options, const LoopLog& log = {});

}  // namespace calib
