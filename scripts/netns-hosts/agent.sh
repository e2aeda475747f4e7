#!/usr/bin/env bash
# agent.sh: mpirun's remote-shell agent (--mca plm_rsh_agent) for the hosts of
# hosts.sh: where ssh would log in to HOST and run the command, this runs it
# in HOST's namespace, under its own host name (a UTS namespace), so that
# Open MPI sees separate machines and talks TCP between them.
#
#   agent.sh HOST COMMAND...   with CALIB_NETNS_NAME set to hosts.sh's NAME;
#                              HOST is SUBNET.K, run in namespace NAME-K
set -euo pipefail
name=${CALIB_NETNS_NAME:?agent.sh: set CALIB_NETNS_NAME to the hosts.sh NAME}
while [[ ${1:-} == -* ]]; do shift; done  # ssh-style options, none needed
host=${1:?agent.sh: no host}
shift
k=${host##*.}
sudo=""
[[ $(id -u) -eq 0 ]] || sudo="sudo -n"
# The command arrives as words of one shell line (what ssh would pass on).
exec $sudo ip netns exec "$name-$k" unshare --uts /bin/sh -c "hostname '$name-host$k' && $*"
