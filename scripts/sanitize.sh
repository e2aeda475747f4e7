#!/usr/bin/env bash
# Sanitizer runs of the test suite (docs/reliability.md, "Sanitizers"; not
# in CI: their builds do not fit its time beside command B yet).
#
#   scripts/sanitize.sh address   # AddressSanitizer + UndefinedBehaviorSanitizer
#                                 # (build-asan/): the whole suite but the long
#                                 # loop tests
#   scripts/sanitize.sh thread    # ThreadSanitizer (build-tsan/): the runner's,
#                                 # pruning's and the MPI manager's tests
#
# Any finding fails the run (exit status non-zero): undefined behaviour and
# data races abort instead of printing and going on. Extra arguments go to
# ctest (e.g. -R Runner).
set -euo pipefail
cd "$(dirname "$0")/.."
root="$PWD"
kind="${1:?usage: scripts/sanitize.sh address|thread [ctest arguments]}"
shift

# The loop tests that take minutes each at full speed (an hour and more
# under AddressSanitizer): the loop's code runs under the sanitizer in every
# other loop test (Loop.TheSimulationReachesTheStoredJobsAndTheReport,
# GoldenTest.LoopOnPushCentreAtATinyBudget, LoopBenchmarkCli, ...).
long_tests='LoopOnSyntheticEffect|Loop\.(AddsNothing|EquallyGoodFitsMeasure|RestartsKeep|SameSeed)|ExternalPairs|FamilyBenchmark'

bash scripts/install-deps.sh
jobs="$(nproc)"
case "$kind" in
  address)
    build=build-asan
    cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DCALIB_WERROR=ON \
      -DCALIB_SANITIZE=address,undefined -DCALIB_BUILD_BENCHMARKS=OFF >/dev/null
    cmake --build "$build" -j"$jobs"
    # allocator_may_return_null: an allocation too large throws std::bad_alloc
    # as without the sanitizer (the tests of absurd sizes expect the named
    # error). Leaks are findings too, except those of libraries outside the project
    # (scripts/lsan.supp says which and why).
    export ASAN_OPTIONS="detect_leaks=1:allocator_may_return_null=1:strict_string_checks=1:detect_stack_use_after_return=1:fast_unwind_on_malloc=0"
    export LSAN_OPTIONS="suppressions=$root/scripts/lsan.supp:print_suppressions=0"
    export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
    # Open MPI unloads its components at MPI_Finalize: kept loaded, their
    # leaks have names that scripts/lsan.supp can match.
    export OMPI_MCA_mca_base_component_disable_dlclose=1
    ctest --test-dir "$build" --output-on-failure -j"$jobs" --timeout 1800 -E "$long_tests" "$@"
    ;;
  thread)
    build=build-tsan
    cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DCALIB_WERROR=ON \
      -DCALIB_SANITIZE=thread -DCALIB_BUILD_BENCHMARKS=OFF >/dev/null
    cmake --build "$build" -j"$jobs" --target calib jobs_runner_test jobs_job_cli_test \
      jobs_pruning_test
    # libgomp is not built with ThreadSanitizer: its barriers are invisible
    # to it (scripts/tsan.supp says which reports that suppresses).
    export TSAN_OPTIONS="suppressions=$root/scripts/tsan.supp:halt_on_error=1:second_deadlock_stack=1"
    export OMP_WAIT_POLICY=passive
    ctest --test-dir "$build" --output-on-failure -j"$jobs" --timeout 1800 \
      -R '^(Runner|Progress|PruneBounds|RecordingObjectivePruning|JobCli\.ThreeMpiRanks)' "$@"
    ;;
  *)
    echo "scripts/sanitize.sh: unknown sanitizer '$kind' (address or thread)" >&2
    exit 2
    ;;
esac
