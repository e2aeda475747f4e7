#!/usr/bin/env bash
# compare-outputs.sh OLD_REV NEW_REV [OUT_DIR] [options]
#
# Behaviour check for a refactoring: builds the `calib` executable of two
# commits and compares what they compute, bit for bit. For each revision:
#
#  - every bundled example job (examples/jobs/*.yaml) with the spec's own
#    budget and seed: `calib run` on a copy of the spec (absolute recording
#    paths, results under OUT_DIR/<hash>/jobs/<name>/, no wall-time limit),
#    then `calib results --json` (every evaluation: id, point, parameters,
#    status, score, IoU summary, reason, attempts, detail; the job's status,
#    canonical spec and report scores) and `calib best`;
#  - every bundled loop pair (train/holdout) with `calib loop` at reduced
#    budgets (--loop-budget, --effect-budget, --restarts; seed 1, no overlays,
#    no HTML): report.json (stages, decisions, scores, hypotheses, residual
#    analyses, kept effects) and the history of every job in its store.sqlite
#    (again through `calib results --store`).
#
# The exports are canonicalised (scripts/canonical-outputs.py): the fields
# that are wall-clock times or worker names (eval_time_s, worker, *_unix_s,
# run_time_s, calibration_time_s, mean/total_eval_time_s, the count of kept
# checkpoints) are removed, and the revision-specific paths (OUT_DIR, the
# commit hash, the binary) replaced by placeholders. Then the two revisions'
# canonical files are compared exactly, file by file (doubles by their
# round-trip text), and a summary says per job and per pair "identical" or
# the first differences. Exit status: 0 all identical, 1 something differs or
# a run failed, 2 bad usage.
#
# Why: issue 21 restructures the code (effect discovery, typed calibration
# requests, effects owning their search boxes) and must leave behaviour
# unchanged: the same seed gives the same histories, best parameters and loop
# decisions. Only the `calib` command line is used, so the two revisions may
# lay out their libraries differently.
#
# Caching: each revision's raw outputs are kept under OUT_DIR/<full hash>/
# (jobs/<name>/, loops/b<budget>-e<effect budget>-r<restarts>-s1/<train>--<holdout>/)
# with a `done` marker; a later run reuses them, so
#   scripts/compare-outputs.sh fef4a9b NEWREV /work/compare
# builds and runs only NEWREV. Thread counts are not part of the key (the
# history is the same at any thread count). Delete a folder to redo it.
# Sources go to OUT_DIR/src-<full hash> (a detached git worktree) and build
# into its build/ folder (Release, calib target only, ccache when installed),
# reused when present. Segmentation caches: OUT_DIR/<hash>/segmentation-cache.
#
# Runtime per revision at the defaults (2 threads), plus the build: about 11
# minutes of CPU (fef4a9b: the example job 2.4 min and the seven pairs 18 min
# wall on a 2-core machine shared with other builds; less on idle cores).
#
# The small-budget version of this check is in the test suite:
# tests/jobs/golden_test.cpp against tests/golden/*.json. After a deliberate
# change of behaviour (e.g. of the score), regenerate those goldens with
#   scripts/update-golden.sh            (or: CALIB_UPDATE_GOLDEN=1 build/tests/jobs_golden_test)
# and commit them with the change that explains them.
set -euo pipefail

usage() {
  sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'
  cat <<'EOF'
Options:
  --loop-budget N     evaluations of each base-model search in the loop (default 48)
  --effect-budget N   evaluations of each effect's calibration (default 48)
  --restarts N        independent base-model searches (default 2)
  --threads N         OpenMP threads of every run (default 2)
  --only jobs|loops   compare only the example jobs, or only the loop pairs
  --pairs a,b         only these loop pairs (by training recording, or train/holdout)
  --jobs N            parallel compile jobs of the builds (default: nproc)
  -h, --help          this text
Default OUT_DIR: out/compare under the repository root.
EOF
}

# The bundled loop pairs: training recording / held-out recording (examples/).
ALL_PAIRS=(
  push_centre/push_offset
  push_plastic/push_plastic_offset
  push_uneven/push_uneven_offset
  push_stiffening/push_stiffening_offset
  push_viscoelastic/push_viscoelastic_offset
  push_friction/push_friction_offset
  hang_gravity/hang_gravity_b
)

loop_budget=48
effect_budget=48
restarts=2
seed=1
threads=2
only=""
pairs_filter=""
build_jobs=$(nproc)
positional=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --loop-budget) loop_budget=$2; shift 2 ;;
    --effect-budget) effect_budget=$2; shift 2 ;;
    --restarts) restarts=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    --only) only=$2; shift 2 ;;
    --pairs) pairs_filter=$2; shift 2 ;;
    --jobs) build_jobs=$2; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    -*) echo "compare-outputs.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
    *) positional+=("$1"); shift ;;
  esac
