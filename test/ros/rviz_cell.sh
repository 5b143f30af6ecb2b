#!/bin/bash
# ctest's entry to test/ros/rviz_cell.test (cmake/rviz.cmake):
#   rviz_cell.sh RESULT_XML COMMAND...
# Without Xvfb it prints "rviz_cell SKIPPED: ..." (ctest's SKIP_REGULAR_EXPRESSION turns
# that into "Skipped"), writes a JUnit result with the test skipped to RESULT_XML (what
# catkin's run_tests.py checks for) and exits 0; otherwise it runs COMMAND (rostest).
# MASSAGE_CELL_XVFB=PATH names the Xvfb executable (a missing path shows the skip).
set -u
xml=$1
shift
xvfb=${MASSAGE_CELL_XVFB:-Xvfb}
if ! command -v "$xvfb" >/dev/null 2>&1; then
  msg="Xvfb is not installed ($xvfb not found): apt-get install xvfb imagemagick libgl1-mesa-dri rviz (scripts/debian_packages.txt) to render rviz/cell.rviz"
  echo "rviz_cell SKIPPED: $msg"
  mkdir -p "$(dirname "$xml")"
  cat > "$xml" <<XML
<?xml version="1.0" encoding="UTF-8"?>
<testsuite name="rviz_cell" tests="1" failures="0" errors="0" skipped="1">
  <testcase classname="RvizCell" name="RendersRobotAndCloud" status="notrun">
    <skipped message="$msg"/>
  </testcase>
</testsuite>
XML
  exit 0
fi
exec "$@"
