#!/usr/bin/env bash
# Fetches Debian's own kernel for the qemu SocketCAN harness (see run.sh) and
# caches vmlinuz plus the CAN modules, uncompressed, in dependency order.
#
#   scripts/qemu_can/prepare.sh CACHE_DIR [--modules "can can-raw can-dev vcan"]
#
# - The kernel package is the one the `linux-image-amd64` metapackage currently
#   depends on (apt-cache show: the candidate version), fetched with
#   `apt-get download` (no root needed) and unpacked with dpkg-deb: only
#   /boot/vmlinuz-* and the CAN module folders (net/can, drivers/net/can) are
#   extracted and kept; the .deb (~70 MB) is deleted afterwards.
# - Module dependencies are read from each module's own .modinfo `depends=`
#   field (the .deb ships no modules.dep: depmod makes it at install time) and
#   resolved recursively; .ko.xz / .ko.zst / .ko.gz modules are decompressed
#   because busybox insmod may not read them. --modules picks other CAN modules
#   (e.g. add can-bcm or can-isotp); the default is what run.sh's vcan0 needs.
# - Idempotent and offline-safe: an already-prepared kernel is reused without
#   network access; when the metapackage now names a kernel that cannot be
#   downloaded (no network) the newest kernel already in the cache is used,
#   with a warning. When the download gets a 404 (stale package lists) and we
#   are root, the lists are refreshed once (apt-get update), as
#   scripts/setup.sh would. Fails (exit 1, clear message) only when nothing
#   usable is cached and the download fails.
#
# Cache layout (CACHE_DIR):
#   kernel/<package>/vmlinuz            kernel image
#   kernel/<package>/tree/              the CAN module folders, as shipped
#   kernel/<package>/modules/*.ko       the selected modules, uncompressed
#   kernel/<package>/modules.load       their file names in load order
#   kernel/<package>/modules.set        the --modules value they were made for
#   kernel/<package>/kernel.version     e.g. "6.1.0-56-amd64 6.1.192-2"
#   current -> kernel/<package>         what run.sh boots
set -euo pipefail

usage() { sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; }
die() { echo "qemu_can/prepare.sh: ERROR: $*" >&2; exit 1; }
log() { echo "[qemu_can/prepare] $*"; }

cache=""
modules="can can-raw can-dev vcan"
while [ $# -gt 0 ]; do
  case "$1" in
    --modules) [ $# -ge 2 ] || die "--modules needs a value"; modules="$2"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    -*) die "unknown option '$1' (see --help)" ;;
    *) [ -z "$cache" ] || die "only one CACHE_DIR"; cache="$1"; shift ;;
  esac
done
[ -n "$cache" ] || { usage >&2; exit 2; }
modules=$(echo $modules)  # normalised spacing (modules.set comparison)
mkdir -p "$cache/kernel"
cache=$(cd "$cache" && pwd)

# Parallel ctest runs share the cache: one preparer at a time.
exec 9>"$cache/.lock"
flock -w 120 9 || die "could not lock $cache/.lock within 120 s"

# --- module selection ------------------------------------------------------------
modinfo_field() {  # $1 .ko (uncompressed), $2 field
  tr '\0' '\n' < "$1" | sed -n "s/^$2=//p" | head -n1
}
# Writes $1/modules, $1/modules.load, $1/modules.set for $modules from $1/tree.
select_modules() {
  local kdir=$1 kver; kver=$(cut -d' ' -f1 "$kdir/kernel.version")
  [ -d "$kdir/tree" ] || die "$kdir has no tree/ (made by an older prepare.sh): delete $kdir and re-run"
  local new="$kdir/modules.new"
  rm -rf "$new"; mkdir -p "$new"
  declare -A state=()   # module name -> visiting | done
  local order=()
  find_module() {  # $1 module name ('-' and '_' are equivalent) -> its .ko[.xz|.zst|.gz]
    local n1=${1//_/-} n2=${1//-/_} f
    while IFS= read -r f; do
      case "$f" in *.ko|*.ko.xz|*.ko.zst|*.ko.gz) echo "$f"; return 0 ;; esac
    done < <(find "$kdir/tree" -type f \( -name "$n1.ko*" -o -name "$n2.ko*" \) | sort)
    return 1
  }
  plain_module() {  # $1 file -> uncompressed copy in $new, prints its path
    local f=$1 base; base=$(basename "$f"); base=${base%.xz}; base=${base%.zst}; base=${base%.gz}
    local dst="$new/$base"
    if [ ! -f "$dst" ]; then
      case "$f" in
        *.xz)  xz -dc "$f" > "$dst" || die "xz -d $f failed (install xz-utils)" ;;
        *.zst) zstd -qdc "$f" > "$dst" || die "zstd -d $f failed (install zstd)" ;;
        *.gz)  gzip -dc "$f" > "$dst" || die "gzip -d $f failed" ;;
        *)     cp "$f" "$dst" ;;
      esac
    fi
    echo "$dst"
  }
  visit() {
    local name=${1//_/-}
    case "${state[$name]:-}" in
      done) return ;;
      visiting) die "module dependency cycle at $name" ;;
    esac
    state[$name]=visiting
    local src; src=$(find_module "$name") ||
      die "module $name is not among the CAN modules of $(basename "$kdir") ($kver)"
    local ko; ko=$(plain_module "$src")
    local vm; vm=$(modinfo_field "$ko" vermagic)
    [ "${vm%% *}" = "$kver" ] || die "module $name has vermagic '$vm', not $kver"
    local deps d; deps=$(modinfo_field "$ko" depends)
    for d in ${deps//,/ }; do visit "$d"; done
    state[$name]="done"
    order+=("$(basename "$ko")")
  }
  local m
  for m in $modules; do visit "$m"; done
  rm -rf "$kdir/modules"
  mv "$new" "$kdir/modules"
  printf '%s\n' "${order[@]}" > "$kdir/modules.load"
  echo "$modules" > "$kdir/modules.set"
}

