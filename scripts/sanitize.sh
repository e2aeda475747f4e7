#!/usr/bin/env bash
# Sanitizer runs of the test suite (docs/reliability.md, "Sanitizers").
#
#   scripts/sanitize.sh address   # AddressSanitizer + UndefinedBehaviorSanitizer
#                                 # (build-asan/): the whole suite but the long
#                                 # loop tests
#   scripts/sanitize.sh thread    # ThreadSanitizer (build-tsan/): the runner's,
#                                 # pruning's and the MPI manager's tests
#   scripts/sanitize.sh address --ci   # CI's reduced sets (.ci/run): the same
#   scripts/sanitize.sh thread --ci    # builds, fewer tests (see below)
#
# Builds are -O1 (AddressSanitizer's advice, and half the compile time of
# -O3). Any finding fails the run (exit status non-zero): undefined
# behaviour and data races abort instead of printing and going on. An extra
# argument is a gtest filter (address, e.g. 'Runner*') or goes to ctest
# (thread, e.g. -R Runner).
set -euo pipefail
cd "$(dirname "$0")/.."
root="$PWD"
kind="${1:?usage: scripts/sanitize.sh address|thread [--ci] [ctest arguments]}"
shift
ci=0
if [[ "${1:-}" == "--ci" ]]; then
  ci=1
  shift
fi

# The loop tests that take minutes each at full speed (an hour and more
# under AddressSanitizer), as gtest filters: the loop's code runs under the
# sanitizer in every other loop test
# (Loop.TheSimulationReachesTheStoredJobsAndTheReport,
# GoldenTest.LoopOnPushCentreAtATinyBudget, LoopBenchmarkCli, ...).
long_tests='*LoopOnSyntheticEffect*:Loop.AddsNothing*:Loop.EquallyGoodFitsMeasure*:Loop.RestartsKeep*:Loop.EffectRestarts*:Loop.SameSeed*:ExternalPairs.*:FamilyBenchmark.*'
# CI leaves out, besides, the tests that run whole loops or a loop benchmark
# through the command line (minutes each instrumented) but one,
# Loop.TheSimulationReachesTheStoredJobsAndTheReport, which runs the loop's
# stages, its store and its report instrumented; and the multi-host test,
# whose ranks run in network namespaces and which CI runs uninstrumented.
# And the rest shape tracked through a whole real recording (1074 frames:
# 4 s at full speed, 2 minutes instrumented), whose tracking and estimate
# run instrumented in ShapeTracking.* and ObjectTransferTest.*.
if ((ci)); then
  long_tests="$long_tests:GoldenTest.LoopOnPushCentre*:LoopBenchmarkCli.*:Loop.AResumedLoop*:LoopCli.*"
  long_tests="$long_tests:RealRecordingMotion.*"
fi
# The tests that start MPI jobs (with the tests that are not gtest cases:
# the scripts' and the command line's, run by ctest), each program's with
# the allocation stacks unwound the slow way (below).
mpi_tests='JobCli.ThreeMpiRanks*:Service.AJobOnMpiHosts*:ServiceKinds.AComparisonOnMpiHosts*'

