#!/usr/bin/env bash
# Runs programs against a real Linux SocketCAN stack: boots Debian's own kernel
# (fetched by prepare.sh) under qemu-system-x86_64 with software emulation
# (TCG: no KVM needed), loads can / can-raw / can-dev / vcan, creates vcan0 and
# runs the given programs in the guest, then powers off. qemu itself exits 0
# whatever the guest did, so the guest's /init prints
#     QEMU_CAN_RESULT exit=<code>
# on the serial console and this script exits with that code.
#
# Usage:
#   scripts/qemu_can/run.sh --cache DIR [options] -- PROG [ARGS...] [::: PROG [ARGS...]]...
#
#   --cache DIR        kernel cache made by `prepare.sh DIR` (required)
#   --prepare          run `prepare.sh DIR` first (fetches the kernel once;
#                      works offline from the cache afterwards)
#   --expect REGEX     also require a console line matching REGEX (grep -E),
#                      e.g. the test program's own success line; repeatable
#   --timeout SEC      host-side limit for the whole qemu run (default 100); the
#                      guest gets SEC-15 s (at least 10) for its programs before
#                      it kills them and reports exit=124
#   --file HOST[:GUEST]  copy a file into the guest (default GUEST: /data/<name>);
#                      repeatable
#   --env NAME=VALUE   environment variable for the guest programs; repeatable
#   --vcan "vcan0 ..." vcan interfaces to create and bring up (default vcan0)
#   --stagger SEC      pause between starting programs (default 0.3)
#   --wait-all         wait for every program to end (default: see below)
#   --keep DIR         keep the initramfs and the console log in DIR
#   --smp N, --mem MB  guest CPUs (default 2) and memory (default 512)
#   --icount SPEC      qemu's -icount SPEC (default: none, the guest's clock is
#                      the host's). `shift=N,sleep=off` makes the guest's clock
#                      count its own instructions (2^N ns each) and jump over
#                      idle time, so the guest's timing no longer depends on how
#                      busy the host is (a loaded host only makes the run longer
#                      in wall time). Only with --smp 1 (more vCPUs would run
#                      round-robin on one host thread)
#
# Programs are separated by a `:::` word. PROG containing a `/` is a host file:
# it is copied into the guest's /bin (a dynamically linked one brings the shared
# libraries `ldd` lists, but statically linked programs are the intended use);
# a bare name is a guest command (a busybox applet or a --file). ARGS are passed
# verbatim (no shell expansion in the guest). The guest's working directory is
# /data (--file's default target).
#
# All programs run concurrently, started in the given order --stagger apart;
# their output interleaves on the console, and /init prints one line
# `QEMU_CAN_PROG <n> <name> exit=<code> (...)` per program at the end. The
# LAST program is the main one: when it ends, programs still running get
# SIGTERM (SIGKILL 3 s later). The result is the main
# program's exit code when non-zero, else the exit code of the first
# background program that failed: one that ended on its own with a non-zero
# code, or that ended on SIGTERM with a code other than 0/143/137. Example:
# simulated drives in the background, the CANopen master in the foreground:
#     run.sh --cache _build/qemu_can -- /path/sim_drive --node 2 ::: /path/sim_drive --node 3 ::: /path/master_test
# With --wait-all, every program is waited for (none is terminated) and the
# result is the first non-zero exit code in program order.
#
# Exit codes: the guest result (0..255) when the result line was printed, 1
# when it was 0 but an --expect line is missing; 125 for harness errors
# (kernel cache missing or prepare.sh failed, qemu or busybox-static not
# installed, boot timed out, no result line), each with a message on stderr
# starting with "qemu_can/run.sh: ERROR:". The last line is
# "[qemu_can/run] PASS: ..." only on success (ctest: PASS_REGULAR_EXPRESSION).
#
# Needs: qemu-system-x86 busybox-static cpio gzip (Debian packages).
set -uo pipefail

die() { echo "qemu_can/run.sh: ERROR: $*" >&2; exit 125; }
say() { echo "[qemu_can/run] $*"; }
usage() { sed -n '2,/^set -uo/p' "$0" | sed '$d; s/^# \{0,1\}//'; }

