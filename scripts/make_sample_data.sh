#!/usr/bin/env bash
# Regenerates the data the cell ships, from the project's own renderer:
#   data/sample_stereo/  20 rendered pairs of a textured plane 0.8 m away
#                        (rectified 320x240, baseline 6 cm, breathing motion),
#                        left.yaml / right.yaml calibrations, ground_truth.yaml
#   rosbags/sample.bag   the stereo driver's output on those pairs, recorded
#                        with launch/record.launch (bz2), + /tf_static
# Deterministic images (fixed seed); the bag's stamps are those of the run.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
export PYENV_VERSION=system
"$root/scripts/setup.sh"
set +u
# shellcheck disable=SC1091
source "$root/_build/devel/setup.bash"
set -u

out="$root/data/sample_stereo"
rm -rf "$out"
"$root/_build/devel/lib/massage_cell/render_sample" --out "$out" --frames 20 --width 320 --height 240 \
    --fx 300 --baseline 0.06 --distance 0.8 --amplitude 0.005 --format jpg --seed 7 --noise 1.0

# Record the driver's output on a private master.
export ROS_HOSTNAME=localhost
export ROS_MASTER_URI=http://localhost:$((20000 + RANDOM % 20000))
work=$(mktemp -d)
trap 'kill -INT $(jobs -p) 2>/dev/null; sleep 1; rm -rf "$work"' EXIT
roscore -p "${ROS_MASTER_URI##*:}" > "$work/roscore.log" 2>&1 &
for _ in $(seq 50); do rostopic list >/dev/null 2>&1 && break; sleep 0.2; done
roslaunch massage_cell record.launch bag:="$work/sample.bag" compression:=bz2 > "$work/record.log" 2>&1 &
record_pid=$!
sleep 2
roslaunch massage_cell stereo_camera.launch params:="$root/config/sample_stereo.yaml" > "$work/driver.log" 2>&1 &
driver_pid=$!
rosrun massage_cell stereo_monitor __ns:=stereo _idle_timeout:=2.0 _print_every:=5
kill -INT "$record_pid" "$driver_pid"
wait "$record_pid" "$driver_pid" 2>/dev/null || true

pairs=$(rosbag info --yaml --key=topics "$work/sample.bag" | awk '/topic: \/stereo\/left\/image_raw/{f=1} f&&/messages:/{print $2; exit}')
if [ "$pairs" != "20" ]; then
  echo "make_sample_data: the recording holds ${pairs:-no} left images, expected 20" >&2
  cat "$work/record.log" "$work/driver.log" >&2
  exit 1
fi
mkdir -p "$root/rosbags"
mv "$work/sample.bag" "$root/rosbags/sample.bag"
rosbag info "$root/rosbags/sample.bag"
du -sh "$out" "$root/rosbags/sample.bag"
