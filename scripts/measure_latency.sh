#!/usr/bin/env bash
# measure_latency.sh [WIDTH HEIGHT FX [roslaunch args]]: the cell's latencies at
# a camera resolution (default 640 480 500; roslaunch args such as hbds:=false
# go to the cell): records a session of the dressed subject at that size (record_session.sh, into a temporary folder), runs the whole cell
# on it (run_cell.sh: the recording played live at 10 Hz, HBDS, CECT, the
# planar node, the arm) with a massage session, and prints the session's
# report, whose latency lines are camera stamp -> acupoints / acupoint tf /
# disparity and acupoint tf stamp -> press start (p50, p95). Exits with the
# session's status.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
width=${1:-640}
height=${2:-480}
fx=${3:-500}
shift $(( $# < 3 ? $# : 3 ))
export PYENV_VERSION=system
"$root/scripts/setup.sh" > /dev/null
set +u
# shellcheck disable=SC1091
source "$root/_build/devel/setup.bash"
set -u
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "measure_latency: recording a ${width}x${height} session (fx $fx) ..."
"$root/scripts/record_session.sh" "$work/session.bag" --subject 7 --arms along --arm-angle 5 --head --hair nape \
    --towel white --light top_left --seed 12 --width "$width" --height "$height" --fx "$fx" > "$work/record.log" 2>&1 ||
  { cat "$work/record.log" >&2; exit 1; }
echo "measure_latency: running the cell on it ..."
CELL_REPORT="$work/report" "$root/scripts/run_cell.sh" bag:="$work/session.bag" "$@" 2>&1 | grep -v '^\S*\[ INFO\]'
exit "${PIPESTATUS[0]}"
