#!/usr/bin/env bash
# Regenerates the bundled synthetic recordings: examples/NAME from
# examples/scenarios/NAME.yaml with `calib synth`, for every scenario or for
# the NAMEs given. Each folder's old files are replaced. Prints the time and
# size `calib synth` reports for each, and the size of examples/ at the end.
#
#   scripts/make-examples.sh                      # all of them
#   scripts/make-examples.sh push_centre push_offset
#   CALIB=build-release/apps/calib scripts/make-examples.sh
#
# Uses $CALIB (default build/apps/calib); build it first (scripts/build.sh).
# The same scenario gives the same truth, track.csv and truth.json; the H.264
# bits of video.mp4 may differ between encoder builds.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/calib-exe.sh
if [[ $# -gt 0 ]]; then
  names=("$@")
else
  names=()
  for f in examples/scenarios/*.yaml; do names+=("$(basename "$f" .yaml)"); done
fi
for name in "${names[@]}"; do
  scenario=examples/scenarios/$name.yaml
  if [[ ! -f "$scenario" ]]; then
    echo "make-examples.sh: $scenario: no such scenario" >&2
    exit 2
  fi
  echo "== $name"
  "$calib" synth "$scenario" --out "examples/$name"
done
du -sh examples
