#!/usr/bin/env bash
# scripts/calib-mpirun.sh refuses each kind of bad option with exit 2 and a
# message naming the option and the value, before it starts anything.
#   calib_mpirun_options_test.sh CALIB_EXE
set -uo pipefail
launcher="$(cd "$(dirname "$0")/../.." && pwd)/scripts/calib-mpirun.sh"
export CALIB=${1:?usage: calib_mpirun_options_test.sh CALIB_EXE}
# mpirun must never be reached: a stand-in that fails the test if it is.
export MPIRUN=/bin/false
fails=0
expect() {  # MESSAGE_PART ARGS...
  local want=$1
  shift
  local out rc
  out=$(bash "$launcher" "$@" 2>&1)
  rc=$?
  if [[ $rc -eq 2 && $out == *"$want"* ]]; then
    echo "ok: $* -> $out"
  else
    echo "FAILED: $* -> exit $rc, '$out' (wanted exit 2 naming: $want)"
    fails=$((fails + 1))
  fi
}
expect "slots of 'node2' must be a positive integer, got '0'" --hosts node1,node2:0 job.yaml
expect "slots of 'node1' must be a positive integer, got 'x'" --hosts node1:x job.yaml
expect "an empty host name in ':4'" --hosts :4 job.yaml
expect "--max-restarts must be a non-negative integer, got 'many'" --hosts a:2 --max-restarts many job.yaml
expect "--probe-timeout must be a positive integer, got '0'" --hosts a:2 --probe-timeout 0 job.yaml
expect "--hostfile: cannot read '/nonexistent/hosts'" --hostfile /nonexistent/hosts job.yaml
expect "unknown option '--nodes'" --nodes 3 job.yaml
expect "no hosts given" job.yaml
expect "no job spec given" --hosts a:2
CALIB=/nonexistent/calib expect "calib executable '/nonexistent/calib' not found" --hosts a:2 job.yaml
exit $((fails > 0))
