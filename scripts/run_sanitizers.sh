#!/usr/bin/env bash
# The core libraries' gtests and the fuzz targets under AddressSanitizer +
# UndefinedBehaviorSanitizer: builds the package with
# -DMASSAGE_CELL_SANITIZE=ON (-O0 -g1) into its own folder (only these
# executables), runs the gtests, then each fuzz target for a short run
# (scripts/run_fuzz.sh). Any sanitizer report, test failure or fuzz finding
# fails the run.
#
# Default (ctest's `sanitizers`, ~5 min on 2 cores beside the other tests):
# the CAN stack's, the arm's and the camera's gtests, and the CAN and stereo
# fuzz targets (fuzz_stereo_match drives the whole stereo library under the
# sanitizers with a thousand drawn images and parameter sets). --all adds the
# stereo and CECT libraries' gtests and the YAML-loader and CECT fuzz targets
# (~22 min on 2 cores: the CECT sources alone take minutes to compile
# instrumented), run by hand before a release (docs/safety.md).
#
#   scripts/run_sanitizers.sh [--all] [build-folder] [fuzz-inputs-per-target]
#     defaults: _build_sanitize, 1000
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
all=0
if [ "${1:-}" = "--all" ]; then all=1; shift; fi
build=${1:-"$root/_build_sanitize"}
fuzz_runs=${2:-1000}
export PYENV_VERSION=system
tests=(test_can_bus test_can_canopen test_can_config test_can_master test_can_cia402 test_can_sim_drive test_can_drive
       test_arm_config test_arm_profile test_arm_plan test_arm_controller test_arm_session test_arm_force_fuzz
       test_session_report test_camera)
fuzzers=(fuzz_can_frames fuzz_can_master fuzz_stereo_match)
if [ $all = 1 ]; then
  tests+=(test_stereo_cost_volume test_stereo_graph_cuts test_stereo_hbds test_stereo_refine)
  tests+=(test_cect_robustness test_cect_segmentation test_cect_cect test_cect_acupoint_model
          test_cect_temporal_filter test_cect_real_backs)
  fuzzers+=(fuzz_yaml_loaders fuzz_cect)
fi

# (Re)configure every time: cheap when nothing changed, and a folder from an
# older checkout learns the test targets added since.
mkdir -p "$build"
# -O0 -g1: line tables for the reports; -O1 triples the compile time of a test.
targets="${tests[*]} ${fuzzers[*]}"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=None -DCMAKE_CXX_FLAGS="-O0 -g1" -DMASSAGE_CELL_SANITIZE=ON \
      -DMASSAGE_CELL_SANITIZE_TARGETS="${targets// /;}" \
      -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 >"$build/configure.log" 2>&1 ||
  { cat "$build/configure.log"; exit 1; }
start=$SECONDS
cmake --build "$build" -j"$(nproc 2>/dev/null || echo 2)" --target sanitize_targets
echo "run_sanitizers.sh: build took $((SECONDS - start)) s"

# Leaks are reported too; a finding stops the test with a non-zero status.
# OpenCV's camera probing (cv::VideoCapture, test_camera) leaks inside
# libgphoto2 (its camera drivers are unloaded before the report, so their
# frames have no names to suppress) and libusb: gphoto2 is not probed, libusb
# suppressed by name. Nothing of ours.
export OPENCV_VIDEOIO_PRIORITY_GPHOTO2=0
suppressions="$build/lsan.supp"
printf 'leak:gp_port_usb_find_device\nleak:libusb_get_device_list\n' > "$suppressions"
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=0:halt_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
export LSAN_OPTIONS=suppressions=$suppressions
failed=0
cd "$root"  # the gtests read config/ relative to the package
for t in "${tests[@]}"; do
  exe=$(find "$build/devel/lib" -name "$t" -type f -perm -u+x | head -n1)
  [ -n "$exe" ] || { echo "run_sanitizers.sh: $t was not built" >&2; exit 1; }
  echo "== $t (ASan + UBSan)"
  start=$SECONDS
  if ! "$exe" --gtest_brief=1; then
    echo "run_sanitizers.sh: $t FAILED under the sanitizers" >&2
    failed=1
  fi
  echo "   $t: $((SECONDS - start)) s"
done
echo "== fuzz targets, $fuzz_runs inputs each (ASan + UBSan)"
"$root/scripts/run_fuzz.sh" --build "$build" --runs "$fuzz_runs" --work "$build/fuzz" "${fuzzers[@]#fuzz_}" || failed=1
exit $failed
