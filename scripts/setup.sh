#!/usr/bin/env bash
# Installs what fesbench needs from Debian's packages (only what is missing),
# then configures and builds it. Idempotent and non-interactive; run as root
# (or with sudo available) on Debian 12.
#
#   scripts/setup.sh [BUILD_DIR]                    default BUILD_DIR: build
#   scripts/setup.sh --server-packages [BUILD_DIR]  only what building the server
#                                                   and the web page needs; no build
#                                                   (scripts/run-server.sh)
#
# Once every package of a list was found installed, a stamp in BUILD_DIR
# (setup-packages.stamp, setup-server-packages.stamp) holds the list's hash,
# and later runs with the same list skip the check (1.5 s of dpkg-query);
# delete the stamp to check again.
set -euo pipefail

if [[ ${1:-} == --help || ${1:-} == -h ]]; then
  sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
  exit 0
fi
server_only=false
if [[ ${1:-} == --server-packages ]]; then
  server_only=true
  shift
fi

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${1:-"$root/build"}

# What configuring the project and building fesbench-server and the web
# page need (the fesbench_run_server target; GoogleTest and Google Benchmark
# because the configuration finds them).
server_packages=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev libboost-dev libboost-math-dev nlohmann-json3-dev
  libsqlite3-dev libssl-dev libcpp-httplib-dev
  libfastrtps-dev libfastcdr-dev fastddsgen
  libgtest-dev libgmock-dev libbenchmark-dev
  libcli11-dev openssl
  nodejs
  libarchive-dev
  libedf-dev
  libpq-dev
  libsystemd-dev
)
# The rest: the tests, the Python client, the Debian package's tools.
packages=(
  "${server_packages[@]}"
  chromium
  gnuplot-nox
  python3-pandas
  python3-requests python3-numpy python3-matplotlib python3-nbconvert python3-ipykernel
  jupyter-nbconvert
  postgresql
  help2man lintian systemd
)
# libedf-dev: EDFlib, the session archive's EMG as EDF+ (api/bids.h).
# libsystemd-dev: fesbench-server's sd_notify readiness (Type=notify service).
# help2man: the man pages of the Debian package, from each program's --help;
# lintian, systemd (systemd-analyze, systemd-sysusers): the package tests
# (tests/packaging: lintian errors, unit verification, the service user).
# python3-*, jupyter-nbconvert: the Python client (clients/python), its tests
# and its example notebook run headless (tests/python), all with /usr/bin/python3.
# libpq-dev: the PostgreSQL engine's client library (--db postgresql://…);
# postgresql: the server the tests start themselves (initdb in a temporary
# folder, as the postgres user when run as root).
# The web client's build and browser tests (clients/web, tests/browser): Node
# and npm (npm packages come from the npm registry via package-lock.json),
# Debian's chromium for Playwright. A Node that already brings its own npm
# (e.g. NodeSource's nodejs) needs no Debian npm.
if ! command -v npm >/dev/null 2>&1; then
  server_packages+=(npm)
  packages+=(npm)
fi

stamp=$build_dir/setup-packages.stamp
if $server_only; then
  packages=("${server_packages[@]}")
  stamp=$build_dir/setup-server-packages.stamp
fi
list_hash=$(printf '%s\n' "${packages[@]}" | sha256sum | cut -d' ' -f1)
if [[ ! -f $stamp || $(<"$stamp") != "$list_hash" ]]; then
  missing=()
  for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if ((${#missing[@]})); then
    echo "setup: installing ${missing[*]}"
    sudo_cmd=()
    [[ $(id -u) -eq 0 ]] || sudo_cmd=(sudo)
    export DEBIAN_FRONTEND=noninteractive
    "${sudo_cmd[@]}" apt-get update -qq
    "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
  fi
  mkdir -p "$build_dir"
  echo "$list_hash" >"$stamp"
fi
$server_only && exit 0

jobs=${FESBENCH_JOBS:-$(nproc)}
cmake -S "$root" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build "$build_dir" -j "$jobs"
