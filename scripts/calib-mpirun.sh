#!/usr/bin/env bash
# calib-mpirun.sh: runs a calibration job (or an optimiser comparison) over
# several hosts with mpirun and resumes it on the hosts left when one of
# them dies.
#
#   scripts/calib-mpirun.sh --hosts H1[:SLOTS],H2[:SLOTS],... [options] [--] JOB.yaml [calib options]
#   scripts/calib-mpirun.sh --hosts ... --compare [options] [--] SPEC.yaml [calib options]
#
# Rank 0 (the manager: optimiser, store, checkpoints) goes to the first host,
# one worker rank to every other slot. Debian's Open MPI cannot survive a dead
# rank: when a host dies, mpirun ends every rank. The store has kept every
# evaluation recorded before that (each is its own SQLite transaction), so the
# job is resumable; this launcher then probes each host (`mpirun -H HOST -np 1
# true`), drops those that do not answer and runs `calib resume` on the others.
# A dead host costs the candidates in flight on every rank (one per worker)
# and a restart; the history is the one an uninterrupted run gives. With
# --compare it runs `calib compare-optimizers SPEC` (each run of the
# comparison spread over the ranks) and, after a failure, the same command
# again, which continues the comparison.
#
# Options:
#   --hosts LIST          comma-separated hosts, each with an optional :SLOTS (1)
#   --hostfile FILE       one host per line, "HOST [slots=N]" (Open MPI's format)
#   --max-restarts N      resumes after a rank failure before giving up (3)
#   --probe-timeout S     seconds a host has to answer the probe (30)
#   --mpirun-args "ARGS"  extra mpirun arguments (word-split), e.g. MCA settings
#   --compare             SPEC is an optimiser comparison (docs/compare.md)
# Environment: CALIB (the calib executable; default build/apps/calib of this
# repository), MPIRUN (mpirun).
#
# Exit status: calib's (0 finished, 2 bad input, 3 aborted by the failure
# policy, 4 stopped resumably: wall time or SIGTERM, which this launcher passes
# on and then does not resume); 5 no host left or restarts used up.
set -uo pipefail

here="$(cd "$(dirname "$0")" && pwd)"
calib=${CALIB:-$here/../build/apps/calib}
mpirun=${MPIRUN:-mpirun}
hosts=()
slots=()
max_restarts=3
probe_timeout=30
mpirun_args=()
compare=0

usage() {
  sed -n '2,/^set -uo/p' "$0" | sed '$d; s/^# \{0,1\}//' >&2
  exit 2
}
fail() {
  echo "calib-mpirun: $*" >&2
  exit 2
}
log() { echo "calib-mpirun: $*" >&2; }

