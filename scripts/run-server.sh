#!/usr/bin/env bash
# The run command: installs what is missing, builds, and starts
# fesbench-server with the simulated bench and a SQLite file under ./data.
# The server prints the address it actually listens on ("fesbench-server:
# listening on http://HOST:PORT/", the port it bound, also for --port 0)
# and where the admin token is. Ctrl-C (SIGINT) or SIGTERM stops it cleanly
# (a running protocol is stopped with stimulation zero, the database is
# closed).
#
#   scripts/run-server.sh [fesbench-server flags...]
#   e.g. scripts/run-server.sh --port 9000 --time-scale 0
#   scripts/run-server.sh --help      this text (the server's flags: fesbench-server --help)
set -euo pipefail

if [[ ${1:-} == --help || ${1:-} == -h ]]; then
  sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
  exit 0
fi

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${FESBENCH_BUILD_DIR:-"$root/build"}

"$root/scripts/setup.sh" "$build_dir"
cd "$root"
mkdir -p data
exec "$build_dir/server/fesbench-server" --bench sim --db "$root/data/fesbench.db" "$@"
