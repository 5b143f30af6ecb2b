#!/usr/bin/env bash
# record_session.sh BAG [render_scene options]: renders a 5 s session of the
# back preset at 10 Hz (320x240, fx 250, baseline 10 cm unless the options say
# otherwise: later options win), plays it through the stereo driver and
# records BAG (lz4) with its sidecars BAG minus .bag + .ground_truth.yaml and
# .manifest.yaml. Used by make_sample_data.sh and measure_latency.sh; needs
# the package built (_build) and sourced.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bag=$(realpath -m "$1")
shift
[[ "$bag" == *.bag ]] || { echo "record_session: $bag: expected a path ending in .bag" >&2; exit 2; }
bin="$root/_build/devel/lib/massage_cell"
frames=50
work=$(mktemp -d)
session="$work/session"
export ROS_HOSTNAME=localhost
export ROS_MASTER_URI=http://localhost:$((20000 + RANDOM % 20000))
trap 'kill -INT $(jobs -p) 2>/dev/null; sleep 1; rm -rf "$work"' EXIT
"$bin/render_scene" --preset back --frames $frames --rate 10 --width 320 --height 240 --fx 250 \
    --baseline 0.10 --supersample 2 --noise "${SESSION_NOISE:-0.3}" "$@" --out "$session"
cat > "$work/driver.yaml" <<YAML
source: folder
layout: pair
folder: $session
left/pattern: left_*.png
right/pattern: right_*.png
rate: 10.0
loop: false
start_delay: 1.0
camera_name: stereo
left/camera_name: sim_left
right/camera_name: sim_right
left/camera_info_url: file://$session/left_camera_info.yaml
right/camera_info_url: file://$session/right_camera_info.yaml
rectified: true
YAML
roscore -p "${ROS_MASTER_URI##*:}" > "$work/roscore.log" 2>&1 &
for _ in $(seq 50); do rostopic list >/dev/null 2>&1 && break; sleep 0.2; done
roslaunch massage_cell record.launch bag:="$work/session.bag" compression:=lz4 > "$work/record.log" 2>&1 &
record_pid=$!
sleep 2
roslaunch massage_cell stereo_camera.launch params:="$work/driver.yaml" > "$work/driver.log" 2>&1 &
driver_pid=$!
rosrun massage_cell stereo_monitor __ns:=stereo _idle_timeout:=2.0 _print_every:=10
kill -INT "$record_pid" "$driver_pid"
wait "$record_pid" "$driver_pid" 2>/dev/null || true
pairs=$(rosbag info --yaml --key=topics "$work/session.bag" | awk '/topic: \/stereo\/left\/image_raw/{f=1} f&&/messages:/{print $2; exit}')
if [ "$pairs" != "$frames" ]; then
  echo "record_session: the recording holds ${pairs:-no} left images, expected $frames" >&2
  cat "$work/record.log" "$work/driver.log" >&2
  exit 1
fi
mkdir -p "$(dirname "$bag")"
mv "$work/session.bag" "$bag"
cp "$session/ground_truth.yaml" "${bag%.bag}.ground_truth.yaml"
cp "$session/manifest.yaml" "${bag%.bag}.manifest.yaml"
rosbag info "$bag"
