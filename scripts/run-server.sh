#!/usr/bin/env bash
# The run command from source: installs what is missing, builds only the
# server and the web page it serves (the fesbench_run_server target, not the
# tests), and starts fesbench-server with the simulated bench. The server
# prints the address it actually listens on ("fesbench-server: listening on
# http://HOST:PORT/", the port it bound, also for --port 0) and where the
# admin token is. Ctrl-C (SIGINT) or SIGTERM stops it cleanly (a running
# protocol is stopped with stimulation zero, the database is closed).
#
#   scripts/run-server.sh [fesbench-server flags...]
#   e.g. scripts/run-server.sh --port 9000 --time-scale 0
#        scripts/run-server.sh --data-dir /srv/fesbench      (database and token there)
#        scripts/run-server.sh --db /srv/f.db --data-dir /srv/fesbench-files
#   scripts/run-server.sh --help      this text (the server's flags: fesbench-server --help)
#
# Data: without --db, --data-dir or --config the database and admin.token go
# to ./data in the checkout; with --data-dir alone the database goes there too.
# Only the packages the server's build needs are installed (scripts/setup.sh
# --server-packages; the tests' come with scripts/test.sh), and their check
# is skipped while its stamp in the build folder matches the package list.
# A new build folder compiles the server's sources in unity batches
# (-DFESBENCH_UNITY_SERVER=ON). An up-to-date build is a no-op, so a warm
# start is listening within about 0.3 s. Environment: FESBENCH_BUILD_DIR
# (default build), FESBENCH_JOBS (default: all cores).
set -euo pipefail

if [[ ${1:-} == --help || ${1:-} == -h ]]; then
  sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
  exit 0
fi

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${FESBENCH_BUILD_DIR:-"$root/build"}

"$root/scripts/setup.sh" --server-packages "$build_dir"
if [[ ! -f $build_dir/build.ninja ]]; then
  launcher=()
  if command -v ccache >/dev/null; then
    launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
  fi
  # A new build folder: the server's own sources as unity batches (a first
  # build in about half the time; the tests, built later by scripts/test.sh,
  # stay file by file).
  cmake -S "$root" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DFESBENCH_UNITY_SERVER=ON "${launcher[@]}" >/dev/null
fi
cmake --build "$build_dir" -j "${FESBENCH_JOBS:-$(nproc)}" --target fesbench_run_server

# Where the data goes: the flags' own choice, else ./data.
given_db=false
given_data_dir=false
given_config=false
data_dir=
previous=
for arg in "$@"; do
  case $arg in
    --db | --db=*) given_db=true ;;
    --data-dir=*) given_data_dir=true; data_dir=${arg#--data-dir=} ;;
    --data-dir) given_data_dir=true ;;
    --config | --config=*) given_config=true ;;
  esac
  [[ $previous == --data-dir ]] && data_dir=$arg
  previous=$arg
done
defaults=()
if ! $given_db && ! $given_config; then
  if $given_data_dir; then
    defaults=(--db "$data_dir/fesbench.db")
  else
    defaults=(--db "$root/data/fesbench.db")
  fi
fi
exec "$build_dir/server/fesbench-server" "${defaults[@]}" "$@"
