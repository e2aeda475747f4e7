#!/usr/bin/env bash
# README command A: installs, builds and runs the main job on the bundled
# example (examples/push_centre): mesh it, simulate it with a parameter file
# and score it, writing the overlay video and the per-frame CSV to out/example.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
out=out/example
./build/apps/calib mesh examples/push_centre --out "$out"
./build/apps/calib simulate examples/push_centre --params examples/params_push.json \
  --out "$out" --png-frames 0,120,200
./build/apps/calib score examples/push_centre --params examples/params_push.json