cache="" timeout=100 stagger=0.3 wait_all=0 keep="" smp=2 mem=512 vcans="vcan0" prepare=0 icount=""
files=() envs=() expects=()
while [ $# -gt 0 ]; do
  case "$1" in
    --cache) cache=${2:-}; shift 2 || die "--cache needs a value" ;;
    --timeout) timeout=${2:-}; shift 2 || die "--timeout needs a value" ;;
    --file) files+=("${2:-}"); shift 2 || die "--file needs a value" ;;
    --env) envs+=("${2:-}"); shift 2 || die "--env needs a value" ;;
    --vcan) vcans=${2:-}; shift 2 || die "--vcan needs a value" ;;
    --stagger) stagger=${2:-}; shift 2 || die "--stagger needs a value" ;;
    --wait-all) wait_all=1; shift ;;
    --prepare) prepare=1; shift ;;
    --expect) expects+=("${2:-}"); shift 2 || die "--expect needs a value" ;;
    --keep) keep=${2:-}; shift 2 || die "--keep needs a value" ;;
    --smp) smp=${2:-}; shift 2 || die "--smp needs a value" ;;
    --mem) mem=${2:-}; shift 2 || die "--mem needs a value" ;;
    --icount) icount=${2:-}; shift 2 || die "--icount needs a value" ;;
    -h|--help) usage; exit 0 ;;
    --) shift; break ;;
    *) die "unknown option '$1' (options come before --; see --help)" ;;
  esac
done
[ -n "$cache" ] || die "--cache DIR is required (see --help)"
[ $# -gt 0 ] || die "no program given after -- (see --help)"
[[ "$timeout" =~ ^[0-9]+$ ]] && [ "$timeout" -ge 10 ] || die "--timeout must be an integer >= 10"
if [ -n "$icount" ]; then
  [[ "$icount" =~ ^[a-z0-9=,]+$ ]] || die "--icount '$icount': expected qemu -icount suboptions such as shift=0,sleep=off"
  [ "$smp" = 1 ] || die "--icount needs --smp 1"
fi
guest_timeout=$(( timeout - 15 )); [ "$guest_timeout" -ge 10 ] || guest_timeout=10

# --- host requirements ---------------------------------------------------------
if [ "$prepare" -eq 1 ]; then
  "$(dirname "${BASH_SOURCE[0]}")/prepare.sh" "$cache" || die "prepare.sh $cache failed (see above)"
fi
kdir="$cache/current"
[ -f "$kdir/ready" ] && [ -f "$kdir/vmlinuz" ] && [ -f "$kdir/modules.load" ] ||
  die "no prepared kernel in $cache (run scripts/qemu_can/prepare.sh $cache first)"
while read -r m; do
  [ -z "$m" ] || [ -f "$kdir/modules/$m" ] || die "module $m listed in $kdir/modules.load is missing (re-run prepare.sh)"
done < "$kdir/modules.load"
command -v qemu-system-x86_64 >/dev/null || die "qemu-system-x86_64 is not installed (Debian package qemu-system-x86; scripts/setup.sh installs it)"
command -v cpio >/dev/null || die "cpio is not installed (Debian package cpio)"
busybox=/bin/busybox
[ -x "$busybox" ] || die "$busybox is missing (Debian package busybox-static)"
if ldd "$busybox" >/dev/null 2>&1; then
  die "$busybox is dynamically linked: install the Debian package busybox-static (it replaces busybox)"
fi

# --- initramfs tree --------------------------------------------------------------
if [ -n "$keep" ]; then mkdir -p "$keep" && work=$(cd "$keep" && pwd) || die "cannot create $keep"
  rm -rf "$work/root"
else work=$(mktemp -d "${TMPDIR:-/tmp}/qemu_can.XXXXXX") || die "mktemp failed"
  trap 'rm -rf "$work"' EXIT
fi
trap 'exit 143' TERM INT HUP   # so that the EXIT trap cleans up
root="$work/root"
mkdir -p "$root"/{bin,sbin,usr/bin,usr/sbin,proc,sys,dev,tmp,data,modules,lib,lib64}
cp "$busybox" "$root/bin/busybox"
cp "$kdir"/modules/*.ko "$root/modules/"
cp "$kdir/modules.load" "$root/modules.load"

copy_libs() {  # shared libraries of a dynamically linked host program
  local lib
  for lib in $(ldd "$1" 2>/dev/null | grep -o '/[^ ]*'); do
    [ -f "$lib" ] || continue
    mkdir -p "$root$(dirname "$lib")"
    cp -L "$lib" "$root$lib"
  done
}

sq() { printf "'%s'" "${1//\'/\'\\\'\'}"; }  # single-quote for the guest shell

# Split the program list at ::: and turn each into a quoted guest command line.
progs=()   # guest command lines
names=()
cur=()
flush() {
  [ ${#cur[@]} -gt 0 ] || die "empty program between ::: separators"
  local p=${cur[0]} line guest
  if [[ "$p" == */* ]]; then
    [ -f "$p" ] && [ -x "$p" ] || die "program $p is not an executable file"
    guest="/bin/$(basename "$p")"
    if [ -e "$root$guest" ] && ! cmp -s "$p" "$root$guest"; then die "two different programs named $(basename "$p")"; fi
    cp "$p" "$root$guest"
    if ldd "$p" >/dev/null 2>&1; then
      say "note: $p is dynamically linked; copying its shared libraries into the guest"
      copy_libs "$p"
    fi
  else
    guest=$p
  fi
  line=$(sq "$guest")
  local a
  for a in "${cur[@]:1}"; do line+=" $(sq "$a")"; done
  progs+=("$line"); names+=("$(basename "$p")")
  cur=()
}
for a in "$@"; do
  if [ "$a" = ":::" ]; then flush; else cur+=("$a"); fi
