#!/usr/bin/env bash
# The roles of the calib image (docker/Dockerfile, docker/compose.yaml):
#
#   calib-entrypoint.sh server [calib serve options]
#       as user calib: makes the key mpirun logs in to the workers with (in
#       /ssh, once), then runs `calib serve` with the options given.
#   calib-entrypoint.sh worker
#       as root: waits for the server's public key in /ssh, lets user calib
#       log in with it, and runs sshd: a host mpirun starts ranks on.
#
# Started as root, the server role drops to user calib (the folders of its
# volumes are calib's).
set -euo pipefail
role=${1:?usage: calib-entrypoint.sh server [calib serve options] | worker}
shift
keys=/ssh

case $role in
  server)
    if [[ $(id -u) -eq 0 ]]; then
      exec setpriv --reuid calib --regid calib --init-groups env HOME=/home/calib "$0" server "$@"
    fi
    if [[ ! -f $keys/id_ed25519 ]]; then
      ssh-keygen -q -t ed25519 -N "" -C "calib serve" -f "$keys/id_ed25519"
    fi
    mkdir -p "$HOME/.ssh"
    # The workers are the compose project's own containers, on its private
    # network, made afresh with new host keys: their keys are not pinned.
    cat >"$HOME/.ssh/config" <<CONFIG
Host *
  IdentityFile $keys/id_ed25519
  StrictHostKeyChecking no
  UserKnownHostsFile /dev/null
  LogLevel ERROR
CONFIG
    chmod 600 "$HOME/.ssh/config"
    exec calib serve "$@"
    ;;
  worker)
    [[ $(id -u) -eq 0 ]] || { echo "calib-entrypoint.sh worker: run as root (sshd)" >&2; exit 2; }
    for ((t = 0; t < 300; ++t)); do
      [[ -f $keys/id_ed25519.pub ]] && break
      sleep 1
    done
    [[ -f $keys/id_ed25519.pub ]] || { echo "calib-entrypoint.sh worker: no $keys/id_ed25519.pub after 300 s" >&2; exit 1; }
    install -d -o calib -g calib -m 700 /home/calib/.ssh
    install -o calib -g calib -m 600 "$keys/id_ed25519.pub" /home/calib/.ssh/authorized_keys
    ssh-keygen -A >/dev/null
    mkdir -p /run/sshd
    # OMP_NUM_THREADS and CALIB_CACHE_DIR for the ranks started over ssh.
    printf 'OMP_NUM_THREADS=1\nCALIB_CACHE_DIR=/var/cache/calib/segmentation\n' >/home/calib/.ssh/environment
    chown calib:calib /home/calib/.ssh/environment
    exec /usr/sbin/sshd -D -e -o PermitRootLogin=no -o PasswordAuthentication=no \
      -o PermitUserEnvironment=yes
    ;;
  *)
    echo "calib-entrypoint.sh: unknown role '$role' (server or worker)" >&2
    exit 2
    ;;
esac
