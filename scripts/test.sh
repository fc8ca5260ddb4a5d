#!/usr/bin/env bash
# The test command: installs what is missing, builds, and runs every test.
#
#   scripts/test.sh [ctest arguments...]     e.g. scripts/test.sh -L unit
set -euo pipefail

if [[ ${1:-} == --help || ${1:-} == -h ]]; then
  sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
  exit 0
fi

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${FESBENCH_BUILD_DIR:-"$root/build"}

"$root/scripts/setup.sh" "$build_dir"
cd "$build_dir"
ctest --output-on-failure -j "${FESBENCH_JOBS:-$(nproc)}" "$@"
