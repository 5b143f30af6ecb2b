#!/usr/bin/env bash
# Regenerates the data the cell ships, from the project's own renderers:
#   data/sample_stereo/         20 rendered pairs of a textured plane 0.8 m away
#                               (rectified 320x240, baseline 6 cm): the camera
#                               driver's test data (render_sample)
#   rosbags/back_session.bag    a 5 s session at 10 Hz of the mean subject lying
#                               prone and breathing under the stereo camera
#                               (render_scene --preset back --frames 50), played
#                               through the stereo driver and recorded with
#                               launch/record.launch (lz4)
#   rosbags/back_session.ground_truth.yaml   per frame: time, breathing phase,
#                               acupoints in the left optical frame (the sidecar)
#   rosbags/back_session.manifest.yaml       how the session was rendered
#   rosbags/dressed_session.*   the same for a dressed subject as real cells show
#                               one (subject 7, arms along the trunk, head in the
#                               face cradle with hair, a towel, light from the
#                               left): the main job's default (cell.launch)
# Images are deterministic (fixed seeds); the bag's stamps are those of the run.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
export PYENV_VERSION=system
"$root/scripts/setup.sh"
set +u
# shellcheck disable=SC1091
source "$root/_build/devel/setup.bash"
set -u
bin="$root/_build/devel/lib/massage_cell"

out="$root/data/sample_stereo"
rm -rf "$out"
"$bin/render_sample" --out "$out" --frames 20 --width 320 --height 240 \
    --fx 300 --baseline 0.06 --distance 0.8 --amplitude 0.005 --format jpg --seed 7 --noise 1.0

work=$(mktemp -d)
frames=50
# Record on a private master.
export ROS_HOSTNAME=localhost
export ROS_MASTER_URI=http://localhost:$((20000 + RANDOM % 20000))
trap 'kill -INT $(jobs -p) 2>/dev/null; sleep 1; rm -rf "$work"' EXIT
roscore -p "${ROS_MASTER_URI##*:}" > "$work/roscore.log" 2>&1 &
for _ in $(seq 50); do rostopic list >/dev/null 2>&1 && break; sleep 0.2; done
mkdir -p "$root/rosbags"

# record_session NAME RENDER_SCENE_ARGS...: renders a 5 s session at 10 Hz,
# plays it through the stereo driver, records rosbags/NAME.bag (+ sidecars).
record_session() {
  local name=$1
  shift
  local session="$work/$name"
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
  roslaunch massage_cell record.launch bag:="$work/$name.bag" compression:=lz4 > "$work/record.log" 2>&1 &
  local record_pid=$!
  sleep 2
  roslaunch massage_cell stereo_camera.launch params:="$work/driver.yaml" > "$work/driver.log" 2>&1 &
  local driver_pid=$!
  rosrun massage_cell stereo_monitor __ns:=stereo _idle_timeout:=2.0 _print_every:=10
  kill -INT "$record_pid" "$driver_pid"
  wait "$record_pid" "$driver_pid" 2>/dev/null || true
  local pairs
  pairs=$(rosbag info --yaml --key=topics "$work/$name.bag" | awk '/topic: \/stereo\/left\/image_raw/{f=1} f&&/messages:/{print $2; exit}')
  if [ "$pairs" != "$frames" ]; then
    echo "make_sample_data: $name holds ${pairs:-no} left images, expected $frames" >&2
    cat "$work/record.log" "$work/driver.log" >&2
    exit 1
  fi
  mv "$work/$name.bag" "$root/rosbags/$name.bag"
  cp "$session/ground_truth.yaml" "$root/rosbags/$name.ground_truth.yaml"
  cp "$session/manifest.yaml" "$root/rosbags/$name.manifest.yaml"
  rosbag info "$root/rosbags/$name.bag"
}

rm -f "$root/rosbags/sample.bag"
record_session back_session --subject 0 --seed 11
record_session dressed_session --subject 7 --arms along --arm-angle 5 --head --hair nape --towel white \
    --light top_left --seed 12
du -sh "$out" "$root/rosbags/"*
