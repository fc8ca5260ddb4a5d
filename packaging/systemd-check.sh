#!/usr/bin/env bash
# The Debian package under a real systemd (docs/SAFETY.md, "The service"): a
# manual check, not a ctest test (it needs root, debootstrap, systemd-nspawn
# and a Debian mirror; about a minute, two the first time). A fresh Debian 12
# root is made with debootstrap (kept as a tarball for the next run), the
# package installed into it with apt (its dependencies from the mirror), the
# root booted with systemd as PID 1 in systemd-nspawn (its own network:
# loopback only), and the service checked from inside: readiness, the journal,
# DDS, protocol runs and e-stops through the API and DDS, file modes, the
# serial-port allow-list, stop and crash restart, the backup service and
# timer, a reinstall and an upgrade, and `systemd-analyze security` on the
# running unit. Each check prints PASS or FAIL; the exit code is 1 if any
# failed.
#
#   sudo packaging/systemd-check.sh build/packaging/out/fesbench_0.1.0_amd64.deb
#
# While it runs, a drop-in makes a system call outside the unit's
# SystemCallFilter= kill the server (SIGSYS) instead of failing with EPERM,
# so a filtered call cannot pass unnoticed. The container runs with the
# unified cgroup hierarchy and the bpf() system call allowed: without them
# the container's systemd cannot enforce DevicePolicy= (checked first).
# Needs: debootstrap, systemd-container (systemd-nspawn), dpkg-deb, nsenter.
# Environment: FESBENCH_CHECK_DIR (default /var/tmp/fesbench-systemd-check:
# the base root's tarball, the booted root, the logs), FESBENCH_CHECK_MIRROR
# (default: the host's first Debian mirror in its apt sources, else
# http://deb.debian.org/debian), FESBENCH_CHECK_KEEP=1 (leave the booted
# root in place).
set -euo pipefail

if [[ ${1:-} == --help || ${1:-} == -h ]]; then
  sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
  exit 0
fi
deb=$(realpath "${1:?give the fesbench .deb (build/packaging/out/fesbench_*.deb)}")
[[ $(id -u) -eq 0 ]] || { echo "systemd-check: needs root" >&2; exit 2; }
for tool in debootstrap systemd-nspawn dpkg-deb nsenter; do
  command -v "$tool" >/dev/null || { echo "systemd-check: $tool is missing" >&2; exit 2; }
done

