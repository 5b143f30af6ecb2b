#!/usr/bin/env bash
# Runs the fuzz targets (test/fuzz: the CAN frame codecs, the CANopen master
# with a stranger on the bus, every YAML loader, stereo::match, the CECT
# chain) from a build folder, each for N inputs; any crash, hang or broken
# property stops it non-zero and leaves the input as fuzz-<kind>-<target>-<n>.bin
# in the work folder (replay: <target> --replay FILE). The YAML loaders start
# from the package's own files (config/, data/sample_stereo/) as seeds.
#
#   scripts/run_fuzz.sh [--build DIR] [--runs N] [--seed S] [--work DIR] [TARGET...]
#     defaults: --build _build, --runs 1000000, --seed 1, every target
# scripts/run_sanitizers.sh runs each briefly under ASan + UBSan.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="$root/_build" runs=1000000 seed=1 work=""
targets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build=$2; shift 2 ;;
    --runs) runs=$2; shift 2 ;;
    --seed) seed=$2; shift 2 ;;
    --work) work=$2; shift 2 ;;
    -h|--help) sed -n 2,12p "$0"; exit 0 ;;
    -*) echo "run_fuzz.sh: unknown option $1" >&2; exit 2 ;;
    *) targets+=("$1"); shift ;;
  esac
done
[ ${#targets[@]} -gt 0 ] || targets=(can_frames can_master yaml_loaders stereo_match cect)
work=${work:-$(mktemp -d)}
mkdir -p "$work"

# Seeds of the YAML loaders: the loader's number (fuzz_yaml_loaders.cpp) as the first byte, then a file.
corpus="$work/yaml_seeds"
rm -rf "$corpus" && mkdir -p "$corpus"
seed_file() { printf "\\x$(printf %02x "$1")" > "$corpus/$2"; cat >> "$corpus/$2"; }
sample="$root/data/sample_stereo"
seed_file 0 can_axes < "$root/config/can_axes.yaml"
seed_file 1 arm < "$root/config/arm.yaml"
seed_file 2 acupoints < "$root/config/acupoints.yaml"
seed_file 3 acupoint_regions < "$root/config/acupoints.yaml"
seed_file 4 camera_info < "$sample/left.yaml"
seed_file 5 session < "$root/config/session.yaml"
seed_file 6 hand_eye <<YAML
parent_frame: stereo_left_optical_frame
child_frame: arm_base_link
translation: {x: 0.1, y: -0.2, z: 0.9}
rotation: {x: 0, y: 0, z: 0.7071067811865476, w: 0.7071067811865476}
residuals_mm: [0.3, 0.4]
rms_mm: 0.35
max_mm: 0.4
warnings: [a warning]
date: "2026-11-28"
YAML
seed_file 7 views <<YAML
views:
  - {image: $sample/left_0000.jpg, camera_info: $sample/left.yaml, position: [0, 0, 0], orientation: [0, 0, 0, 1]}
  - {image: $sample/right_0000.jpg, camera_info: $sample/right.yaml, position: [0.06, 0, 0], orientation: [0, 0, 0, 1]}
YAML

failed=0
for t in "${targets[@]}"; do
  exe=$(find "$build/devel/lib" -name "fuzz_$t" -type f -perm -u+x | head -n1)
  [ -n "$exe" ] || { echo "run_fuzz.sh: fuzz_$t is not built in $build" >&2; exit 1; }
  seeds=()
  [ "$t" = yaml_loaders ] && seeds=("$corpus")
  if ! (cd "$work" && "$exe" --runs "$runs" --seed "$seed" --quiet "${seeds[@]}"); then
    echo "run_fuzz.sh: fuzz_$t FAILED (its input is in $work)" >&2
    failed=1
  fi
done
exit $failed
