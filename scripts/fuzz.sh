#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/) with clang in build-fuzz/ and runs
# each for RUNS executions (default 1000000), starting from the seed corpus
# fuzz/corpus/<target>/. docs/reliability.md, "Fuzzing", has the figures.
#
#   scripts/fuzz.sh                      # every target, 10^6 executions each
#   scripts/fuzz.sh fuzz_track_csv 20000 # one target
#
# New inputs the fuzzer finds go to build-fuzz/corpus/<target>/ (the seeds in
# the repository stay as they are); a crashing input goes to
# build-fuzz/artifacts/<target>/ and the run of that target stops there.
# Environment: FUZZ_MAX_TIME=<seconds> also stops each target after that
# long (default: no limit); FUZZ_JOBS=<n> build jobs (default: nproc).
# Exit status: 0 when no target crashed, 1 otherwise.
set -euo pipefail
cd "$(dirname "$0")/.."

target="${1:-all}"
runs="${2:-1000000}"
build=build-fuzz
all_targets=(fuzz_recording_json fuzz_track_csv fuzz_job_spec fuzz_parameter_file
             fuzz_segmentation_cache fuzz_checkpoint fuzz_request_body)

# The largest input worth trying per target: a few times its largest seed.
max_len() {
  case "$1" in
    fuzz_parameter_file | fuzz_segmentation_cache) echo 1024 ;;
    *) echo 4096 ;;
  esac
}

if [ "$target" = all ]; then
  targets=("${all_targets[@]}")
else
  targets=("$target")
fi

# clang is needed for this build only (scripts/install-deps.sh installs what
# the default GCC build, the tests and calib need).
if ! command -v clang++ >/dev/null; then
  echo "fuzz.sh: clang++ not found; on Debian 12: apt-get install clang libclang-rt-dev" >&2
  exit 2
fi

launcher=()
if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
  -DCALIB_FUZZ=ON -DCALIB_BUILD_TESTS=OFF -DCALIB_BUILD_BENCHMARKS=OFF "${launcher[@]}" >/dev/null
cmake --build "$build" -j"${FUZZ_JOBS:-$(nproc)}" --target "${targets[@]}"

status=0
summary=()
for t in "${targets[@]}"; do
  mkdir -p "$build/corpus/$t" "$build/artifacts/$t"
  log="$build/$t.log"
  echo "== $t: $runs executions, -max_len=$(max_len "$t")"
  start=$(date +%s)
  before=$(find "$build/artifacts/$t" -type f | wc -l)
  rc=0
  "$build/fuzz/$t" -runs="$runs" -max_len="$(max_len "$t")" -timeout=10 -rss_limit_mb=2048 \
    -max_total_time="${FUZZ_MAX_TIME:-0}" -print_final_stats=1 \
    -artifact_prefix="$build/artifacts/$t/" "$build/corpus/$t" "fuzz/corpus/$t" >"$log" 2>&1 ||
    rc=$?
  seconds=$(($(date +%s) - start))
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  crashes=$(($(find "$build/artifacts/$t" -type f | wc -l) - before))
  line="$t: ${execs:-?} executions in ${seconds} s, exit $rc, $crashes new crash input(s)"
  if [ "$crashes" -gt 0 ]; then line="$line in $build/artifacts/$t/"; fi
  echo "$line"
  if [ "$rc" -ne 0 ]; then
    status=1
    grep -E "ERROR: |unexpected exception|SUMMARY|accepted an|deadly signal" "$log" | head -5 || true
    echo "(full log: $log)"
  fi
  summary+=("$line")
done
echo "== summary"
printf '%s\n' "${summary[@]}"
exit "$status"
