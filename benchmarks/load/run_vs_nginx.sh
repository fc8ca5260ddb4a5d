#!/usr/bin/env bash
# HTTP throughput against nginx (README, "Benchmarks"): the same JSON (a stored
# parameter set) fetched by wrk over 32 keep-alive loopback connections,
# from fesbench-server (GET /api/v1/parameter-sets/{id} with a bearer token:
# routing, authentication, a database read and JSON) and from nginx serving
# those bytes as a static file. Rounds alternate between the two; prints
# each round's requests/s and the median ratio. Needs the Debian packages
# nginx-light (or nginx) and wrk; talks to 127.0.0.1 only; temporary files.
# With FESBENCH_LOAD_JSON=FILE it also writes the medians as Google
# Benchmark JSON for benchmarks/compare_baseline.py: the time per request
# (1/throughput) of each server, and the ratio as "fesbench_ratio".
#
#   benchmarks/load/run_vs_nginx.sh [SECONDS] [CONNECTIONS] [ROUNDS]   defaults 10 32 3
set -euo pipefail

if [[ "${1:-}" == "-h" || "${1:-}" == "--help" ]]; then
  sed -n '2,14p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
  exit 0
fi
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
build_dir=${FESBENCH_BUILD_DIR:-"$root/build"}
seconds=${1:-10}
connections=${2:-32}
rounds=${3:-3}
threads=${WRK_THREADS:-2}
for tool in nginx wrk curl; do
  command -v "$tool" >/dev/null || [[ -x /usr/sbin/$tool ]] ||
    { echo "run_vs_nginx: needs $tool (apt-get install nginx-light wrk curl)" >&2; exit 1; }
done
nginx_bin=$(command -v nginx || echo /usr/sbin/nginx)

cmake -S "$root" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build "$build_dir" -j "${FESBENCH_JOBS:-$(nproc)}" --target fesbench-server load_client
server="$build_dir/server/fesbench-server"
client="$build_dir/benchmarks/load/load_client"

work=$(mktemp -d)
chmod 755 "$work"
pid=""
nginx_pid=""
cleanup() {
  [[ -n "$pid" ]] && kill -TERM "$pid" 2>/dev/null && wait "$pid" 2>/dev/null || true
  [[ -n "$nginx_pid" ]] && kill -QUIT "$nginx_pid" 2>/dev/null || true
  sleep 0.2
  rm -rf "$work"
}
trap cleanup EXIT

"$server" --bind 127.0.0.1 --port 0 --db "$work/data/fesbench.db" --time-scale 0 \
  --dds-transport off --max-connections $((connections + 16)) \
  >"$work/server.out" 2>"$work/server.err" &
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
path="/api/v1/parameter-sets/$parameter_set_id"

# nginx: the same bytes and Content-Type, keep-alive without a request cap.
mkdir -p "$work/www" "$work/nginx"
curl -sf -H "Authorization: Bearer $analyst" "$url$path" >"$work/www/set.json"
chmod -R a+rX "$work/www"
nginx_port=$((20000 + RANDOM % 20000))
cat >"$work/nginx/nginx.conf" <<CONF
worker_processes auto;
daemon off;
pid $work/nginx/nginx.pid;
error_log $work/nginx/error.log warn;
events { worker_connections 1024; }
http {
  access_log off;
  client_body_temp_path $work/nginx/body;
  proxy_temp_path $work/nginx/proxy;
  fastcgi_temp_path $work/nginx/fastcgi;
  uwsgi_temp_path $work/nginx/uwsgi;
  scgi_temp_path $work/nginx/scgi;
  keepalive_requests 100000000;
  server {
    listen 127.0.0.1:$nginx_port;
    location = $path {
      default_type application/json;
      alias $work/www/set.json;
    }
  }
}
CONF
"$nginx_bin" -c "$work/nginx/nginx.conf" -e "$work/nginx/error.log" &
nginx_pid=$!
for _ in $(seq 1 50); do
  curl -sf "http://127.0.0.1:$nginx_port$path" >/dev/null && break
  sleep 0.1
done
cmp -s <(curl -sf "http://127.0.0.1:$nginx_port$path") "$work/www/set.json" ||
  { echo "nginx does not serve the file:" >&2; cat "$work/nginx/error.log" >&2; exit 1; }

rate() {  # URL [header]: requests/s of one wrk round (fails on any non-2xx)
  local out
  out=$(wrk -t "$threads" -c "$connections" -d "${seconds}s" ${2:+-H "$2"} "$1")
  if grep -q "Non-2xx" <<<"$out"; then
    echo "run_vs_nginx: non-2xx answers from $1:" >&2; echo "$out" >&2; exit 1
  fi
  awk '/^Requests\/sec:/ {printf "%.0f", $2}' <<<"$out"
}

echo "body: $(wc -c <"$work/www/set.json") bytes; $connections keep-alive connections, wrk $threads threads, ${seconds} s per round, $(nproc) cores shared by client and server"
printf "%6s %14s %14s %8s\n" round "fesbench r/s" "nginx r/s" ratio
ratios=() f_us=() n_us=()
for r in $(seq 1 "$rounds"); do
  f=$(rate "$url$path" "Authorization: Bearer $analyst")
  n=$(rate "http://127.0.0.1:$nginx_port$path")
  ratio=$(awk -v f="$f" -v n="$n" 'BEGIN {printf "%.2f", f / n}')
  ratios+=("$ratio")
  # For the JSON: µs per request (1/throughput) of each.
  f_us+=("$(awk -v f="$f" 'BEGIN {printf "%.4f", 1e6 / f}')")
  n_us+=("$(awk -v n="$n" 'BEGIN {printf "%.4f", 1e6 / n}')")
  printf "%6d %14s %14s %8s\n" "$r" "$f" "$n" "$ratio"
done
printf "median ratio fesbench / nginx: %s\n" "$(printf '%s\n' "${ratios[@]}" | sort -n | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')"
if [[ -n ${FESBENCH_LOAD_JSON:-} ]]; then
  median() { printf '%s\n' "$@" | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
  printf '{"context": {"host_name": "%s", "num_cpus": %s, "mhz_per_cpu": %s, "date": "%s",
  "fesbench_note": "benchmarks/load/run_vs_nginx.sh %s %s %s: medians over the rounds"},
 "benchmarks": [
  {"name": "BM_HttpParameterSet/fesbench_us_per_request", "run_type": "iteration", "cpu_time": %s, "time_unit": "us"},
  {"name": "BM_HttpParameterSet/nginx_us_per_request", "run_type": "iteration", "cpu_time": %s, "time_unit": "us"}],
 "fesbench_ratio": %s}\n' \
    "$(hostname)" "$(nproc)" "$(awk '/^cpu MHz/ {printf "%.0f", $4; exit}' /proc/cpuinfo)" \
    "$(date -u +%Y-%m-%dT%H:%M:%S+00:00)" "$seconds" "$connections" "$rounds" \
    "$(median "${f_us[@]}")" "$(median "${n_us[@]}")" "$(median "${ratios[@]}")" >"$FESBENCH_LOAD_JSON"
fi