done
if [[ ${#positional[@]} -lt 2 || ${#positional[@]} -gt 3 ]]; then
  echo "usage: compare-outputs.sh OLD_REV NEW_REV [OUT_DIR] [options] (see --help)" >&2
  exit 2
fi
if [[ -n "$only" && "$only" != jobs && "$only" != loops ]]; then
  echo "compare-outputs.sh: --only $only: expected jobs or loops" >&2
  exit 2
fi
for n in "$loop_budget" "$effect_budget" "$restarts" "$threads" "$build_jobs"; do
  [[ "$n" =~ ^[0-9]+$ ]] || { echo "compare-outputs.sh: '$n' is not a number" >&2; exit 2; }
done

repo=$(git -C "$(dirname "$0")" rev-parse --show-toplevel)
canon_py="$repo/scripts/canonical-outputs.py"
python=python3
[[ -x /usr/bin/python3 ]] && python=/usr/bin/python3   # Debian's, with python3-yaml
out_root=$(realpath -m "${positional[2]:-$repo/out/compare}")
mkdir -p "$out_root"
loop_key="b${loop_budget}-e${effect_budget}-r${restarts}-s${seed}"

pairs=()
for p in "${ALL_PAIRS[@]}"; do
  if [[ -n "$pairs_filter" ]]; then
    IFS=, read -ra wanted <<<"$pairs_filter"
    keep=0
    for w in "${wanted[@]}"; do [[ "$w" == "${p%%/*}" || "$w" == "$p" ]] && keep=1; done
    [[ $keep == 1 ]] || continue
  fi
  pairs+=("$p")
done
if [[ -n "$pairs_filter" && ${#pairs[@]} -eq 0 ]]; then
  echo "compare-outputs.sh: --pairs $pairs_filter matches no pair (${ALL_PAIRS[*]})" >&2
  exit 2
fi

log() { echo "[compare $(date +%H:%M:%S)] $*" >&2; }

# --- one revision --------------------------------------------------------

# Sets src and calib for revision $1 (a full hash): the worktree and the
# built executable. Called only when something must run.
prepare_revision() {
  local hash=$1
  src="$out_root/src-$hash"
  if [[ ! -d "$src" ]]; then
    log "worktree $src"
    git -C "$repo" worktree add --detach "$src" "$hash" >/dev/null 2>&1 ||
      git -C "$repo" worktree add --detach "$src" "$hash"
  fi
  if [[ "$(git -C "$src" rev-parse HEAD)" != "$hash" ]]; then
    echo "compare-outputs.sh: $src is not at $hash" >&2
    exit 1
  fi
  local launcher=()
  if command -v ccache >/dev/null; then
    launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
    export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$out_root}
  fi
  if [[ ! -f "$src/build/CMakeCache.txt" ]]; then
    log "configure $src/build"
    cmake -S "$src" -B "$src/build" -DCMAKE_BUILD_TYPE=Release -DCALIB_BUILD_TESTS=OFF \
      -DCALIB_BUILD_BENCHMARKS=OFF "${launcher[@]}" >"$src/build-configure.log" 2>&1 ||
      { tail -30 "$src/build-configure.log" >&2; exit 1; }
  fi
  log "build calib of ${hash:0:12} (log: $src/build.log)"
  nice cmake --build "$src/build" --target calib -j"$build_jobs" >"$src/build.log" 2>&1 ||
    { tail -30 "$src/build.log" >&2; exit 1; }
  calib="$src/build/apps/calib"
  if [[ ! -x "$calib" ]]; then  # another layout: whatever the calib target built
    calib=$(find "$src/build" -type f -name calib -perm -u+x | head -1)
  fi
  [[ -x "$calib" ]] || { echo "compare-outputs.sh: no calib executable in $src/build" >&2; exit 1; }
}

# Writes paths.json: what canonical-outputs.py replaces in this unit's outputs.
write_paths() {
  printf '{"out": "%s", "rev": "%s", "calib": "%s"}\n' "$out_root" "$1" "$calib" >"$2/paths.json"
}

# run_job HASH SPEC_REL: the example job at SPEC_REL (in the revision's tree).
run_job() {
  local hash=$1 rel=$2 name dir spec
  name=$(basename "$rel"); name=${name%.*}
  dir="$out_root/$hash/jobs/$name"
  if [[ -f "$dir/done" ]]; then log "${hash:0:12} job $name: cached"; return; fi
  [[ -n "${calib:-}" ]] || prepare_revision "$hash"
  rm -rf "$dir"; mkdir -p "$dir"
  spec="$dir/spec.json"
  "$python" "$canon_py" make-spec "$src/$rel" "$spec" --store "$dir/store.sqlite" --out-dir "$dir/report"
  log "${hash:0:12} job $name: calib run ($threads threads)"
  local t0=$SECONDS
  if ! "$calib" run "$spec" --threads "$threads" --progress none --no-video \
      --cache-dir "$out_root/$hash/segmentation-cache" >"$dir/run.log" 2>&1; then
    tail -20 "$dir/run.log" >&2
    echo "compare-outputs.sh: ${hash:0:12} job $name: calib run failed (log: $dir/run.log)" >&2
    return 1
  fi
  "$calib" results "$spec" --json "$dir/results.json" >"$dir/results.txt"
  "$calib" best "$spec" --out "$dir/best.json" >/dev/null
  write_paths "$hash" "$dir"
  echo "threads=$threads seconds=$((SECONDS - t0))" >"$dir/done"
  log "${hash:0:12} job $name: done in $((SECONDS - t0)) s"
}

# run_pair HASH TRAIN/HOLDOUT: calib loop on the pair.
run_pair() {
  local hash=$1 pair=$2 train holdout dir
  train=${pair%%/*}; holdout=${pair##*/}
  dir="$out_root/$hash/loops/$loop_key/$train--$holdout"
  if [[ -f "$dir/done" ]]; then log "${hash:0:12} loop $pair: cached"; return; fi
  [[ -n "${calib:-}" ]] || prepare_revision "$hash"
  rm -rf "$dir"; mkdir -p "$dir/store"
  log "${hash:0:12} loop $pair: calib loop ($loop_key, $threads threads)"
  local t0=$SECONDS
  if ! "$calib" loop --train "$src/examples/$train" --holdout "$src/examples/$holdout" \
      --out "$dir/out" --budget "$loop_budget" --effect-budget "$effect_budget" \
      --restarts "$restarts" --seed "$seed" --overlays 0 --no-html --threads "$threads" \
      --cache-dir "$out_root/$hash/segmentation-cache" --quiet >"$dir/loop.log" 2>&1; then
    tail -20 "$dir/loop.log" >&2
    echo "compare-outputs.sh: ${hash:0:12} loop $pair: calib loop failed (log: $dir/loop.log)" >&2
    return 1
  fi
  "$python" "$canon_py" store-jobs "$dir/out/store.sqlite" >"$dir/store-jobs.txt"
  local job
  while read -r job; do
    "$calib" results "$job" --store "$dir/out/store.sqlite" --json "$dir/store/$job.json" >/dev/null
  done <"$dir/store-jobs.txt"
  write_paths "$hash" "$dir"
  echo "threads=$threads seconds=$((SECONDS - t0))" >"$dir/done"
  log "${hash:0:12} loop $pair: done in $((SECONDS - t0)) s"
}

# The example jobs of a revision (paths relative to its tree), from git.
job_specs() {
  git -C "$repo" ls-tree --name-only "$1" examples/jobs/ | grep -E '\.(yaml|yml|json)$' || true
}

failed=0
run_revision() {
  local hash=$1 rel pair
  src="" calib=""
  if [[ "$only" != loops ]]; then
    for rel in $(job_specs "$hash"); do run_job "$hash" "$rel" || failed=1; done
  fi
  if [[ "$only" != jobs ]]; then
    for pair in "${pairs[@]}"; do run_pair "$hash" "$pair" || failed=1; done
  fi
}

old=$(git -C "$repo" rev-parse --verify "${positional[0]}^{commit}")
new=$(git -C "$repo" rev-parse --verify "${positional[1]}^{commit}")
start=$SECONDS
run_revision "$old"
run_revision "$new"

# --- compare -------------------------------------------------------------

echo
echo "OLD ${positional[0]} = $old"
echo "NEW ${positional[1]} = $new"
echo "outputs: $out_root/{${old:0:12}...,${new:0:12}...}; threads $threads"
differ=0
# compare_unit LABEL KIND OLD_RAW NEW_RAW
compare_unit() {
  local label=$1 kind=$2 a=$3 b=$4
  if [[ ! -f "$a/done" || ! -f "$b/done" ]]; then
    echo "$label: MISSING ($([[ -f "$a/done" ]] || echo "OLD ")$([[ -f "$b/done" ]] || echo "NEW")run failed or absent)"
    differ=1
    return
  fi
  "$python" "$canon_py" "canonical-$kind" "$a" "$a/canonical"
  "$python" "$canon_py" "canonical-$kind" "$b" "$b/canonical"
  "$python" "$canon_py" compare "$label" "$a/canonical" "$b/canonical" || differ=1
}
if [[ "$only" != loops ]]; then
  echo "== example jobs (the spec's budget and seed) =="
  for name in $( (job_specs "$old"; job_specs "$new") | xargs -rn1 basename | sed 's/\.[^.]*$//' | sort -u); do
    compare_unit "job $name" job "$out_root/$old/jobs/$name" "$out_root/$new/jobs/$name"
  done
fi
if [[ "$only" != jobs ]]; then
  echo "== loop pairs (--budget $loop_budget --effect-budget $effect_budget --restarts $restarts --seed $seed) =="
  for pair in "${pairs[@]}"; do
    d="loops/$loop_key/${pair%%/*}--${pair##*/}"
    compare_unit "loop $pair" loop "$out_root/$old/$d" "$out_root/$new/$d"
  done
fi
echo
if [[ $differ == 0 && $failed == 0 ]]; then
  echo "RESULT: identical ($((SECONDS - start)) s)"
  exit 0
fi
echo "RESULT: DIFFERENT or failed ($((SECONDS - start)) s); canonical files: <unit>/canonical/ under each revision's folder"
exit 1
