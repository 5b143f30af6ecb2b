#!/usr/bin/env bash
# The CECT gtests under AddressSanitizer + UndefinedBehaviorSanitizer: builds
# the package with -DMASSAGE_CELL_SANITIZE=ON into its own folder
# (_build_sanitize, only the CECT test executables) and runs them; any
# report fails the run. ctest runs this as the test `cect_sanitizers`.
#
#   scripts/run_sanitizers.sh [build-folder]
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${1:-"$root/_build_sanitize"}
export PYENV_VERSION=system
tests=(test_cect_robustness test_cect_segmentation test_cect_cect test_cect_acupoint_model test_cect_temporal_filter
       test_cect_real_backs)

# (Re)configure every time: cheap when nothing changed, and a folder from an
# older checkout learns the test targets added since.
mkdir -p "$build"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMASSAGE_CELL_SANITIZE=ON \
      -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 >"$build/configure.log" 2>&1 ||
  { cat "$build/configure.log"; exit 1; }
cmake --build "$build" -j"$(nproc 2>/dev/null || echo 2)" --target "${tests[@]}"

# Leaks are reported too; a finding stops the test with a non-zero status.
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=0:halt_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
failed=0
for t in "${tests[@]}"; do
  exe=$(find "$build/devel/lib" -name "$t" -type f -perm -u+x | head -n1)
  [ -n "$exe" ] || { echo "run_sanitizers.sh: $t was not built" >&2; exit 1; }
  echo "== $t (ASan + UBSan)"
  if ! "$exe" --gtest_brief=1; then
    echo "run_sanitizers.sh: $t FAILED under the sanitizers" >&2
    failed=1
  fi
done
exit $failed
