#!/usr/bin/env bash
# hosts.sh: stands in for a small cluster on one machine: each "host" is a
# network namespace with its own address, joined to the others by a veth pair
# to a bridge. mpirun (in the root namespace, as on a login node) starts its
# daemons in them through agent.sh, so each rank talks to the others over
# TCP between namespaces only. Needs root (or sudo) and iproute2.
#
#   hosts.sh up   NAME COUNT SUBNET   e.g. up calib7 3 10.213.7  -> hosts 10.213.7.1..3
#   hosts.sh kill NAME K              host K dies: its processes are killed
#                                     (SIGKILL) and its namespace removed
#   hosts.sh down NAME                removes every namespace, link and bridge of NAME
#
# NAME (at most 8 characters: it prefixes the links' names) keeps concurrent
# runs apart; namespace K is NAME-K and answers at SUBNET.K; the bridge has
# SUBNET.254. Nothing is routed beyond SUBNET.0/24.
set -euo pipefail

sudo=""
[[ $(id -u) -eq 0 ]] || sudo="sudo -n"

cmd=${1:?usage: hosts.sh up|kill|down NAME ...}
name=${2:?usage: hosts.sh $cmd NAME ...}
[[ ${#name} -le 8 && $name =~ ^[a-z][a-z0-9]*$ ]] ||
  { echo "hosts.sh: NAME '$name' must be 1-8 lower-case letters and digits" >&2; exit 2; }
bridge="${name}br"

case $cmd in
  up)
    count=${3:?usage: hosts.sh up NAME COUNT SUBNET}
    subnet=${4:?usage: hosts.sh up NAME COUNT SUBNET}
    [[ $subnet =~ ^[0-9]+\.[0-9]+\.[0-9]+$ ]] ||
      { echo "hosts.sh: SUBNET '$subnet' must be three octets, e.g. 10.213.7" >&2; exit 2; }
    $sudo ip link add "$bridge" type bridge
    $sudo ip addr add "$subnet.254/24" dev "$bridge"
    $sudo ip link set "$bridge" up
    for ((k = 1; k <= count; ++k)); do
      $sudo ip netns add "$name-$k"
      $sudo ip link add "${name}h$k" type veth peer name eth0 netns "$name-$k"
      $sudo ip link set "${name}h$k" master "$bridge" up
      $sudo ip -n "$name-$k" addr add "$subnet.$k/24" dev eth0
      $sudo ip -n "$name-$k" link set eth0 up
      $sudo ip -n "$name-$k" link set lo up
    done
    ;;
  kill)
    k=${3:?usage: hosts.sh kill NAME K}
    pids=$($sudo ip netns pids "$name-$k" || true)
    [[ -n $pids ]] && $sudo kill -9 $pids 2>/dev/null || true
    $sudo ip netns del "$name-$k"
    ;;
  down)
    for ns in $($sudo ip netns list | awk -v p="$name-" 'index($1, p) == 1 {print $1}'); do
      pids=$($sudo ip netns pids "$ns" || true)
      [[ -n $pids ]] && $sudo kill -9 $pids 2>/dev/null || true
      $sudo ip netns del "$ns"
    done
    $sudo ip link del "$bridge" 2>/dev/null || true
    ;;
  *)
    echo "hosts.sh: unknown command '$cmd' (up, kill, down)" >&2
    exit 2
    ;;
esac
