#!/usr/bin/env bash
# Memory soak (README, "Benchmarks"): rapid_parameterisation runs one after another
# on a server at --time-scale 0, each followed by a prediction with the new
# set and the list pages an analyst reads; prints the server's resident
# memory (VmRSS) and its peak every N runs. Talks to 127.0.0.1 only; uses a
# temporary database; stops by itself.
#
#   benchmarks/load/run_soak.sh [RUNS] [EVERY]     defaults 1000 100
set -euo pipefail

if [[ "${1:-}" == "-h" || "${1:-}" == "--help" ]]; then
  sed -n '2,8p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
  exit 0
fi
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
build_dir=${FESBENCH_BUILD_DIR:-"$root/build"}
runs=${1:-1000}
every=${2:-100}

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

"$server" --bind 127.0.0.1 --port 0 --db "$work/data/fesbench.db" --time-scale 0 \
  --dds-transport off >"$work/server.out" 2>"$work/server.err" &
pid=$!
url=""
for _ in $(seq 1 100); do
  url=$(grep -o 'listening on http://127.0.0.1:[0-9]*' "$work/server.out" | sed 's/listening on //' || true)
  [[ -n "$url" ]] && break
  sleep 0.1
done
[[ -n "$url" ]] || { echo "server did not start:" >&2; cat "$work/server.err" >&2; exit 1; }

setup=$("$client" setup --url "$url" --token "$(cat "$work/data/admin.token")")
eval "$(echo "$setup" | tr ' ' '\n' | sed 's/^/export /')"
echo "server: $url (time scale 0, DDS off), pid $pid; $runs rapid runs, each with a prediction and 4 list pages"
"$client" soak --url "$url" --clinician "$clinician" --analyst "$analyst" \
  --session "$session_id" --pid "$pid" --runs "$runs" --every "$every"
