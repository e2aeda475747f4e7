#!/usr/bin/env bash
# README command B: installs, builds and runs the whole test suite (ctest).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh -DCALIB_WERROR=ON
cd build
ctest --output-on-failure -j"$(nproc)" --timeout 600
