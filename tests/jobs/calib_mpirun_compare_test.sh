#!/usr/bin/env bash
# scripts/calib-mpirun.sh --compare: an optimiser comparison whose launch
# fails mid-run (its process killed, as when a host dies) is continued by the
# launcher, and ends with the numbers of an uninterrupted comparison.
#
# mpirun is a stand-in (MPIRUN) that runs the command as one process: the
# first launch of the comparison is killed with SIGKILL once its second run
# has recorded some evaluations; probes answer. The ranks themselves are
# tested by JobCli.ThreeMpiRanksCompareOptimizersAsThreadsDo.
#   calib_mpirun_compare_test.sh CALIB_EXE WORK_DIR
set -uo pipefail
repo="$(cd "$(dirname "$0")/../.." && pwd)"
calib=$(realpath "${1:?usage: calib_mpirun_compare_test.sh CALIB_EXE WORK_DIR}")
work=${2:?usage: calib_mpirun_compare_test.sh CALIB_EXE WORK_DIR}
rm -rf "$work"
mkdir -p "$work"
work=$(realpath "$work")

cat >"$work/compare.yaml" <<YAML
name: launcher_compare
train: [$repo/examples/push_centre]
model:
  substeps: 4
  mesh: {edge_length_px: 40}
parameters:
  - {name: k_D,   lower: 10,   upper: 5000, scale: log}
  - {name: k_d,   lower: 0.01, upper: 50,   scale: log}
  - {name: k_A,   lower: 1,    upper: 5000, scale: log}
  - {name: k_phi, lower: 0.1,  upper: 1000, scale: log}
  - {name: mass,  fixed: 0.2}
  - {name: tau,   lower: 0,    upper: 0.5}
budget: {evaluations: 48}
optimizers:
  - {name: random}
  - {name: nlopt:SBPLX}
seeds: [1, 2]
checkpoint: {every_evaluations: 4, every_seconds: 0}
YAML

cat >"$work/mpirun" <<'SH'
#!/usr/bin/env bash
# Stand-in for mpirun: drops its options, runs the command as one process.
while [[ $# -gt 0 && $1 != -np ]]; do shift; done
shift 2
case " $* " in
  *" --status "*|*" true "*) exec "$@" ;;
esac
if [[ -e "$WORK/launched" ]]; then exec "$@"; fi
touch "$WORK/launched"
"$@" &
pid=$!
# Killed once the second run (random seed 2) has 8 evaluations or more.
for ((t = 0; t < 1200; ++t)); do
  n=$("$CALIB" compare-optimizers "$WORK/compare.yaml" --out "$WORK/launched-out" --status 2>/dev/null |
      awk -F', ' '/^random seed 2 / {print $(NF)+0}')
  [[ ${n:-0} -ge 8 ]] && break
  kill -0 "$pid" 2>/dev/null || break
  sleep 0.1
done
echo "${n:-0}" >"$WORK/killed-after"
kill -KILL "$pid"
wait "$pid"
exit 137
SH
chmod +x "$work/mpirun"

"$calib" compare-optimizers "$work/compare.yaml" --out "$work/threads" --threads 2 --progress none \
  >"$work/threads.log" 2>&1 || { cat "$work/threads.log"; exit 1; }

status=0
WORK="$work" CALIB="$calib" MPIRUN="$work/mpirun" bash "$repo/scripts/calib-mpirun.sh" \
  --hosts localhost:3 --compare "$work/compare.yaml" --out "$work/launched-out" --progress log \
  >"$work/launcher.log" 2>&1 || status=$?
cat "$work/launcher.log"

fails=0
check() {  # MESSAGE CONDITION...
  local message=$1
  shift
  if "$@"; then echo "ok: $message"; else echo "FAILED: $message"; fails=$((fails + 1)); fi
}
killed=$(cat "$work/killed-after" 2>/dev/null || echo 0)
check "the launcher exits 0 (got $status)" test "$status" -eq 0
check "the first launch was killed mid-run ($killed evaluations of 48)" test "$killed" -ge 8 -a "$killed" -lt 48
check "it launched the comparison" grep -q "calib compare-optimizers on localhost:3 (3 ranks)" "$work/launcher.log"
check "it continued after the failure" grep -q "mpirun exit 137 with every host answering; resuming (restart 1 of 3)" "$work/launcher.log"
check "the second launch found runs done" grep -q "3 runs: 1 done before, 2 run now" "$work/launcher.log"
for csv in runs.csv convergence.csv fixed_budget.csv fixed_target.csv pairwise.csv; do
  check "$csv is the uninterrupted comparison's" cmp "$work/threads/$csv" "$work/launched-out/$csv"
done
exit $((fails > 0))
