#!/usr/bin/env bash
# The run command: installs what is missing, builds, and starts
# fesbench-server with the simulated bench and a SQLite file under ./data.
# Prints the web client's URL and where the admin token is. Ctrl-C (SIGINT)
# or SIGTERM stops it cleanly (a running protocol is stopped with
# stimulation zero, the database is closed).
#
#   scripts/run-server.sh [fesbench-server flags...]
#   e.g. scripts/run-server.sh --port 9000 --time-scale 0
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${FESBENCH_BUILD_DIR:-"$root/build"}

"$root/scripts/setup.sh" "$build_dir"
cd "$root"
mkdir -p data
echo "run-server: web client and API at http://127.0.0.1:8080/ (unless --bind/--port say otherwise)"
echo "run-server: admin token in $root/data/admin.token (written at the first start, mode 0600)"
exec "$build_dir/server/fesbench-server" --bench sim --db "$root/data/fesbench.db" "$@"
