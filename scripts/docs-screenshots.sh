#!/usr/bin/env bash
# Regenerates docs/screenshots: runs the scripted clinician walk (the browser
# test browser.clinician_chain: a new subject to a checked model, the daily
# check, the e-stop and the admin page, at 1280 and 820 px, axe-core on every
# page), then keeps the key screens as small palette PNGs and writes
# docs/screenshots/README.md with each step's clicks and time and the axe
# counts.
#
#   scripts/docs-screenshots.sh        (after scripts/test.sh or setup.sh has built once)
set -euo pipefail

if [[ ${1:-} == --help || ${1:-} == -h ]]; then
  sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
  exit 0
fi

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${FESBENCH_BUILD_DIR:-"$root/build"}
cmake --build "$build_dir" --target fesbench-server fesbench_web >/dev/null
shots="$build_dir/tests/browser/screenshots/chain"
rm -rf "$shots"
(cd "$build_dir" && ctest -R '^browser\.clinician_chain$' --output-on-failure >/dev/null)
/usr/bin/python3 "$root/scripts/docs_screenshots.py" "$shots" "$root/docs/screenshots"
