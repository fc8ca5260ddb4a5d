#!/usr/bin/env bash
# The sanitizer step of CI: builds the server and the suites that take hostile
# input or hold its state (HTTP front end and fuzz, storage, run service,
# protocol runner, safety) with AddressSanitizer + UndefinedBehaviorSanitizer
# (build-asan/), and the concurrency tests with ThreadSanitizer (build-tsan/),
# at -O1 -g1, then runs them. The model/identification, CLI, DDS and browser
# suites are left out (most of a cold build, no outside bytes or own threads).
# Any ASan/LSan/TSan report, from a test executable or from a fesbench-server
# a test started, fails the step (reports are written to
# DIR/sanitizer-reports/ and printed). UBSan aborts the process at the first
# report, on its stderr (GCC's UBSan beside ASan does not take log_path): a
# test's own fails it in ctest's output; a server's kills the server, and the
# test that started it fails (it must exit 0 at SIGTERM).
#
#   scripts/sanitize.sh [asan|tsan|all]      default: all
#
# Prints wall and CPU seconds of each build and test run. Environment:
# FESBENCH_JOBS (parallel jobs, default nproc), FESBENCH_ASAN_DIR,
# FESBENCH_TSAN_DIR (build directories). Run scripts/setup.sh first on a
# fresh machine (scripts/test.sh does).
set -euo pipefail

if [[ ${1:-} == --help || ${1:-} == -h ]]; then
  sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
  exit 0
fi

mode=${1:-all}
case $mode in asan|tsan|all) ;; *) echo "sanitize.sh: unknown mode '$mode' (asan, tsan or all)" >&2; exit 2;; esac

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
jobs=${FESBENCH_JOBS:-$(nproc)}

# Suites under ASan+UBSan: the ones that take hostile input or hold the
# server's state (HTTP front end with the fuzz, edge, slow-client, admission
# and restart tests against an instrumented fesbench-server; SSE and
# authentication; storage; the run service with its recorder thread; the job
# pool). Not the model/identification, protocol-unit or CLI suites: their
# Eigen-heavy code costs most of a cold build and takes no outside bytes (the
# model library itself is built with ASan only, see model/CMakeLists.txt).
asan_targets=(fesbench_test_postgres_fixture storage_tests job_pool_tests run_service_tests http_integration_tests
  http_front_end_tests fesbench-server)
# Only the suites built here run (ctest lists the others as *_NOT_BUILT; the
# browser tests and the Debian package tests, which need the whole build, are
# left out by label).
# TSan: the tests whose threads are the project's own (no DDS: Fast DDS is not
# instrumented) — job pool, sample hub and SSE viewers, run/bench services,
# the runner's recorder and watchdog, safe bench e-stop from another thread,
# slow clients against the connection threads.
tsan_targets=(fesbench_test_postgres_fixture job_pool_tests run_service_tests protocol_tests server_tests sciencemode2_pty_tests
  http_front_end_tests http_integration_tests fesbench-server)
# Left out under TSan: single-threaded identification runs and the random
# plan fuzz (≈ 150 s CPU, no threads to check), and the hostile-input HTTP
# suites, which ASan+UBSan covers.
tsan_exclude='_NOT_BUILT$|^(Seeds/)?Rapid\.|^SafetyFuzz\.TenThousand|^(FuzzTest|ProtocolEdgesTest|BadInputTest|RolesTest|CorrectionsTest|RestartTest)\.'

launcher=()
if command -v ccache >/dev/null; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi

# CPU seconds (user + system) of all finished child processes so far: on a
# shared machine a fairer figure than the wall time, printed beside it.
cpu_seconds() {
  # Fields 16 and 17 of /proc/PID/stat: waited-for children's user and
  # system time, in clock ticks (the comm field has no spaces here).
  awk -v hz="$(getconf CLK_TCK)" '{ printf "%d", ($16 + $17) / hz }' "/proc/$$/stat"
}

# run NAME DIR SANITIZERS EXCLUDE_REGEX TARGETS...
run() {
  local name=$1 dir=$2 sanitizers=$3 exclude=$4; shift 4
  local targets=("$@")
  echo "== $name: configure $dir"
  cmake -S "$root" -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" -DFESBENCH_SANITIZE="$sanitizers" \
    -DFESBENCH_BUILD_BENCHMARKS=OFF -DFESBENCH_WERROR=OFF -DCMAKE_UNITY_BUILD=ON \
    "${launcher[@]}" >/dev/null
  echo "== $name: build ${targets[*]}"
  local t0=$SECONDS c0
  c0=$(cpu_seconds)
  # Warnings do not stop this build (GCC 12's -Wmaybe-uninitialized is wrong
  # about std::regex under the sanitizers; the normal build keeps -Werror).
  # `|| return 1`: set -e does not act inside a function called from `||`,
  # and a failed build must not pass as "no reports".
  cmake --build "$dir" -j "$jobs" --target "${targets[@]}" || return 1
  echo "== $name: built in $((SECONDS - t0)) s ($(($(cpu_seconds) - c0)) s CPU)"
  local reports=$dir/sanitizer-reports
  rm -rf "$reports"; mkdir -p "$reports"
  t0=$SECONDS
  c0=$(cpu_seconds)
  local status=0
  (cd "$dir" && ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:log_path=$reports/asan" \
      UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1" \
      TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:log_path=$reports/tsan:suppressions=$root/scripts/tsan.supp" \
      ctest --output-on-failure --no-tests=error -j "$jobs" -E "$exclude" -LE 'browser|package') || status=$?
  echo "== $name: tests ran in $((SECONDS - t0)) s ($(($(cpu_seconds) - c0)) s CPU)"
  if compgen -G "$reports/*" >/dev/null; then
    echo "== $name: sanitizer reports:" >&2
    for f in "$reports"/*; do echo "--- $f" >&2; cat "$f" >&2; done
    status=1
  fi
  return $status
}

status=0
if [[ $mode == asan || $mode == all ]]; then
  run asan "${FESBENCH_ASAN_DIR:-$root/build-asan}" address,undefined '_NOT_BUILT$' "${asan_targets[@]}" || status=1
fi
if [[ $mode == tsan || $mode == all ]]; then
  run tsan "${FESBENCH_TSAN_DIR:-$root/build-tsan}" thread "$tsan_exclude" "${tsan_targets[@]}" || status=1
fi
exit $status
