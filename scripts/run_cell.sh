#!/usr/bin/env bash
# The cell's main job on its bundled default data, no hardware needed:
# installs what is missing, builds, then runs launch/cell.launch (the bundled
# recording played as a live camera, HBDS, CECT, the planar node, the arm on
# simulated drives) and the massage session in the foreground: it waits for a
# stable acupoint fix, homes the arm, presses the routine (config/session.yaml)
# and prints its report (index.html and pictures in $CELL_REPORT, default
# _build/session_report). Exits with the session's status (0: it went well).
# Extra arguments go to roslaunch, e.g. `scripts/run_cell.sh rviz:=true`.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
export PYENV_VERSION=system
"$root/scripts/setup.sh"
export ROS_HOSTNAME=${ROS_HOSTNAME:-localhost}
set +u
# shellcheck disable=SC1091
source "$root/_build/devel/setup.bash"
set -u
# A master of our own, so a second cell on this machine does not interfere.
port=${CELL_MASTER_PORT:-$((20000 + RANDOM % 20000))}
export ROS_MASTER_URI=http://localhost:$port
log=$(mktemp -d)/cell.log
echo "run_cell: starting the cell (roslaunch massage_cell cell.launch; its log: $log)"
roslaunch -p "$port" massage_cell cell.launch session:=false "$@" > "$log" 2>&1 &
launch=$!
trap 'kill -INT $launch 2>/dev/null || true; wait $launch 2>/dev/null || true' EXIT
for _ in $(seq 100); do rostopic list > /dev/null 2>&1 && break; sleep 0.2; done
if ! kill -0 $launch 2>/dev/null; then
  echo "run_cell: the cell did not start:" >&2
  cat "$log" >&2
  exit 1
fi
status=0
report=${CELL_REPORT:-$root/_build/session_report}
rm -rf "$report"
rosrun massage_cell massage_session __ns:=stereo _session:="$root/config/session.yaml" _report:="$report" || status=$?
exit $status
