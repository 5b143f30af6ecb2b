#!/usr/bin/env bash
# Regenerates the data the cell ships, from the project's own renderers:
#   data/sample_stereo/         20 rendered pairs of a textured plane 0.8 m away
#                               (rectified 320x240, baseline 6 cm): the camera
#                               driver's test data (render_sample)
#   data/back_pair/             one rendered 640x480 pair of the dressed subject of
#                               dressed_session (below) with its calibrations and truth:
#                               cect_locate's example (render_scene --preset back)
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
#   rosbags/markers_session.*   the dressed session again with the skin markers of
#                               config/skin_markers.yaml stuck on C7 (green), T7
#                               (magenta) and L4 (blue): cell.launch markers:=true
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

pair="$root/data/back_pair" tmp=$(mktemp -d)
"$bin/render_scene" --preset back --out "$tmp" --subject 7 --arms along --arm-angle 5 --head --hair nape \
    --towel white --light top_left --seed 12
cp "$tmp"/{left.png,right.png,left_camera_info.yaml,right_camera_info.yaml,acupoints_truth.yaml} "$pair/"
rm -rf "$tmp"

rm -f "$root/rosbags/sample.bag"
"$root/scripts/record_session.sh" "$root/rosbags/back_session.bag" --subject 0 --seed 11
"$root/scripts/record_session.sh" "$root/rosbags/dressed_session.bag" --subject 7 --arms along --arm-angle 5 \
    --head --hair nape --towel white --light top_left --seed 12
"$root/scripts/record_session.sh" "$root/rosbags/markers_session.bag" --subject 7 --arms along --arm-angle 5 \
    --head --hair nape --towel white --light top_left --seed 12 --sticker C7=green --sticker L4=blue \
    --sticker T7=magenta
du -sh "$out" "$pair" "$root/rosbags/"*
