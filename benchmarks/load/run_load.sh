#!/usr/bin/env bash
# HTTP load measurement (README, "Benchmarks"): 32 concurrent analysts fetch a parameter
# set over keep-alive loopback connections for 30 s while a
# rapid_parameterisation run streams at real time. Prints requests/s,
# p50/p99 latency, requests per connection and whether the stream lost a
# sample. Stops by itself; talks to 127.0.0.1 only; uses a temporary
# database.
#
#   benchmarks/load/run_load.sh [SECONDS] [CONNECTIONS]     defaults 30 32
#
# FESBENCH_LOAD_DB=postgresql://user@host:port/db runs it on that (empty)
# PostgreSQL database instead of a temporary SQLite file.
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
build_dir=${FESBENCH_BUILD_DIR:-"$root/build"}
seconds=${1:-30}
connections=${2:-32}

cmake -S "$root" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build "$build_dir" -j "${FESBENCH_JOBS:-$(nproc)}" --target fesbench-server load_client
server="$build_dir/server/fesbench-server"
client="$build_dir/benchmarks/load/load_client"

work=$(mktemp -d)
pid=""
cleanup() {
  [[ -n "$pid" ]] && kill -TERM "$pid" 2>/dev/null && wait "$pid" 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT

# start_server TIME_SCALE: starts the server on a free port; sets pid and url.
start_server() {
  "$server" --bind 127.0.0.1 --port 0 --db "${FESBENCH_LOAD_DB:-$work/data/fesbench.db}" \
    --data-dir "$work/data" --time-scale "$1" \
    --max-connections $((connections + 16)) >"$work/server.out" 2>"$work/server.err" &
  pid=$!
  for _ in $(seq 1 100); do
    url=$(grep -o 'listening on http://127.0.0.1:[0-9]*' "$work/server.out" | sed 's/listening on //' || true)
    [[ -n "$url" ]] && return 0
    sleep 0.1
  done
  echo "server did not start:" >&2
  cat "$work/server.err" >&2
  exit 1
}
stop_server() {
  kill -TERM "$pid"
  wait "$pid"
  pid=""
}

# 1. Data: a subject, a session and one parameter set (fast bench).
start_server 0
setup=$("$client" setup --url "$url" --token "$(cat "$work/data/admin.token")")
stop_server
eval "$(echo "$setup" | tr ' ' '\n' | sed 's/^/export /')"

# 2. The measurement: real-time bench, one run streaming, N analysts.
start_server 1
echo "server: $url (time scale 1), $(nproc) cores; load: $connections connections, $seconds s"
status=0
"$client" load --url "$url" --clinician "$clinician" --analyst "$analyst" \
  --session "$session_id" --parameter-set "$parameter_set_id" \
  --seconds "$seconds" --connections "$connections" || status=$?
stop_server
exit "$status"
