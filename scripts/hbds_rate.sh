#!/usr/bin/env bash
# How fast the hbds node runs with given parameters, end to end (rectify,
# downsample, match, refine, depth and cloud): records a 5 s session of the
# back at --size (record_session.sh), runs the hbds node alone on a master of
# its own with config/hbds.yaml overridden by each KEY=VALUE, plays the
# recording looped at 10 Hz with a subscriber on the disparity and, after
# --seconds, prints the node's diagnostics (pairs received / processed /
# dropped, mean processing time) and the rate that time allows (rosbag may
# play large images slower than 10 Hz; the processing time is what counts).
#
#   scripts/hbds_rate.sh [--size 640x480] [--fx 500] [--seconds 20] [KEY=VALUE ...]
#   e.g. scripts/hbds_rate.sh min_disparity=32 disparity_range=64 downsample=4
#
# The disparities are in full-resolution pixels (640x480, fx 500, baseline
# 10 cm: the back at 62-71 px, the table at 53 px). Exit 1 when the node
# processed nothing, 2 on a bad argument.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
size=640x480 fx=500 seconds=20 overrides=()
while [ $# -gt 0 ]; do
  case $1 in
    --size) size=$2; shift 2 ;;
    --fx) fx=$2; shift 2 ;;
    --seconds) seconds=$2; shift 2 ;;
    -h | --help) sed -n '2,/^set -e/{/^set -e/d;s/^# \{0,1\}//;p}' "$0"; exit 0 ;;
    *=*) overrides+=("$1"); shift ;;
    *) echo "hbds_rate.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
[[ $size =~ ^([0-9]+)x([0-9]+)$ ]] || { echo "hbds_rate.sh: --size must be WxH, got $size" >&2; exit 2; }
width=${BASH_REMATCH[1]} height=${BASH_REMATCH[2]}
export PYENV_VERSION=system
set +u
# shellcheck disable=SC1091
[[ ":${ROS_PACKAGE_PATH:-}:" == *":$root:"* ]] || source "$root/_build/devel/setup.bash"
set -u
work=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2> /dev/null || true; done
  wait 2> /dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT

params="$work/hbds.yaml"
cp "$root/config/hbds.yaml" "$params"
for kv in "${overrides[@]}"; do
  key=${kv%%=*} value=${kv#*=}
  if grep -q "^$key:" "$params"; then
    sed -i "s|^$key:.*|$key: $value|" "$params"
  elif grep -q "^gen.add(\"$key\"" "$root/cfg/HBDS.cfg"; then
    echo "$key: $value" >> "$params"  # a parameter at its default (cfg/HBDS.cfg)
  else
    echo "hbds_rate.sh: $key is not a parameter of the hbds node (config/hbds.yaml, cfg/HBDS.cfg)" >&2
    exit 2
  fi
done

echo "hbds_rate: recording a ${width}x${height} session (fx $fx) ..."
"$root/scripts/record_session.sh" "$work/session.bag" --width "$width" --height "$height" --fx "$fx" \
  > "$work/record.log" 2>&1 || { cat "$work/record.log" >&2; exit 1; }

port=$((20000 + RANDOM % 20000))
export ROS_MASTER_URI=http://localhost:$port ROS_HOSTNAME=localhost ROS_LOG_DIR="$work/log"
roscore -p "$port" > "$work/roscore.log" 2>&1 & pids+=($!)
for _ in $(seq 50); do rostopic list > /dev/null 2>&1 && break; sleep 0.2; done
roslaunch massage_cell hbds.launch params:="$params" output:=log > "$work/hbds.log" 2>&1 & pids+=($!)
rostopic hz /stereo/disparity > /dev/null 2>&1 & pids+=($!)
sleep 2
rosbag play -q -l "$work/session.bag" > /dev/null 2>&1 & pids+=($!)
echo "hbds_rate: running the node for $seconds s with: ${overrides[*]:-config/hbds.yaml as it is}"
sleep "$seconds"
timeout 10 rostopic echo -n 2 /diagnostics > "$work/diagnostics.txt" 2>&1 || true

# The hbds status's key/value pairs, last message wins.
awk '/name: .*hbds/ {in_hbds = 1; next} /name: / {in_hbds = 0}
     in_hbds && /key:/ {sub(/.*key: "/, ""); sub(/"$/, ""); key = $0}
     in_hbds && /value:/ {sub(/.*value: /, ""); gsub(/^["\047]|["\047]$/, ""); v[key] = $0}
     END {
       n = split("pairs received|pairs processed|dropped pairs|bad pairs|mean processing time (ms)|last error", keys, "|")
       for (i = 1; i <= n; ++i) if (keys[i] in v) printf "  %-28s %s\n", keys[i], v[keys[i]]
       if ((v["pairs processed"] + 0) == 0) exit 1
       printf "  %-28s %.1f Hz\n", "rate the time allows", 1000.0 / v["mean processing time (ms)"]
     }' "$work/diagnostics.txt" || { echo "hbds_rate.sh: the node processed no pair (log: $work/hbds.log)" >&2; cat "$work/hbds.log" >&2; exit 1; }
