#!/usr/bin/env bash
# README command A: installs, builds and runs the main job on the bundled
# example: calibrates the model on the centre-push recording
# (examples/push_centre) with CMA-ES on every core, predicts the held-out
# offset push (examples/push_offset), and prints where the best parameters,
# the overlay videos and the summary are (out/jobs/push_centre_cmaes/).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
job=examples/jobs/push_centre_cmaes.yaml
# Each run of command A starts the job afresh (`calib resume $job` continues
# an interrupted one instead).
rm -rf out/jobs/push_centre_cmaes.sqlite* out/jobs/push_centre_cmaes
./build/apps/calib run "$job"
echo
./build/apps/calib results "$job"
