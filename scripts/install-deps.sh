#!/usr/bin/env bash
# Installs every build, test and run-time dependency of the project from
# Debian 12 packages. Idempotent: when everything is present it prints nothing
# and exits 0. Used by README, .ci/run and docker/Dockerfile.
set -euo pipefail

packages=(
  build-essential cmake pkg-config git ca-certificates
  libeigen3-dev libcgal-dev libgmp-dev libmpfr-dev
  libopencv-dev ffmpeg
  libnlopt-cxx-dev libnlopt-dev
  nlohmann-json3-dev libcli11-dev libyaml-cpp-dev
  libspdlog-dev libfmt-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libsqlite3-dev sqlite3
  libcsv-dev
  libopenmpi-dev openmpi-bin
  gnuplot-nox
  python3 python3-yaml
  python3-scipy python3-optuna python3-cmaes
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
[ ${#missing[@]} -eq 0 ] && exit 0

echo "install-deps: installing ${missing[*]}" >&2
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
