#!/usr/bin/env bash
# The cell's main job on its bundled default data, no hardware needed:
# installs what is missing, builds, then runs launch/cell.launch — for now the
# stereo camera driver replaying the bundled recording (data/sample_stereo),
# with stereo_monitor printing every pair it published and a summary.
# Extra arguments go to roslaunch, e.g. `scripts/run_cell.sh stereo_proc:=true`.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
export PYENV_VERSION=system
"$root/scripts/setup.sh"
export ROS_HOSTNAME=${ROS_HOSTNAME:-localhost}
set +u
# shellcheck disable=SC1091
source "$root/_build/devel/setup.bash"
set -u
exec roslaunch massage_cell cell.launch "$@"
