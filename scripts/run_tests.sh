#!/usr/bin/env bash
# The whole test suite: installs what is missing, builds (tests included) and
# runs every gtest, rostest and check through ctest. Ends with ctest's summary
# line; exits non-zero when any test fails.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
export PYENV_VERSION=system
"$root/scripts/setup.sh" --tests
# rostest starts its own master on a random port per test.
export ROS_HOSTNAME=localhost
exec ctest --test-dir "$root/_build" --output-on-failure --no-tests=error -j2 "$@"