done
flush

for f in "${files[@]}"; do
  host=${f%%:*} guest=/data/$(basename "${f%%:*}")
  [[ "$f" == *:* ]] && guest=${f#*:}
  [ -e "$host" ] || die "--file $host does not exist"
  [[ "$guest" == /* ]] || guest=/data/$guest
  mkdir -p "$root$(dirname "$guest")"
  cp -a "$host" "$root$guest"
done

# --- /init -------------------------------------------------------------------------
{
  cat <<'EOF'
#!/bin/busybox sh
# Generated by scripts/qemu_can/run.sh
/bin/busybox --install -s
export PATH=/bin:/sbin:/usr/bin:/usr/sbin
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev 2>/dev/null
[ -c /dev/console ] && exec </dev/console >/dev/console 2>&1
mount -t tmpfs tmpfs /tmp
result() {  # $1 code, $2 note
  echo "QEMU_CAN_RESULT exit=$1${2:+ ($2)} uptime=$(cut -d' ' -f1 /proc/uptime)"
  sync
  poweroff -f
  sleep 10
}
echo
echo "QEMU_CAN_BOOTED kernel=$(uname -r) cpus=$(nproc) uptime=$(cut -d' ' -f1 /proc/uptime)"
for m in $(cat /modules.load); do
  insmod /modules/$m || result 125 "insmod $m failed"
done
EOF
  echo "for i in $vcans; do"
  cat <<'EOF'
  ip link add dev $i type vcan || result 125 "ip link add dev $i type vcan failed"
  ip link set $i up || result 125 "ip link set $i up failed"
done
echo "QEMU_CAN_READY modules=\"$(cat /modules.load | tr '\n' ' ')\" interfaces=\"$(ls /sys/class/net | tr '\n' ' ')\""
EOF
  for e in "${envs[@]}"; do echo "export $(sq "$e")"; done
  echo "cd /data"
  echo "GUEST_TIMEOUT=$guest_timeout STAGGER=$stagger WAIT_ALL=$wait_all NPROG=${#progs[@]}"
  i=0
  for line in "${progs[@]}"; do
    i=$((i + 1))
    [ "$i" -gt 1 ] && echo "sleep \$STAGGER"
    echo "$line &"
    echo "pid$i=\$! name$i=$(sq "${names[$((i - 1))]}")"
  done
  cat <<'EOF'
alive() { [ -r /proc/$1/stat ] && [ "$(sed 's/.*) //' /proc/$1/stat | cut -c1)" != Z ]; }
pids=""
i=1; while [ $i -le $NPROG ]; do eval "pids=\"\$pids \$pid$i\""; i=$((i + 1)); done
( sleep $GUEST_TIMEOUT
  echo "QEMU_CAN_GUEST_TIMEOUT: programs still running after ${GUEST_TIMEOUT} s: killing them"
  touch /tmp/guest_timeout
  kill -TERM $pids 2>/dev/null; sleep 3; kill -KILL $pids 2>/dev/null ) &
watchdog=$!
final=0
report() {  # $1 index, $2 status, $3 note
  eval "n=\$name$1"
  echo "QEMU_CAN_PROG $1 $n exit=$2${3:+ ($3)}"
  [ "$final" -eq 0 ] && [ "$2" -ne 0 ] && final=$2
}
if [ "$WAIT_ALL" -eq 1 ]; then
  i=1; while [ $i -le $NPROG ]; do
    eval "p=\$pid$i"; wait $p; report $i $?; i=$((i + 1))
  done
else
  eval "p=\$pid$NPROG"; wait $p; st=$?
  report $NPROG $st main
  i=1; while [ $i -lt $NPROG ]; do
    eval "p=\$pid$i"
    if alive $p; then eval "term$i=1"; kill -TERM $p 2>/dev/null; fi
    i=$((i + 1))
  done
  n=0; while [ $n -lt 30 ]; do
    any=0; i=1; while [ $i -lt $NPROG ]; do eval "p=\$pid$i"; alive $p && any=1; i=$((i + 1)); done
    [ $any -eq 0 ] && break
    sleep 0.1; n=$((n + 1))
  done
  i=1; while [ $i -lt $NPROG ]; do
    eval "p=\$pid$i; t=\${term$i:-0}"
    alive $p && kill -KILL $p 2>/dev/null
    wait $p; st=$?
    if [ "$t" -eq 1 ]; then
      case $st in 0|143|137) report $i 0 "terminated, exit $st" ;; *) report $i $st "terminated" ;; esac
    else
      report $i $st "ended on its own"
    fi
    i=$((i + 1))
  done
fi
kill $watchdog 2>/dev/null
[ -e /tmp/guest_timeout ] && result 124 "guest timeout ${GUEST_TIMEOUT} s"
result $final
EOF
} > "$root/init"
chmod 755 "$root/init"

initrd="$work/initramfs.cpio.gz"
(cd "$root" && find . -print0 | cpio --null -o -H newc -R 0:0 --quiet) | gzip -1 > "$initrd" ||
  die "building the initramfs failed"

# --- boot --------------------------------------------------------------------------
log="$work/console.log"
say "booting $(cut -d' ' -f1 "$kdir/kernel.version") under qemu (TCG, ${smp} CPUs, ${mem} MB${icount:+, icount $icount}), timeout ${timeout} s, initramfs $(( $(stat -c %s "$initrd") / 1024 )) KiB"
icount_args=()
[ -z "$icount" ] || icount_args=(-icount "$icount")
start=$(date +%s.%N)
timeout -k 5 "$timeout" qemu-system-x86_64 -accel tcg "${icount_args[@]}" -m "$mem" -smp "$smp" -nographic -no-reboot \
  -kernel "$kdir/vmlinuz" -initrd "$initrd" -append "console=ttyS0 panic=-1 quiet" -nic none \
  < /dev/null 2>&1 | sed -u -e 's/\r//g' -e 's/\x1b\[[0-9;?]*[A-Za-z]//g' -e 's/\x1b[c]//g' | tee "$log"
rc=${PIPESTATUS[0]}
wall=$(awk -v a="$(date +%s.%N)" -v b="$start" 'BEGIN{printf "%.1f", a-b}')

code=$(sed -n 's/.*QEMU_CAN_RESULT exit=\([0-9]*\).*/\1/p' "$log" | tail -n1)
if [ "$rc" -eq 124 ] || [ "$rc" -eq 137 ]; then
  die "qemu did not finish within ${timeout} s (boot hung or guest too slow)${code:+; last result line: exit=$code}; wall ${wall} s"
fi
[ "$rc" -eq 0 ] || die "qemu-system-x86_64 failed with exit code $rc (see the console output above); wall ${wall} s"
if [ -z "$code" ]; then
  grep -q QEMU_CAN_BOOTED "$log" || die "the guest never reached /init (no QEMU_CAN_BOOTED line: kernel or initramfs problem); wall ${wall} s"
  die "the guest printed no QEMU_CAN_RESULT line (guest crashed or powered off early); wall ${wall} s"
fi
ready=$(sed -n 's/.*QEMU_CAN_BOOTED.*uptime=\([0-9.]*\).*/\1/p' "$log" | head -n1)
summary="guest exit code $code; wall ${wall} s (guest /init started at ${ready:-?} s uptime)"
if [ "$code" -ne 0 ]; then
  echo "[qemu_can/run] FAIL: $summary" >&2
  exit "$code"
fi
for e in "${expects[@]}"; do
  if ! grep -Eq -- "$e" "$log"; then
    echo "qemu_can/run.sh: ERROR: no console line matches '$e' although the guest exit code is 0" >&2
    echo "[qemu_can/run] FAIL: $summary" >&2
    exit 1
  fi
done
say "PASS: $summary"
exit 0