use() {  # make a prepared kernel folder the `current` one (selecting modules if needed)
  local kdir=$1
  if [ "$(cat "$kdir/modules.set" 2>/dev/null)" != "$modules" ] || [ ! -f "$kdir/modules.load" ]; then
    select_modules "$kdir"
  fi
  ln -sfn "kernel/$(basename "$kdir")" "$cache/current.tmp"
  mv -Tf "$cache/current.tmp" "$cache/current"
  log "kernel $(cat "$kdir/kernel.version") ready: $cache/current ($(paste -sd' ' "$kdir/modules.load"))"
}

# Newest fully prepared kernel in the cache (by package version), or "".
newest_cached() {
  local d best="" bestv="" v
  for d in "$cache"/kernel/*/; do
    [ -f "$d/ready" ] || continue
    v=$(awk '{print $2}' "$d/kernel.version")
    if [ -z "$best" ] || dpkg --compare-versions "$v" gt "$bestv"; then best=${d%/}; bestv=$v; fi
  done
  echo "$best"
}

# --- 1. which kernel package does the metapackage name now? (local apt lists) ------
wanted_package() {
  apt-cache show --no-all-versions linux-image-amd64 2>/dev/null \
    | sed -n 's/^Depends:.*\(linux-image-[0-9][^ ,]*-amd64\).*/\1/p' | head -n1 || true
}
pkg=""
command -v apt-cache >/dev/null && pkg=$(wanted_package)

if [ -n "$pkg" ] && [ -f "$cache/kernel/$pkg/ready" ]; then
  use "$cache/kernel/$pkg"
  exit 0
fi

fallback() {  # $1: why the wanted kernel is not available
  local old; old=$(newest_cached)
  if [ -n "$old" ]; then
    echo "qemu_can/prepare.sh: WARNING: $1; using the cached $(basename "$old")" >&2
    use "$old"
    exit 0
  fi
  die "$1, and no kernel is cached in $cache/kernel
  (needs Debian's archive once: apt-get download ${pkg:-linux-image-amd64}; if the package lists
   are stale, run 'apt-get update' or scripts/setup.sh)"
}

[ -n "$pkg" ] || fallback "apt-cache does not know linux-image-amd64 (no apt lists?)"

# --- 2. download (scratch folder inside the cache, removed on exit) -----------------
work=$(mktemp -d "$cache/.work.XXXXXX")
trap 'rm -rf "$work"' EXIT
chmod 755 "$work"
download() {
  local rc=0
  log "downloading $pkg (apt-get download)"
  (cd "$work" && apt-get download -q -o Acquire::Retries=1 -o Acquire::http::Timeout=15 "$pkg") \
    > "$work/apt.log" 2>&1 || rc=$?
  grep -v -e 'Download is performed unsandboxed' "$work/apt.log" >&2 || true
  return "$rc"
}
if ! download; then
  # 404: the package lists name a kernel the archive no longer has (stale lists).
  # Only then, and only as root, refresh them (as scripts/setup.sh would).
  if [ "$(id -u)" -eq 0 ] && grep -q '404' "$work/apt.log"; then
    log "the archive no longer has $pkg: refreshing the package lists (apt-get update) and retrying once"
    apt-get update -q >/dev/null 2>&1 || fallback "apt-get download $pkg got 404 and apt-get update failed"
    pkg2=$(wanted_package)
    if [ -n "$pkg2" ] && [ "$pkg2" != "$pkg" ]; then
      pkg=$pkg2
      if [ -f "$cache/kernel/$pkg/ready" ]; then use "$cache/kernel/$pkg"; exit 0; fi
    fi
    download || fallback "apt-get download $pkg failed"
  else
    fallback "apt-get download $pkg failed (no network? or stale package lists: run apt-get update)"
  fi
fi
deb=$(find "$work" -maxdepth 1 -name "${pkg}_*.deb" | head -n1)
[ -n "$deb" ] || die "apt-get download $pkg left no .deb in $work"
debver=$(dpkg-deb -f "$deb" Version)

# --- 3. extract only the kernel image and the CAN module folders ---------------------
# (dpkg -x would unpack ~400 MB; the .deb has no modules.dep: see select_modules)
mkdir -p "$work/x"
dpkg-deb --fsys-tarfile "$deb" | tar -x -C "$work/x" --wildcards \
  './boot/vmlinuz-*' './lib/modules/*/kernel/net/can/*' './lib/modules/*/kernel/drivers/net/can/*' \
  || die "extracting $deb failed (not a kernel image package?)"
rm -f "$deb"
vmlinuz=$(find "$work/x/boot" -maxdepth 1 -name 'vmlinuz-*' 2>/dev/null | head -n1)
[ -n "$vmlinuz" ] || die "$pkg has no /boot/vmlinuz-*"
kver=${vmlinuz##*/vmlinuz-}

out="$work/out"
mkdir -p "$out/tree"
cp "$vmlinuz" "$out/vmlinuz"
echo "$kver $debver" > "$out/kernel.version"
mv "$work/x/lib/modules/$kver/kernel/net" "$work/x/lib/modules/$kver/kernel/drivers" "$out/tree/"
select_modules "$out"
touch "$out/ready"

rm -rf "${cache:?}/kernel/$pkg"
mv "$out" "$cache/kernel/$pkg"
use "$cache/kernel/$pkg"
