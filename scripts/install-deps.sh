#!/usr/bin/env bash
# Installs every build, test and run-time dependency of the project from
# Debian 12 packages. Idempotent: when everything is present it prints nothing
# and exits 0. Used by README, .ci/run and docker/Dockerfile.
#   --ssh-server   also the ssh server the MPI worker containers of
#                  docker/compose.yaml are reached by (the image only)
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
  libcpp-httplib-dev
  libcsv-dev
  libopenmpi-dev openmpi-bin
  iproute2
  gnuplot-nox
  python3 python3-yaml
  python3-scipy python3-optuna python3-cmaes
  nodejs chromium
)
if [[ "${1:-}" == "--ssh-server" ]]; then
  packages+=(openssh-server openssh-client)
elif [[ $# -gt 0 ]]; then
  echo "install-deps: unknown option '$1' (the one option is --ssh-server)" >&2
  exit 2
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
# npm: Debian's package, unless a node install (NodeSource's nodejs) brings its own.
command -v npm >/dev/null || missing+=(npm)
if [ ${#missing[@]} -gt 0 ]; then
  echo "install-deps: installing ${missing[*]}" >&2
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# The dashboard's npm packages (dashboard/package-lock.json): Chart.js, which
# the build compiles into the server, and puppeteer-core for its browser test.
dashboard="$(cd "$(dirname "$0")/.." && pwd)/dashboard"
if ! cmp -s "$dashboard/package-lock.json" "$dashboard/node_modules/.calib-installed-lock.json"; then
  echo "install-deps: npm ci in $dashboard" >&2
  npm ci --prefix "$dashboard" --no-audit --no-fund >/dev/null
  cp "$dashboard/package-lock.json" "$dashboard/node_modules/.calib-installed-lock.json"
fi
