#!/usr/bin/env bash
# The fast benchmarks against their committed baselines (benchmarks/baseline/):
# runs model_bench, identify_bench and the DDS block latency with
# --benchmark_format=json (3 repetitions, medians), and with nginx and wrk
# the HTTP figure of benchmarks/load/run_vs_nginx.sh, into a temporary folder,
# then benchmarks/compare_baseline.py names every figure more than 25 % slower
# than its baseline. Report only: exits 0 whatever the figures (a shared
# machine is too noisy to fail on). --update keeps this run as the new
# baselines (commit them with the machine they were measured on).
#
#   benchmarks/run_baseline.sh [--update]          (about 40 s on 2 cores)
set -euo pipefail

if [[ "${1:-}" == "-h" || "${1:-}" == "--help" ]]; then
  sed -n '2,11p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
  exit 0
fi
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${FESBENCH_BUILD_DIR:-"$root/build"}
update=false
[[ "${1:-}" == "--update" ]] && update=true

out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
run() {  # program, then its own flags
  local program=$1
  shift
  if [[ ! -x "$build_dir/benchmarks/$program" ]]; then
    echo "run_baseline: $build_dir/benchmarks/$program is not built; skipped" >&2
    return 0
  fi
  "$build_dir/benchmarks/$program" --benchmark_repetitions=3 --benchmark_report_aggregates_only=true \
    --benchmark_format=json --benchmark_out_format=json --benchmark_out="$out/$program.json" \
    "$@" >/dev/null
}
run model_bench --benchmark_min_time=0.2
run identify_bench --benchmark_min_time=0.2
run dds_latency_bench --benchmark_filter=BlockLatency
# The HTTP figure against nginx (3 rounds of 3 s; needs nginx and wrk).
if command -v wrk >/dev/null && { command -v nginx >/dev/null || [[ -x /usr/sbin/nginx ]]; }; then
  FESBENCH_LOAD_JSON="$out/http_vs_nginx.json" FESBENCH_BUILD_DIR="$build_dir" \
    timeout 180 "$root/benchmarks/load/run_vs_nginx.sh" 3 32 3 ||
    echo "run_baseline: benchmarks/load/run_vs_nginx.sh failed; skipped" >&2
else
  echo "run_baseline: no nginx or wrk (apt-get install nginx-light wrk); the HTTP figure skipped" >&2
fi

if $update; then
  cp "$out"/*.json "$root/benchmarks/baseline/"
  echo "run_baseline: baselines written to benchmarks/baseline/ ($(ls "$out" | tr '\n' ' '))"
fi
python3 "$root/benchmarks/compare_baseline.py" "$out"/*.json
