# Sourced by the scripts that run the calib executable: sets $calib to
# $CALIB (default build/apps/calib, relative to the repository root) and
# exits 2 naming the calling script when it is not there.
calib=${CALIB:-build/apps/calib}
if [[ ! -x "$calib" ]]; then
  echo "$(basename "$0"): $calib: no calib executable (build it with scripts/build.sh or set CALIB)" >&2
  exit 2
fi