bash scripts/install-deps.sh
jobs="$(nproc)"
case "$kind" in
  address)
    build=build-asan
    cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS_RELEASE="-O1 -DNDEBUG" -DCMAKE_UNITY_BUILD=ON \
      -DCALIB_WERROR=ON -DCALIB_SANITIZE=address,undefined -DCALIB_BUILD_BENCHMARKS=OFF >/dev/null
    cmake --build "$build" -j"$jobs"
    # allocator_may_return_null: an allocation too large throws std::bad_alloc
    # as without the sanitizer (the tests of absurd sizes expect the named
    # error). Leaks are findings too, except those of libraries outside the
    # project (scripts/lsan.supp says which and why).
    asan="detect_leaks=1:allocator_may_return_null=1:strict_string_checks=1:detect_stack_use_after_return=1"
    export LSAN_OPTIONS="suppressions=$root/scripts/lsan.supp:print_suppressions=0"
    export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
    # Open MPI unloads its components at MPI_Finalize: kept loaded, their
    # leaks have names that scripts/lsan.supp can match.
    export OMPI_MCA_mca_base_component_disable_dlclose=1
    export CALIB_SHARED_DIR
    CALIB_SHARED_DIR="$(cd "$root/.." && pwd)/shared"

    # Each test program runs once with all its cases (ctest starts one
    # process per case: with the sanitizer's start-up, about a second for a
    # program that links OpenCV, that was most of the run), the longest
    # first (docs/reliability.md, "Sanitizers"), as many at a time as there
    # are cores. Allocation stacks are unwound the fast way (frame pointers),
    # which is 3 to 6 times quicker, except where the leak suppressions must
    # see frames of libraries that have none: the MPI tests (Open MPI), and
    # the recording and media tests (evaluator_recording_test), whose
    # missing and unreadable videos make OpenCV try its GStreamer and camera
    # backends (scripts/lsan.supp).
    logs="$root/$build/sanitize-logs"
    rm -rf "$logs"
    mkdir -p "$logs"
    first=(jobs_job_cli_test evaluator_test service_test discovery_loop_test jobs_test
           synth_test jobs_golden_test jobs_commands_cli_test search_test core_test)
    mapfile -t programs < <(
      printf '%s\n' "${first[@]}"
      find "$build/tests" -maxdepth 1 -type f -executable -name '*_test' -printf '%f\n' | sort)
    filter="${1:-*}"
    status=0
    run() {  # program, gtest filter, fast unwinding (0 or 1), log name
      local log="$logs/$4.log"
      if (cd "$build/tests" &&
          ASAN_OPTIONS="$asan:fast_unwind_on_malloc=$3" timeout 1800 "./$1" \
            --gtest_filter="$2" >"$log" 2>&1); then
        echo "passed  $4 ($(grep -c '^\[       OK \]' "$log") tests)"
      else
        echo "FAILED  $4: $log"
        tail -n 60 "$log"
        return 1
      fi
    }
    declare -A seen=() fast=([evaluator_recording_test]=0)
    for program in "${programs[@]}"; do
      [[ -n "${seen[$program]:-}" || ! -x "$build/tests/$program" ]] && continue
      seen[$program]=1
      while (($(jobs -rp | wc -l) >= jobs)); do wait -n || status=1; done
      run "$program" "$filter-$long_tests:$mpi_tests" "${fast[$program]:-1}" "$program" &
    done
    while (($(jobs -rp | wc -l) > 0)); do wait -n || status=1; done
    run jobs_job_cli_test "$mpi_tests" 0 jobs_job_cli_test.mpi || status=1
    run service_test "$mpi_tests" 0 service_test.mpi || status=1
    run service_kinds_test "$mpi_tests" 0 service_kinds_test.mpi || status=1
    if [[ "$filter" == "*" ]]; then
      # The command line's and the scripts' tests (not gtest cases).
      exclude='^$'
      ((ci)) && exclude='^Mpi\.AHostDies'
      ASAN_OPTIONS="$asan:fast_unwind_on_malloc=0" ctest --test-dir "$build" \
        --output-on-failure -j"$jobs" --timeout 1800 -LE gtest -E "$exclude" || status=1
    fi
    exit "$status"
    ;;
  thread)
    build=build-tsan
    cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS_RELEASE="-O1 -DNDEBUG" -DCMAKE_UNITY_BUILD=ON \
      -DCALIB_WERROR=ON -DCALIB_SANITIZE=thread -DCALIB_BUILD_BENCHMARKS=OFF >/dev/null
    # CI: the runner's and pruning's tests in one process (threads), not the
    # MPI run through the command line, which needs every library and the
    # program built instrumented.
    targets=(jobs_runner_test jobs_pruning_test)
    tests='^(Runner|Progress|PruneBounds|RecordingObjectivePruning)'
    if ((!ci)); then
      targets+=(calib jobs_job_cli_test)
      tests='^(Runner|Progress|PruneBounds|RecordingObjectivePruning|JobCli\.ThreeMpiRanks)'
    fi
    cmake --build "$build" -j"$jobs" --target "${targets[@]}"
    # libgomp is not built with ThreadSanitizer: its barriers are invisible
    # to it (scripts/tsan.supp says which reports that suppresses).
    export TSAN_OPTIONS="suppressions=$root/scripts/tsan.supp:halt_on_error=1:second_deadlock_stack=1"
    export OMP_WAIT_POLICY=passive
    ctest --test-dir "$build" --output-on-failure -j"$jobs" --timeout 1800 -R "$tests" "$@"
    ;;
  *)
    echo "scripts/sanitize.sh: unknown sanitizer '$kind' (address or thread)" >&2
    exit 2
    ;;
esac
