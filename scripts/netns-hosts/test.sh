#!/usr/bin/env bash
# A job over three hosts (network namespaces, hosts.sh), one of which dies
# mid-job: calib-mpirun.sh resumes it on the other two, and the history is
# the one threads give on one machine. Needs root (or passwordless sudo) and
# iproute2; makes its namespaces, links and bridge and removes them at exit.
#
#   scripts/netns-hosts/test.sh CALIB_EXE [WORK_DIR]
#
# Registered with ctest as Mpi.AHostDiesMidJobAndTheLauncherResumesOnTheOthers.
set -euo pipefail

here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
calib=$(realpath "${1:?usage: test.sh CALIB_EXE [WORK_DIR]}")
work=${2:-$(mktemp -d)}
mkdir -p "$work"
work=$(realpath "$work")

# Names and a subnet of this run's own, so that runs side by side do not meet.
name="cm$(($$ % 1000000))"
subnet="10.213.$(($$ % 250 + 1))"
cleanup() { bash "$here/hosts.sh" down "$name" || true; }
trap cleanup EXIT
bash "$here/hosts.sh" down "$name" >/dev/null 2>&1 || true
bash "$here/hosts.sh" up "$name" 3 "$subnet"

# The README's example job at a third of its budget, results under $work.
sed -e "s#\.\./push_centre#$repo/examples/push_centre#; s#\.\./push_offset#$repo/examples/push_offset#" \
    -e "s#evaluations: 480#evaluations: 144#" \
    -e "s#store: .*#store: $work/mpi.sqlite#; s#out_dir: .*#out_dir: $work/out#" \
    "$repo/examples/jobs/push_centre_cmaes.yaml" >"$work/job.yaml"
rm -f "$work"/*.sqlite*

# The history threads give.
OMP_NUM_THREADS=2 "$calib" run "$work/job.yaml" --store "$work/threads.sqlite" --threads 2 \
  --no-report --progress none >"$work/threads.log" 2>&1
"$calib" results "$work/job.yaml" --store "$work/threads.sqlite" --csv "$work/threads.csv" >/dev/null

export CALIB="$calib" CALIB_NETNS_NAME="$name"
mpi_args="--allow-run-as-root --mca plm_rsh_agent $here/agent.sh --mca plm_rsh_no_tree_spawn 1
  --mca btl self,tcp --mca btl_tcp_if_include $subnet.0/24 --mca oob_tcp_if_include $subnet.0/24
  -x OMP_NUM_THREADS=1"
bash "$repo/scripts/calib-mpirun.sh" --hosts "$subnet.1,$subnet.2,$subnet.3" --probe-timeout 20 \
  --mpirun-args "$mpi_args" "$work/job.yaml" --no-report --progress log --progress-interval 1 \
  >"$work/mpi.log" 2>&1 &
launcher=$!

recorded() {
  "$calib" results "$work/job.yaml" 2>/dev/null | awk '/^evaluations:/ {print $2; exit}'
}
# Host 3 dies once a third of the budget is recorded.
for ((t = 0; t < 600; ++t)); do
  n=$(recorded || true)
  [[ ${n:-0} -ge 48 ]] && break
  kill -0 "$launcher" 2>/dev/null || break
  sleep 0.2
done
echo "host 3 dies after ${n:-0} evaluations"
bash "$here/hosts.sh" kill "$name" 3
status=0
wait "$launcher" || status=$?
cat "$work/mpi.log"

fails=0
check() {  # MESSAGE CONDITION...
  local message=$1
  shift
  if "$@"; then echo "ok: $message"; else echo "FAILED: $message"; fails=$((fails + 1)); fi
}
check "the launcher exits 0 (got $status)" test "$status" -eq 0
check "it named the lost host" grep -q "lost $subnet.3" "$work/mpi.log"
check "the job was resumed on two hosts" grep -q "calib resume on $subnet.1:1,$subnet.2:1" "$work/mpi.log"
check "host 3 died mid-job" test "${n:-0}" -ge 48 -a "${n:-0}" -lt 144
"$calib" results "$work/job.yaml" --csv "$work/mpi.csv" >"$work/mpi-summary.txt"
check "the job finished" grep -q "^status: finished" "$work/mpi-summary.txt"
# Every field of the history but the timing and the worker's name.
check "the history is the one threads give" python3 - "$work/threads.csv" "$work/mpi.csv" <<'EOF'
import csv, sys
def history(path):
    with open(path, newline="") as f:
        return [{k: v for k, v in row.items() if k not in ("eval_time_s", "worker")}
                for row in csv.DictReader(f)]
a, b = history(sys.argv[1]), history(sys.argv[2])
if len(a) != len(b):
    sys.exit(f"{len(a)} evaluations with threads, {len(b)} over the hosts")
for x, y in zip(a, b):
    if x != y:
        sys.exit(f"evaluation {x['id']} differs:\n  threads {x}\n  hosts   {y}")
EOF
exit $((fails > 0))