add_host() {  # HOST[:SLOTS]
  local host=${1%%:*} n=1
  [[ $1 == *:* ]] && n=${1#*:}
  [[ -n $host ]] || fail "--hosts: an empty host name in '$1'"
  [[ $n =~ ^[1-9][0-9]*$ ]] || fail "--hosts: slots of '$host' must be a positive integer, got '$n'"
  hosts+=("$host")
  slots+=("$n")
}

while [[ $# -gt 0 ]]; do
  case $1 in
    --hosts)
      [[ $# -ge 2 ]] || fail "--hosts needs a value"
      IFS=, read -r -a list <<<"$2"
      for h in "${list[@]}"; do add_host "$h"; done
      shift 2 ;;
    --hostfile)
      [[ $# -ge 2 && -r $2 ]] || fail "--hostfile: cannot read '${2:-}'"
      while read -r host rest; do
        [[ -z $host || $host == \#* ]] && continue
        n=1
        [[ $rest =~ slots=([0-9]+) ]] && n=${BASH_REMATCH[1]}
        add_host "$host:$n"
      done <"$2"
      shift 2 ;;
    --max-restarts)
      [[ ${2:-} =~ ^[0-9]+$ ]] || fail "--max-restarts must be a non-negative integer, got '${2:-}'"
      max_restarts=$2; shift 2 ;;
    --probe-timeout)
      [[ ${2:-} =~ ^[1-9][0-9]*$ ]] || fail "--probe-timeout must be a positive integer, got '${2:-}'"
      probe_timeout=$2; shift 2 ;;
    --mpirun-args)
      [[ $# -ge 2 ]] || fail "--mpirun-args needs a value"
      read -r -a extra <<<"$2"
      mpirun_args+=("${extra[@]}")
      shift 2 ;;
    --compare) compare=1; shift ;;
    -h|--help) usage ;;
    --) shift; break ;;
    -*) fail "unknown option '$1'" ;;
    *) break ;;
  esac
done
[[ $# -ge 1 ]] || fail "no job spec given (usage: --help)"
[[ ${#hosts[@]} -ge 1 ]] || fail "no hosts given (--hosts or --hostfile)"
[[ -x $calib ]] || fail "calib executable '$calib' not found (set CALIB)"
# mpirun notices a dead daemon at once, but then waits for its TCP
# connection to time out before it exits: 300 s + 9 x 20 s at Open MPI's
# defaults. Probe an idle connection after 10 s, every 5 s, 3 times.
if [[ " ${mpirun_args[*]} " != *oob_tcp_keepalive* ]]; then
  mpirun_args=(--mca oob_tcp_keepalive_time 10 --mca oob_tcp_keepalive_intvl 5
               --mca oob_tcp_keepalive_probes 3 "${mpirun_args[@]}")
fi
job=$1
shift
calib_args=("$@")
# The options `calib results` shares with run/resume, to find the job (a
# comparison's --status: its --out).
lookup_args=()
for ((i = 0; i < ${#calib_args[@]}; ++i)); do
  case ${calib_args[i]} in
    --store|--name|--out) lookup_args+=("${calib_args[i]}" "${calib_args[i + 1]:-}") ;;
    --store=*|--name=*|--out=*) lookup_args+=("${calib_args[i]}") ;;
  esac
done

# Slurm's warning before the time limit, or a user's SIGTERM: pass it on (the
# manager stops resumably, exit 4) and resume nothing.
mpirun_pid=
interrupted=0
on_signal() {
  interrupted=1
  [[ -n $mpirun_pid ]] && kill -TERM "$mpirun_pid" 2>/dev/null
}
trap on_signal TERM INT HUP

host_list() {  # HOST:SLOTS,... of the hosts given
  local out=() k
  for k in "${!hosts[@]}"; do out+=("${hosts[k]}:${slots[k]}"); done
  (IFS=,; echo "${out[*]}")
}

# Waits until `calib results` no longer calls the job running (its lock's
# holder has ended or gone stale; for a comparison, until `calib
# compare-optimizers --status` calls no run running); false after
# release_timeout seconds. It asks on the first host, where the manager ran:
# there a holder's process that has ended is seen at once (elsewhere only its
# heartbeat, stale after 60 s, tells).
release_timeout=120
wait_for_release() {
  local t running
  for ((t = 0; t < release_timeout; t += 2)); do
    if [[ $compare -eq 1 ]]; then
      running=$(timeout "$probe_timeout" "$mpirun" "${mpirun_args[@]}" -H "${hosts[0]}:1" -np 1 \
                  "$calib" compare-optimizers "$job" "${lookup_args[@]}" --status 2>/dev/null |
                grep -c '): running')
    else
      running=$(timeout "$probe_timeout" "$mpirun" "${mpirun_args[@]}" -H "${hosts[0]}:1" -np 1 \
                  "$calib" results "$job" "${lookup_args[@]}" 2>/dev/null |
                awk '/^status:/ {print $2; exit}' | grep -c '^running')
    fi
    [[ $running -eq 0 ]] && return 0
    sleep 2
  done
  return 1
}

restarts=0
verb=run
if [[ $compare -eq 1 ]]; then
  verb=compare-optimizers  # it continues the comparison each time
elif "$calib" results "$job" "${lookup_args[@]}" >/dev/null 2>&1; then
  verb=resume
fi
while true; do
  np=0
  for n in "${slots[@]}"; do np=$((np + n)); done
  if [[ $np -lt 2 ]]; then
    log "one slot left on ${hosts[*]}: the manager needs at least one worker rank; give a host 2 slots"
    exit 5
  fi
  log "calib $verb on $(host_list) ($np ranks)"
  "$mpirun" "${mpirun_args[@]}" -H "$(host_list)" -np "$np" \
    "$calib" "$verb" "$job" "${calib_args[@]}" &
  mpirun_pid=$!
  wait "$mpirun_pid"
  rc=$?
  # wait returns early when a trapped signal arrives: wait for mpirun itself.
  while kill -0 "$mpirun_pid" 2>/dev/null; do wait "$mpirun_pid"; rc=$?; done
  mpirun_pid=
  case $rc in
    0|2|3|4) exit "$rc" ;;
  esac
  if [[ $interrupted -eq 1 ]]; then
    log "interrupted (mpirun exit $rc): the job stays resumable"
    exit 4
  fi
  if [[ $restarts -ge $max_restarts ]]; then
    log "mpirun exit $rc after $restarts restart(s): giving up (--max-restarts $max_restarts)"
    exit 5
  fi
  # A rank died: keep the hosts that still answer.
  live_hosts=()
  live_slots=()
  lost=()
  for k in "${!hosts[@]}"; do
    if timeout "$probe_timeout" "$mpirun" "${mpirun_args[@]}" -H "${hosts[k]}:1" -np 1 true \
      >/dev/null 2>&1; then
      live_hosts+=("${hosts[k]}")
      live_slots+=("${slots[k]}")
    else
      lost+=("${hosts[k]}")
    fi
  done
  # The old manager may outlive mpirun for a moment (its host's daemon ends
  # it), and one on a dead host holds the job's lock until its heartbeat is
  # stale (60 s): resume once the job is no longer running.
  if ! wait_for_release; then
    log "mpirun exit $rc and the job stays held by a live process after ${release_timeout} s"
    exit 5
  fi
  if [[ ${#live_hosts[@]} -eq 0 ]]; then
    log "mpirun exit $rc and no host answers: the job stays resumable"
    exit 5
  fi
  hosts=("${live_hosts[@]}")
  slots=("${live_slots[@]}")
  restarts=$((restarts + 1))
  if [[ ${#lost[@]} -gt 0 ]]; then
    log "mpirun exit $rc: lost ${lost[*]}; resuming on the hosts left (restart $restarts of $max_restarts)"
  else
    log "mpirun exit $rc with every host answering; resuming (restart $restarts of $max_restarts)"
  fi
  [[ $compare -eq 1 ]] || verb=resume
done
