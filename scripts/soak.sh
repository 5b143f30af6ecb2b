#!/usr/bin/env bash
# A soak test of the whole cell, for memory and rate over time: runs
# launch/cell.launch (the bundled recording looped as a live camera at 10 Hz,
# HBDS, CECT, planar, the arm on simulated drives) on a master of its own and
# keeps the arm busy with the massage session (config/session.yaml) run again
# and again. Every --interval s scripts/soak_sample.py writes one CSV row: each
# node's PID and VmRSS, the rates of the camera's left image, HBDS's disparity,
# CECT's acupoints, /tf and /joint_states. At the end it prints a table and
# exits 1, naming the node or topic, if after the warm-up a node's RSS grew by
# more than --max-growth-mb (median of the last 3 samples minus that of the
# first 3), a topic's mean rate over the last 20 % of the samples fell by more
# than --max-rate-drop below that of the first 20 %, a node died or changed
# PID, or a massage session run failed.
#
#   scripts/soak.sh [--minutes 30] [--warmup-minutes 3] [--interval 10]
#                   [--max-growth-mb 1.0] [--max-rate-drop 0.2] [--out FILE.csv]
#
# --minutes includes the warm-up. The logs (roslaunch's and the nodes' in
# log/, failed sessions', the CSV unless --out) go to a temporary folder, which
# is kept when the soak fails or --out is not given. Uses the devel space
# $CELL_DEVEL, else the one already sourced, else _build/devel.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
minutes=30 warmup=3 interval=10 max_growth=1.0 max_drop=0.2 out=""
while [ $# -gt 0 ]; do
  case $1 in
    --minutes) minutes=$2 ;;
    --warmup-minutes) warmup=$2 ;;
    --interval) interval=$2 ;;
    --max-growth-mb) max_growth=$2 ;;
    --max-rate-drop) max_drop=$2 ;;
    --out) out=$2 ;;
    -h | --help) sed -n '2,/^set -e/{/^set -e/d;s/^# \{0,1\}//;p}' "$0"; exit 0 ;;
    *) echo "soak.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
  shift 2
done
export PYENV_VERSION=system
export ROS_HOSTNAME=${ROS_HOSTNAME:-localhost}
if [ -n "${CELL_DEVEL:-}" ] || [[ ":${ROS_PACKAGE_PATH:-}:" != *":$root:"* ]]; then
  set +u
  # shellcheck disable=SC1091
  source "${CELL_DEVEL:-$root/_build/devel}/setup.bash"
  set -u
fi
work=$(mktemp -d /tmp/soak.XXXXXX)
keep=${out:+no}
touch "$work/runs.txt"
out=${out:-$work/soak.csv}
mkdir -p "$(dirname "$out")"
export ROS_LOG_DIR=$work/log
# A master of our own, so a second cell on this machine does not interfere.
port=$((20000 + RANDOM % 20000))
export ROS_MASTER_URI=http://localhost:$port
launch="" sampler="" loop=""

# Runs the massage session until $work/stop appears; one line per run in runs.txt.
session_loop() {
  local n=0 rc
  while [ ! -e "$work/stop" ]; do
    n=$((n + 1)) rc=0
    rm -rf "$work/report"
    rosrun massage_cell massage_session __ns:=stereo _session:="$root/config/session.yaml" \
      _report:="$work/report" > "$work/session_$n.log" 2>&1 &
    echo $! > "$work/session.pid"
    wait $! || rc=$?
    if [ -e "$work/stop" ]; then echo "interrupted $n"
    elif [ $rc = 0 ]; then echo "ok $n"; rm "$work/session_$n.log"
    else echo "FAIL $n status $rc: $work/session_$n.log"; sleep 2; fi
  done >> "$work/runs.txt"
}

stop_sessions() {
  touch "$work/stop"
  while [ -n "$loop" ] && kill -0 "$loop" 2>/dev/null; do
    kill -INT "$(cat "$work/session.pid" 2>/dev/null)" 2>/dev/null || true
    sleep 0.5
  done
  loop=""
}

# shellcheck disable=SC2317  # (the EXIT trap)
cleanup() {
  local status=$?
  trap - EXIT INT TERM
  stop_sessions
  [ -z "$sampler" ] || { kill -INT "$sampler" 2>/dev/null || true; wait "$sampler" 2>/dev/null || true; }
  [ -z "$launch" ] || { kill -INT "$launch" 2>/dev/null || true; wait "$launch" 2>/dev/null || true; }
  if pgrep -af "$work/" >&2; then
    echo "soak: FAIL: processes left over after the shutdown (above)" >&2
    status=1
  fi
  if [ "$status" = 0 ] && [ "$keep" = no ]; then rm -rf "$work"; else echo "soak: logs in $work"; fi
  if [ "$status" = 0 ]; then echo "soak: PASS"; else echo "soak: FAIL" >&2; fi
  exit "$status"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

nodes=$(roslaunch --nodes massage_cell cell.launch session:=false | paste -sd, -)
echo "soak: starting the cell (master port $port; its log: $work/cell.log)"
roslaunch -p "$port" massage_cell cell.launch session:=false > "$work/cell.log" 2>&1 &
launch=$!
for _ in $(seq 120); do  # up to 60 s for all the launch's nodes to register
  missing=$(comm -23 <(tr , '\n' <<< "$nodes" | sort) <(rosnode list 2>/dev/null | sort) | paste -sd' ' -)
  if [ -z "$missing" ] || ! kill -0 "$launch" 2>/dev/null; then break; fi
  sleep 0.5
done
if [ -n "$missing" ]; then
  echo "soak: FAIL: the cell did not start (missing: $missing); its log:" >&2
  cat "$work/cell.log" >&2
  exit 1
fi

/usr/bin/python3 "$root/scripts/soak_sample.py" sample --out "$out" --interval "$interval" \
  --seconds "$(awk -v m="$minutes" 'BEGIN { print m * 60 }')" --nodes "/master,/rosout,$nodes" &
sampler=$!
while [ ! -s "$out" ]; do kill -0 "$sampler" || exit 1; sleep 0.2; done
session_loop &
loop=$!
echo "soak: $minutes min (warm-up $warmup min), a sample every $interval s into $out, massage sessions in a loop"
wait "$sampler" || { echo "soak: FAIL: the sampler failed" >&2; exit 1; }
sampler=""
stop_sessions

status=0
/usr/bin/python3 "$root/scripts/soak_sample.py" report "$out" --max-growth-mb "$max_growth" \
  --max-rate-drop "$max_drop" --warmup "$(awk -v m="$warmup" 'BEGIN { print m * 60 }')" || status=1
runs=$(grep -c '^ok\|^FAIL' "$work/runs.txt" || true)
failed=$(grep '^FAIL' "$work/runs.txt" || true)
echo "massage_session: $runs runs, $(grep -c . <<< "$failed" || true) failed" \
  "($(grep -c '^interrupted' "$work/runs.txt" || true) interrupted at the end, not counted)"
if [ -n "$failed" ]; then
  echo "soak: FAIL: massage_session runs failed; the first, $(head -n1 <<< "$failed"), ended with:" >&2
  tail -n 4 "$(head -n1 <<< "$failed" | sed 's/.*: //')" >&2
  status=1
fi
if ! kill -0 "$launch" 2>/dev/null; then
  echo "soak: FAIL: roslaunch ended before the soak did (see $work/cell.log)" >&2
  status=1
fi
exit $status
