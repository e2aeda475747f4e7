#!/usr/bin/env bash
# Regenerates the golden files of the golden regression test
# (tests/jobs/golden_test.cpp -> tests/golden/*.json) from the current code:
# builds the test and the calib executable into build/ (or $BUILD_DIR) and
# runs the test with CALIB_UPDATE_GOLDEN=1, which rewrites the goldens
# instead of comparing. Do this only for a deliberate change of behaviour
# (e.g. of the score), check `git diff tests/golden`, and commit the goldens
# with the change that explains them. A refactoring must leave them as they are.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${BUILD_DIR:-build}
if [[ ! -f "$build/CMakeCache.txt" ]]; then
  launcher=()
  command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DCALIB_BUILD_TESTS=ON "${launcher[@]}" >/dev/null
fi
cmake --build "$build" --target jobs_golden_test calib -j"$(nproc)"
CALIB_UPDATE_GOLDEN=1 "$build/tests/jobs_golden_test"
git status --short tests/golden
