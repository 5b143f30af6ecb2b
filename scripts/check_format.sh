#!/bin/bash
# Checks that every C/C++ file git knows or would add (tracked, or untracked
# and not ignored) follows .clang-format (ctest's
# check_format). Usage: scripts/check_format.sh [FILE...]   (default: all of
# them). Prints each file that does not, with clang-format's first complaint;
# fix with `clang-format -i FILE` (or `git clang-format` on staged changes).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
command -v clang-format >/dev/null || { echo "check_format.sh: clang-format is not installed (scripts/setup.sh installs it)" >&2; exit 2; }
if [ $# -gt 0 ]; then
  files=("$@")
elif git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  mapfile -t files < <(git ls-files --cached --others --exclude-standard '*.cpp' '*.h' '*.hpp')
else
  mapfile -t files < <(find include src test -name '*.cpp' -o -name '*.h' -o -name '*.hpp' | sort)
fi
bad=0
for f in "${files[@]}"; do
  if ! out=$(clang-format --style=file --dry-run -Werror "$f" 2>&1); then
    echo "$f: not formatted: $(echo "$out" | head -1)"
    bad=$((bad + 1))
  fi
done
if [ "$bad" -gt 0 ]; then
  echo "check_format.sh: $bad of ${#files[@]} files do not follow .clang-format (clang-format -i FILE)"
  exit 1
fi
echo "check_format.sh: ${#files[@]} files follow .clang-format"