dir=${FESBENCH_CHECK_DIR:-/var/tmp/fesbench-systemd-check}
root=$dir/root
base=$dir/bookworm-base.tar
log=$dir/check.log
mirror=${FESBENCH_CHECK_MIRROR:-$(
  { grep -h '^URIs:' /etc/apt/sources.list.d/*.sources 2>/dev/null | awk '{print $2}'
    grep -h '^deb ' /etc/apt/sources.list /etc/apt/sources.list.d/*.list 2>/dev/null | awk '{print $2}'
  } | grep -v -- '-security' | grep '/debian/\?$' | head -1 || true)}
mirror=${mirror:-http://deb.debian.org/debian}
mkdir -p "$dir"
: >"$log"

failures=0
pass() { printf 'PASS  %s\n' "$*" | tee -a "$log"; }
fail() { printf 'FAIL  %s\n' "$*" | tee -a "$log"; failures=$((failures + 1)); }
note() { printf '      %s\n' "$*" | tee -a "$log"; }
say() { printf 'systemd-check: %s\n' "$*" | tee -a "$log"; }

# --- the root ------------------------------------------------------------------
if [[ ! -f $base ]]; then
  say "debootstrap bookworm (minbase, systemd, dbus, curl) from $mirror"
  rm -rf "$dir/base"
  debootstrap --variant=minbase --include=systemd,systemd-sysv,dbus,curl,passwd \
    bookworm "$dir/base" "$mirror" >>"$log" 2>&1
  tar --numeric-owner -C "$dir/base" -cpf "$base" .
  rm -rf "$dir/base"
fi
rm -rf "$root"
mkdir -p "$root"
tar --numeric-owner -C "$root" -xpf "$base"
echo fesbench-check >"$root/etc/hostname"
cp "$deb" "$root/root/fesbench.deb"
# The upgrade: the same package at a higher version.
version=$(dpkg-deb -f "$deb" Version)
upgrade=$dir/upgrade
rm -rf "$upgrade"
dpkg-deb -R "$deb" "$upgrade"
sed -i "s/^Version: .*/Version: $version+check1/" "$upgrade/DEBIAN/control"
dpkg-deb --root-owner-group -b "$upgrade" "$root/root/fesbench-upgrade.deb" >/dev/null
rm -rf "$upgrade"

nspawn=(systemd-nspawn --quiet --register=no --keep-unit -D "$root")
say "apt install ./fesbench.deb ($version) in the root (dependencies from $mirror)"
if "${nspawn[@]}" --pipe /bin/sh -c 'apt-get update -qq &&
     DEBIAN_FRONTEND=noninteractive apt-get install -y -qq /root/fesbench.deb' >>"$log" 2>&1; then
  pass "apt install of $(basename "$deb") with its dependencies"
else
  fail "apt install (see $log)"
  exit 1
fi

# --- boot ----------------------------------------------------------------------
nspawn_pid=
leader=
stop_container() {
  if [[ -n $leader ]] && kill -0 "$leader" 2>/dev/null; then
    nsenter -t "$leader" -a systemctl poweroff >/dev/null 2>&1 || true
  fi
  if [[ -n $nspawn_pid ]]; then
    for _ in $(seq 100); do kill -0 "$nspawn_pid" 2>/dev/null || break; sleep 0.2; done
    kill -TERM "$nspawn_pid" 2>/dev/null || true
  fi
  [[ ${FESBENCH_CHECK_KEEP:-0} == 1 ]] || rm -rf "$root"
}
trap stop_container EXIT
SYSTEMD_NSPAWN_UNIFIED_HIERARCHY=1 setsid "${nspawn[@]}" -b --private-network \
  --system-call-filter=bpf --machine=fesbench-check >"$dir/console.log" 2>&1 </dev/null &
nspawn_pid=$!
for _ in $(seq 100); do
  leader=$(pgrep -P "$nspawn_pid" | head -1 || true)
  [[ -n $leader && $(cat "/proc/$leader/comm" 2>/dev/null) == systemd ]] && break
  leader=
  sleep 0.2
done
[[ -n $leader ]] || { cat "$dir/console.log"; fail "the container did not boot"; exit 1; }

# A command inside the container (all its namespaces), with a clean environment.
in_ct() {
  nsenter -t "$leader" -a env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root LANG=C.UTF-8 "$@"
}
show() { in_ct systemctl show -p "$2" --value "$1"; }  # UNIT PROPERTY
health() { in_ct curl -sS -m 3 http://127.0.0.1:8080/api/v1/health 2>&1; }
token() { in_ct cat /var/lib/fesbench/admin.token; }
api_get() { in_ct curl -sS -m 5 -H "Authorization: Bearer $(token)" "http://127.0.0.1:8080/api/v1/$1"; }
cli() { in_ct fesbench "$@"; }
wait_active() {  # UNIT: active within 20 s
  for _ in $(seq 100); do
    [[ $(show "$1" ActiveState) == active ]] && return 0
    sleep 0.2
  done
  return 1
}

state=
for _ in $(seq 150); do  # until the manager answers on its bus, then the end of the boot
  state=$(in_ct systemctl is-system-running --wait 2>/dev/null || true)
  [[ -n $state ]] && break
  sleep 0.2
done
if [[ $state == running || $state == degraded ]]; then
  pass "booted: systemd $(in_ct systemctl --version | head -1 | awk '{print $2}') as PID 1, system $state"
  [[ $state == running ]] || note "failed units: $(in_ct systemctl --failed --plain --no-legend | awk '{print $1}' | xargs)"
else
  fail "booted: system $state"
fi

# The container's systemd enforces device policies (a bpf device program).
in_ct mknod -m 0666 /dev/fesbench-check-loop c 10 237
probe=$(in_ct systemd-run --wait --pipe --quiet -p DevicePolicy=closed \
  /bin/sh -c 'exec 3</dev/fesbench-check-loop && echo opened' 2>&1 || true)
if grep -q 'Operation not permitted' <<<"$probe"; then
  pass "the container's systemd enforces DevicePolicy= (a device outside the list: EPERM)"
else
  fail "DevicePolicy= is not enforced here ($probe): the device checks below mean nothing"
fi

# Filtered system calls kill the server from here on (SIGSYS), also the backup's.
for unit in fesbench-server fesbench-backup; do
  in_ct mkdir -p "/run/systemd/system/$unit.service.d"
  in_ct sh -c "printf '[Service]\nSystemCallErrorNumber=\n' >/run/systemd/system/$unit.service.d/zz-check-kill.conf"
done
in_ct systemctl daemon-reload

# --- readiness -----------------------------------------------------------------
if wait_active fesbench-server; then
  pass "fesbench-server.service enabled and started at boot (unit state $(show fesbench-server UnitFileState))"
else
  fail "fesbench-server.service not active after boot: $(in_ct systemctl status fesbench-server --no-pager | tail -5)"
fi
in_ct systemctl restart fesbench-server  # under the drop-in
ready_ok=0
for attempt in 1 2 3; do
  in_ct systemctl stop fesbench-server
  started=$(date +%s%N)
  in_ct systemctl start fesbench-server
  took_ms=$((($(date +%s%N) - started) / 1000000))
  answer=$(health)  # one try, no retry: the port must answer already
  if grep -q '"status":"ok"' <<<"$answer"; then
    ready_ok=$((ready_ok + 1))
    note "start $attempt: systemctl start returned after $took_ms ms; health at once: $answer"
  else
    note "start $attempt: systemctl start returned after $took_ms ms; health: $answer"
  fi
done
if ((ready_ok == 3)) && [[ $(show fesbench-server Type) == notify ]]; then
  pass "Type=notify: systemctl start returned only once the port answered (3 of 3 starts)"
else
  fail "readiness: the port answered right after systemctl start in $ready_ok of 3 starts"
fi
status_text=$(show fesbench-server StatusText)
if [[ $(show fesbench-server ActiveState)/$(show fesbench-server SubState) == active/running &&
      $status_text == "listening on port 8080" ]]; then
  pass "systemctl status: active (running), status \"$status_text\", main PID $(show fesbench-server MainPID) as $(in_ct stat -c %U "/proc/$(show fesbench-server MainPID)")"
else
  fail "systemctl status: $(show fesbench-server ActiveState)/$(show fesbench-server SubState), \"$status_text\""
fi
journal=$(in_ct journalctl -u fesbench-server -o cat --no-pager)
if grep -q '^fesbench-server: listening on http://127.0.0.1:8080/$' <<<"$journal" &&
   grep -q '^fesbench-server: bench sim, time scale 1' <<<"$journal"; then
  pass "the journal holds the server's lines ($(grep -c '^fesbench-server:' <<<"$journal") so far)"
else
  fail "the server's lines are not in the journal"
fi
if grep -qF "$(token)" <<<"$journal"; then
  fail "the first admin's token is in the journal"
elif grep -q 'its token is in /var/lib/fesbench/admin.token (not printed' <<<"$journal"; then
  pass "the first admin's token is not in the journal (it names /var/lib/fesbench/admin.token)"
else
  fail "the journal does not say where the first admin's token is"
fi

# --- DDS, protocol runs, e-stops -------------------------------------------------
in_ct useradd --system labcheck 2>/dev/null || true
benches_root=$(in_ct fesbench-dds-monitor --timeout 10 benches 2>&1 || true)
benches_other=$(in_ct runuser -u labcheck -- fesbench-dds-monitor --timeout 10 benches 2>&1 || true)
if grep -q '^fesbench-check .*kind sim' <<<"$benches_root" &&
   grep -q '^fesbench-check .*kind sim' <<<"$benches_other"; then
  pass "DDS: fesbench-dds-monitor (as root and as another user) sees the bench: $benches_other"
else
  fail "DDS: the monitor does not see the bench: root: $benches_root; other user: $benches_other"
fi
{
  cli login http://127.0.0.1:8080 --token-file /var/lib/fesbench/admin.token
  cli subjects create S01 --leg right --age-years 34 --weight-kg 70 --shank-length-cm 42
  cli sessions create --subject S01 --leg right --date 2026-01-05
} >>"$log"
started=$(date +%s)
if run=$(cli run start 1 tolerance_test --param rate_ma_per_s=5 2>&1) &&
   grep -q '^end done' <<<"$run"; then
  pass "protocol run (tolerance_test, 5 mA/s) through the API: $(grep '^end' <<<"$run" | cut -d' ' -f1-6) in $(($(date +%s) - started)) s"
else
  fail "tolerance_test: $run"
fi
# An e-stop over HTTP in the middle of a run.
in_ct sh -c 'fesbench run start 1 isometric_step_irc >/root/run2.log 2>&1' &
run_pid=$!
sleep 4
cli estop >>"$log"
wait "$run_pid" || true
bench=$(api_get bench)
if grep -q '^end aborted' "$root/root/run2.log" && grep -q '"estop_source":"http (admin)"' <<<"$bench"; then
  pass "e-stop over HTTP during isometric_step_irc: the run ended aborted, source http (admin)"
else
  fail "e-stop over HTTP: $(tail -2 "$root/root/run2.log"); bench: ${bench:0:300}"
fi
cli estop --clear >>"$log"
# DDS: the run's samples to another user, then an e-stop over DDS.
in_ct sh -c 'fesbench run start 1 isometric_step_irc >/root/run3.log 2>&1' &
run_pid=$!
sleep 2
in_ct runuser -u labcheck -- fesbench-dds-monitor samples --run 3 --max 100 \
  --csv /var/tmp/fesbench-check-samples.csv >>"$log" 2>&1 || true
samples=$(in_ct sh -c 'grep -c "^3," /var/tmp/fesbench-check-samples.csv' 2>/dev/null || echo 0)
in_ct env FESBENCH_TOKEN="$(token)" runuser -u labcheck --whitelist-environment=FESBENCH_TOKEN -- \
  fesbench-dds-monitor estop >>"$log" 2>&1 || true
wait "$run_pid" || true
bench=$(api_get bench)
if ((samples >= 100)) && grep -q '^end aborted' "$root/root/run3.log" &&
   grep -q '"estop_source":"dds (admin)"' <<<"$bench"; then
  pass "DDS: $samples samples of run 3 to another user; its e-stop over DDS ended the run (source dds (admin))"
else
  fail "DDS run: $samples samples; $(tail -1 "$root/root/run3.log"); bench: ${bench:0:300}"
fi
cli estop --clear >>"$log"

# --- files -------------------------------------------------------------------------
odd=$(in_ct find /var/lib/fesbench \( -type d ! -perm 0700 \) -o \( -type f ! -perm 0600 \) -o ! -user fesbench)
if [[ -z $odd ]]; then
  pass "/var/lib/fesbench: $(in_ct find /var/lib/fesbench -type f | wc -l) files 0600 and $(in_ct find /var/lib/fesbench -type d | wc -l) folders 0700, all the user fesbench's"
else
  fail "files of another mode or owner: $odd"
fi

# --- the serial port ------------------------------------------------------------------
in_ct cp /etc/fesbench/config.json /root/config.json.packaged
with_stimulator() {  # PORT: the packaged settings with a ScienceMode2 stimulator on PORT
  in_ct sh -c "head -n -1 /root/config.json.packaged | sed '\$ s/\$/,/' >/etc/fesbench/config.json &&
    printf '  \"stimulator\": \"sciencemode2\",\n  \"stimulator-port\": \"%s\",\n  \"stimulator-channel\": 1\n}\n' '$1' >>/etc/fesbench/config.json"
}
open_result() {  # PORT → the server's words about it at its start
  with_stimulator "$1"
  in_ct systemctl restart fesbench-server 2>/dev/null || true
  local said=
  for _ in $(seq 50); do
    said=$(in_ct journalctl -u fesbench-server -o cat --no-pager | grep -F "serial port $1:" | tail -1 || true)
    [[ -n $said ]] && break
    sleep 0.2
  done
  in_ct systemctl stop fesbench-server
  in_ct systemctl reset-failed fesbench-server 2>/dev/null || true
  echo "$said"
}
in_ct sh -c 'mknod -m 0660 /dev/ttyS5 c 4 69 && chgrp dialout /dev/ttyS5'
said=$(open_result /dev/ttyS5)
if grep -q 'No such device or address' <<<"$said"; then
  pass "an allowed port (/dev/ttyS5, c 4:69, root:dialout 0660) passes open()'s permission checks; the driver answers: ${said#*: }"
else
  fail "/dev/ttyS5: $said"
fi
for node in "/dev/mem c 1 1" "/dev/fesbench-check-loop c 10 237"; do
  read -r path _ _ _ <<<"$node"
  in_ct sh -c "[ -e $path ] || mknod $node; chgrp dialout $path; chmod 0660 $path"
  outside=$(in_ct runuser -u fesbench -- sh -c "exec 3<>$path && echo opened" 2>&1 || true)
  said=$(open_result "$path")
  if grep -q 'Operation not permitted' <<<"$said"; then
    pass "a device outside the allow-list ($path) is refused: ${said#*: } (outside the unit, as the same user: ${outside##*: })"
  else
    fail "$path: $said"
  fi
done
# A whole run through the ScienceMode2 driver, to the emulator on a pty.
in_ct systemd-run --quiet --unit=fesbench-check-emulator -p User=fesbench \
  fesbench-sm2-emulator --log /var/tmp/fesbench-check-deliveries.jsonl
pty=
for _ in $(seq 50); do
  pty=$(in_ct journalctl -u fesbench-check-emulator -o cat --no-pager | grep -o '/dev/pts/[0-9]*' | head -1 || true)
  [[ -n $pty ]] && break
  sleep 0.2
done
with_stimulator "$pty"
in_ct systemctl restart fesbench-server
run=$(cli run start 1 tolerance_test --param rate_ma_per_s=5 2>&1 || true)
in_ct systemctl stop fesbench-server fesbench-check-emulator
deliveries=$(in_ct sh -c 'wc -l </var/tmp/fesbench-check-deliveries.jsonl' 2>/dev/null || echo 0)
if grep -q '^end done' <<<"$run" && ((deliveries > 10)); then
  pass "a tolerance_test through the ScienceMode2 driver to the emulator on $pty: $deliveries commands delivered"
else
  fail "the stimulator run on $pty: $(tail -1 <<<"$run"); $deliveries deliveries"
fi
in_ct cp /root/config.json.packaged /etc/fesbench/config.json
in_ct systemctl start fesbench-server

# --- stop and crash --------------------------------------------------------------------
in_ct systemctl stop fesbench-server
last=$(in_ct journalctl -u fesbench-server -o cat --no-pager -n 4)
if [[ $(show fesbench-server ExecMainStatus) == 0 && $(show fesbench-server Result) == success ]] &&
   grep -q '^fesbench-server: stopped$' <<<"$last"; then
  pass "systemctl stop: SIGTERM, \"fesbench-server: stopped\", exit 0"
else
  fail "systemctl stop: status $(show fesbench-server ExecMainStatus), result $(show fesbench-server Result)"
fi
in_ct systemctl start fesbench-server
before=$(show fesbench-server MainPID)
restarts=$(show fesbench-server NRestarts)
# A crash in the middle of a run.
in_ct sh -c 'fesbench run start 1 isometric_step_irc >/root/run-crash.log 2>&1' &
run_pid=$!
sleep 3
in_ct systemctl kill -s SEGV fesbench-server
wait "$run_pid" || true
for _ in $(seq 50); do  # RestartSec=2s
  sleep 0.2
  [[ $(show fesbench-server NRestarts) -gt $restarts && $(show fesbench-server ActiveState) == active ]] && break
done
after=$(show fesbench-server MainPID)
if [[ $(show fesbench-server NRestarts) -gt $restarts && $after != "$before" ]] &&
   grep -q '"status":"ok"' <<<"$(health)"; then
  pass "SIGSEGV: killed (status=11/SEGV), restarted by Restart=on-failure (PID $before -> $after), health ok"
else
  fail "SIGSEGV: restarts $(show fesbench-server NRestarts), PID $before -> $after"
fi
crashed_run=$(sed -n 's/^started run \([0-9]*\) .*/\1/p' "$root/root/run-crash.log")
crashed=$(cli run show "$crashed_run" 2>&1 || true)
if [[ -n $crashed_run ]] && grep -q '^state: failed' <<<"$crashed"; then
  pass "the run the crash interrupted (run $crashed_run) is failed by the restarted server: $(grep '^reason:' <<<"$crashed")"
else
  fail "the interrupted run ${crashed_run:-?}: $(grep -E '^(state|reason):' <<<"$crashed" | xargs)"
fi

# --- backups -------------------------------------------------------------------------------
backups() { in_ct sh -c 'ls /var/lib/fesbench/backups 2>/dev/null' || true; }
count_before=$(backups | wc -l)
if in_ct systemctl start fesbench-backup.service &&
   [[ $(show fesbench-backup Result) == success ]]; then
  made=$(in_ct journalctl -u fesbench-backup -o cat --no-pager | grep '^fesbench-server: backup ' | tail -1)
  pass "fesbench-backup.service: ${made#fesbench-server: } ($count_before -> $(backups | wc -l) backups)"
else
  fail "fesbench-backup.service: $(show fesbench-backup Result)"
fi
timers=$(in_ct systemctl list-timers --all --no-pager)
if grep -q 'fesbench-backup.timer *fesbench-backup.service' <<<"$timers"; then
  pass "systemctl list-timers: next $(grep fesbench-backup.timer <<<"$timers" | awk '{print $1, $2, $3, $4}')"
else
  fail "fesbench-backup.timer is not listed"
fi

# --- reinstall and upgrade ------------------------------------------------------------------
token_before=$(token)
for package in fesbench.deb fesbench-upgrade.deb; do
  count_before=$(backups | wc -l)
  pid_before=$(show fesbench-server MainPID)
  out=$(in_ct env DEBIAN_FRONTEND=noninteractive apt-get install -y --reinstall \
    -o Dpkg::Options::=--force-confold "/root/$package" 2>&1) || { fail "apt install $package: $out"; continue; }
  echo "$out" >>"$log"
  backup_line=$(grep '^fesbench-server: backup of schema version' <<<"$out" || true)
  subjects=$(api_get subjects)
  if [[ -n $backup_line ]] && (($(backups | wc -l) == count_before + 1)) &&
     grep -q '"code":"S01"' <<<"$subjects" && [[ $(token) == "$token_before" ]] &&
     wait_active fesbench-server && [[ $(show fesbench-server MainPID) != "$pid_before" ]]; then
    # shellcheck disable=SC2016 # dpkg-query's field, not the shell's
    pass "apt install ${package%.deb} ($(in_ct dpkg-query -W -f '${Version}' fesbench)): server stopped and started again, ${backup_line#fesbench-server: }, database and token kept"
  else
    fail "apt install $package: backup '${backup_line}', $count_before -> $(backups | wc -l) backups, subjects ${subjects:0:200}"
  fi
done

# --- the filter, then the exposure --------------------------------------------------------------
sys_kills=$(in_ct journalctl -o cat --no-pager -u fesbench-server -u fesbench-backup | grep -c 'status=31/SYS' || true)
if ((sys_kills == 0)); then
  pass "no system call outside the filter in all of the above (none killed by SIGSYS)"
else
  fail "$sys_kills SIGSYS kills: a system call outside SystemCallFilter="
fi
in_ct rm -rf /run/systemd/system/fesbench-server.service.d /run/systemd/system/fesbench-backup.service.d
in_ct systemctl daemon-reload
in_ct systemctl restart fesbench-server
for unit in fesbench-server:1.5 fesbench-backup:1.3; do
  name=${unit%%:*}
  documented=${unit#*:}
  exposure=$(in_ct systemd-analyze security "$name" --no-pager | sed -n 's/.*Overall exposure level for [^:]*: \([0-9.]*\).*/\1/p')
  if [[ -n $exposure ]] && awk -v e="$exposure" -v d="$documented" 'BEGIN { exit !(e <= d) }'; then
    pass "systemd-analyze security $name (online, the running unit): $exposure (documented: $documented)"
  else
    fail "systemd-analyze security $name: '$exposure', documented $documented"
  fi
done

in_ct journalctl -u fesbench-server -u fesbench-backup -o short-iso --no-pager >"$dir/journal.log" 2>&1 || true
say "$failures failed; the journal of the units in $dir/journal.log, this log in $log"
((failures == 0))
