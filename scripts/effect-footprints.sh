#!/usr/bin/env bash
# The footprint of each bundled synthetic recording's effects in pixels: the
# recording (examples/NAME) against its twin made from the same scenario with
# the effects switched off (`calib synth --without-effects`: same scene,
# camera, noise and seed), compared frame by frame (`calib compare`). Set it
# beside a calibrated model's residual: an effect whose footprint is a small
# share of the residual cannot be told from the base model's own mismatch.
#
#   scripts/effect-footprints.sh                        # every scenario with effects
#   scripts/effect-footprints.sh push_plastic push_plastic_offset
#   CALIB=build-release/apps/calib OUT=/tmp/twins scripts/effect-footprints.sh
#
# Uses $CALIB (default build/apps/calib; build it first with scripts/build.sh).
# Twins go to $OUT (default a temporary folder, removed at the end). Prints one
# line per recording: its effects, the XOR sum against the twin, its share of
# the object's pixels, and the frame where the two differ most. About a minute
# per recording on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/calib-exe.sh
out=${OUT:-}
if [[ -z "$out" ]]; then
  out=$(mktemp -d)
  trap 'rm -rf "$out"' EXIT
fi
if [[ $# -gt 0 ]]; then
  names=("$@")
else
  names=()
  for f in examples/scenarios/*.yaml; do
    grep -q '^effects:' "$f" && names+=("$(basename "$f" .yaml)")
  done
fi
printf '%-26s %-20s %12s %8s  %s\n' recording effects "XOR vs twin" "share" "largest frame"
for name in "${names[@]}"; do
  scenario=examples/scenarios/$name.yaml
  if [[ ! -f "$scenario" || ! -f examples/$name/recording.json ]]; then
    echo "effect-footprints.sh: $name: no scenario $scenario or recording examples/$name" >&2
    exit 2
  fi
  "$calib" synth "$scenario" --without-effects --out "$out/$name" > /dev/null
  # The twin's notes end "[effects switched off: ...]" (calib synth).
  effects=$(grep -o 'effects switched off: [^]]*' "$out/$name/recording.json" | sed 's/effects switched off: //; s/, /,/g')
  if [[ "$effects" == "none were on" ]]; then
    printf '%-26s %-20s %12s\n' "$name" "-" "(no effect to switch off: a hang's inertia is the scene's own)"
    continue
  fi
  "$calib" compare "examples/$name" "$out/$name" --csv "$out/$name.csv" > "$out/$name.txt"
  xor=$(sed -n 's/^difference (XOR pixels summed over frames): //p' "$out/$name.txt")
  largest=$(sed -n 's/^largest at //p' "$out/$name.txt")
  object=$(awk -F, 'NR > 1 { s += $5 } END { print s }' "$out/$name.csv")
  printf '%-26s %-20s %12s %7.2f%%  %s\n' "$name" "$effects" "$xor" "$(awk -v x="$xor" -v o="$object" 'BEGIN { print 100 * x / o }')" "$largest"
done
