#!/usr/bin/env bash
# Installs the Debian packages massage_cell needs (only the missing ones) and
# builds the package into _build/ (catkin devel space: _build/devel).
#
#   scripts/setup.sh            install what is missing, configure, build
#   scripts/setup.sh --tests    ... and build the test executables too
#   scripts/setup.sh --no-install   skip the package check (offline rebuild)
#
# Idempotent and non-interactive; runs apt-get as root, or through sudo.
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="$root/_build"
with_tests=0
install=1
for arg in "$@"; do
  case "$arg" in
    --tests) with_tests=1 ;;
    --no-install) install=0 ;;
    *) echo "setup.sh: unknown option '$arg' (use --tests, --no-install)" >&2; exit 2 ;;
  esac
done

# Debian's ROS Python modules are invisible to a pyenv python: use the system one.
export PYENV_VERSION=system

log() { echo "[setup] $*"; }

install_packages() {
  local list="$root/scripts/debian_packages.txt"
  local wanted missing
  wanted=$(awk '!/^[[:space:]]*#/ && NF {print $1}' "$list")
  # dpkg-query exits non-zero when some package is unknown to dpkg: that is the point here.
  local installed
  # shellcheck disable=SC2086
  installed=$(dpkg-query -W -f='${Package} ${db:Status-Abbrev}\n' $wanted 2>/dev/null | awk '$2 == "ii" {print $1}' || true)
  missing=$(comm -13 <(echo "$installed" | sort -u) <(echo "$wanted" | sort -u))
  if [ -z "$missing" ]; then
    log "all $(echo "$wanted" | wc -l) Debian packages are installed"
    return
  fi
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { echo "setup.sh: not root and no sudo: cannot install: $missing" >&2; exit 1; }
    sudo="sudo"
  fi
  export DEBIAN_FRONTEND=noninteractive
  # Refresh the package lists when they are missing or older than a day.
  if [ -z "$(find /var/lib/apt/lists -maxdepth 1 -name '*_Packages*' -mtime -1 2>/dev/null | head -n1)" ]; then
    log "apt-get update"
    $sudo apt-get update -q
  fi
  log "installing: $(echo $missing)"
  # shellcheck disable=SC2086
  if ! $sudo apt-get install -y -q --no-install-recommends $missing; then
    log "install failed; refreshing the package lists and retrying once"
    $sudo apt-get update -q
    # shellcheck disable=SC2086
    $sudo apt-get install -y -q --no-install-recommends $missing
  fi
}

[ "$install" -eq 1 ] && install_packages

jobs=$(nproc 2>/dev/null || echo 2)
if [ ! -f "$build/Makefile" ]; then  # (re)configure: first run, or a configure that failed
  log "configuring into $build"
  cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release \
        -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3
fi
log "building"
cmake --build "$build" -j"$jobs"
if [ "$with_tests" -eq 1 ]; then
  log "building tests"
  cmake --build "$build" -j"$jobs" --target tests
fi
log "done: source $build/devel/setup.bash to use the package"
