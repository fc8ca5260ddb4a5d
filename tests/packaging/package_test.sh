#!/usr/bin/env bash
# The Debian package (README, "Install on a lab PC"; packaging/), one step
# per ctest test (label `package`):
#
#   package_test.sh build BUILD_DIR        cpack -G DEB into BUILD_DIR/packaging/out
#   package_test.sh contents BUILD_DIR     dpkg-deb -I/-c: metadata, files, modes;
#                                          lintian: no errors (warnings printed)
#   package_test.sh install BUILD_DIR      dpkg --root into a temporary tree; the
#                                          service user made there; the installed
#                                          server started as that user on the
#                                          unit's state folder: health, web
#                                          client, file modes, an online backup,
#                                          SIGTERM, --migrate's backup, a newer
#                                          schema refused
#   package_test.sh units BUILD_DIR        systemd-analyze verify of the installed
#                                          units; security exposure printed
#
# A step that needs root (dpkg --root with chown) exits 77 (skipped) without it.
set -euo pipefail

if [[ ${1:-} == --help || ${1:-} == -h ]]; then
  sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
  exit 0
fi
step=${1:?give a step: build, contents, install or units}
build_dir=$(cd "${2:?give the build folder}" && pwd)
out_dir=$build_dir/packaging/out

fail() { echo "package_test $step: FAIL: $*" >&2; exit 1; }
say() { echo "package_test $step: $*"; }

deb() {
  local found=("$out_dir"/fesbench_*.deb)
  [[ -f ${found[0]} ]] || fail "no package in $out_dir (the package.build test makes it)"
  echo "${found[0]}"
}

# A temporary root with the package installed by dpkg, its maintainer
# scripts run outside a chroot with DPKG_ROOT set (as for a bootstrap), and
# /etc/passwd and /etc/group of this machine, so the user it makes is new.
install_root() {
  local root=$1
  mkdir -p "$root/var/lib/dpkg/info" "$root/var/lib/dpkg/updates" "$root/etc"
  : >"$root/var/lib/dpkg/status"
  cp /etc/passwd /etc/group "$root/etc/"
  # The package's dependencies are this machine's libraries (checked by
  # dpkg-shlibdeps when it was built), not installed into the tree.
  dpkg --root="$root" --force-script-chrootless --force-depends --log=/dev/null \
    -i "$(deb)" >"$root/dpkg.log" 2>&1 || { cat "$root/dpkg.log"; fail "dpkg -i"; }
}

case $step in
build)
  rm -rf "$out_dir"
  (cd "$build_dir" && cpack -G DEB --config CPackConfig.cmake) || fail "cpack"
  say "built $(deb) ($(stat -c %s "$(deb)") bytes)"
  ;;

contents)
  package=$(deb)
  info=$(dpkg-deb -I "$package")
  echo "$info"
  for field in 'Package: fesbench' 'Version: ' 'Architecture: ' 'Maintainer: ' 'Section: science'; do
    grep -q "^ $field" <<<"$info" || fail "control has no '$field'"
  done
  # Runtime dependencies from the linked libraries (dpkg-shlibdeps).
  depends=$(dpkg-deb -f "$package" Depends)
  for library in libc6 libstdc++6 libsqlite3-0 libssl3 libpq5 libfastrtps2.9 libarchive13 libsystemd0 systemd; do
    grep -q "\b$library\b" <<<"$depends" || fail "Depends lacks $library: $depends"
  done
  for script in postinst prerm postrm conffiles; do
    grep -q " $script" <<<"$info" || fail "no $script in the control archive"
  done
  [[ $(dpkg-deb --ctrl-tarfile "$package" | tar -xO ./conffiles) == /etc/fesbench/config.json ]] ||
    fail "config.json is not the conffile"
  listing=$(dpkg-deb -c "$package")
  expect=(
    '-rwxr-xr-x root/root .* ./usr/bin/fesbench-server$'
    '-rwxr-xr-x root/root .* ./usr/bin/fesbench$'
    '-rwxr-xr-x root/root .* ./usr/bin/fesbench-model$'
    '-rwxr-xr-x root/root .* ./usr/bin/fesbench-dds-monitor$'
    '-rwxr-xr-x root/root .* ./usr/bin/fesbench-sm2-emulator$'
    ' ./usr/share/fesbench/web/index.html$'
    ' ./usr/share/fesbench/web/app-[A-Z0-9]*\.js$'
    ' ./usr/share/doc/fesbench/README.md$'
    ' ./usr/share/doc/fesbench/docs/SAFETY.md$'
    ' ./usr/share/doc/fesbench/copyright$'
    ' ./usr/share/doc/fesbench/changelog.gz$'
    ' ./usr/share/man/man1/fesbench-server.1.gz$'
    ' ./usr/share/man/man1/fesbench.1.gz$'
    ' ./usr/share/man/man1/fesbench-model.1.gz$'
    ' ./usr/share/man/man1/fesbench-dds-monitor.1.gz$'
    '-rw-r--r-- root/root .* ./lib/systemd/system/fesbench-server.service$'
    ' ./lib/systemd/system/fesbench-backup.service$'
    ' ./lib/systemd/system/fesbench-backup.timer$'
    ' ./usr/lib/sysusers.d/fesbench.conf$'
    '-rw-r--r-- root/root .* ./etc/fesbench/config.json$'
  )
  for pattern in "${expect[@]}"; do
    grep -q -- "$pattern" <<<"$listing" || fail "no file matching '$pattern' in the package"
  done
  ! grep -q ' ./usr/local/' <<<"$listing" || fail "files under /usr/local"
  # The man page is the program's --help.
  dpkg-deb --fsys-tarfile "$package" | tar -xO ./usr/share/man/man1/fesbench-server.1.gz | gzip -dc |
    grep -qF -- 'backup\-keep\-days' || fail "fesbench-server.1 does not carry --help's flags"
  say "$(wc -l <<<"$listing") entries; Depends: $depends"
  # lintian: errors fail, warnings are printed (root: lintian says it would rather not).
  status=0
  lintian_output=$(lintian --fail-on error "$package" 2>&1) || status=$?
  lintian_output=$(grep -v 'running with root privileges' <<<"$lintian_output" || true)
  ((status == 0)) || { echo "$lintian_output"; fail "lintian errors"; }
  say "lintian: 0 errors, $(grep -c '^W: ' <<<"$lintian_output" || true) warnings"
  [[ -z $lintian_output ]] || echo "$lintian_output"
  ;;

install)
  [[ $(id -u) -eq 0 ]] || { say "SKIP: needs root (dpkg --root, a second user)"; exit 77; }
  root=$(mktemp -d /tmp/fesbench-install.XXXXXX)
  server_pid=
  cleanup() {
    [[ -z $server_pid ]] || kill -KILL "$server_pid" 2>/dev/null || true
    rm -rf "$root"
  }
  trap cleanup EXIT
  chmod 0755 "$root"  # the service user walks through it
  install_root "$root"
  grep -q '^Setting up fesbench' "$root/dpkg.log" || { cat "$root/dpkg.log"; fail "not configured"; }
  # The postinst made the system user (systemd-sysusers), in dialout.
  entry=$(grep '^fesbench:' "$root/etc/passwd") || fail "no user fesbench in the tree's /etc/passwd"
  IFS=: read -r _ _ uid gid _ home shell <<<"$entry"
  say "user fesbench: uid $uid gid $gid home $home shell $shell"
  ((uid < 1000)) || fail "fesbench is not a system user (uid $uid)"
  [[ $shell == */nologin ]] || fail "fesbench may log in ($shell)"
  dialout=$(grep '^dialout:' "$root/etc/group") || fail "no group dialout"
  grep -q '[:,]fesbench\(,\|$\)' <<<"$dialout" || fail "fesbench is not in dialout: $dialout"
  dialout_gid=$(cut -d: -f3 <<<"$dialout")

  # What the unit's StateDirectory=fesbench (mode 0700) makes before a start.
  state=$root/var/lib/fesbench
  install -d -m 0700 -o "$uid" -g "$gid" "$state"
  # The unit's User=, Group=, SupplementaryGroups=dialout, NoNewPrivileges=.
  as_service_user=(setpriv --reuid="$uid" --regid="$gid" --groups="$dialout_gid" --inh-caps=-all
                   --no-new-privs)
  server=$root/usr/bin/fesbench-server
  # The installed config, its paths moved into the tree; a free port, no DDS.
  args=(--config "$root/etc/fesbench/config.json" --db "$state/fesbench.db" --data-dir "$state"
        --port 0 --dds-transport off --time-scale 0)
  umask 022  # the server makes its files private whatever umask it is given
  log=$root/server.log
  "${as_service_user[@]}" "$server" "${args[@]}" >"$log" 2>&1 &
  server_pid=$!
  port=
  for _ in $(seq 200); do
    port=$(sed -n 's|^fesbench-server: listening on http://127.0.0.1:\([0-9]*\)/$|\1|p' "$log")
    [[ -n $port ]] && break
    kill -0 "$server_pid" 2>/dev/null || { cat "$log"; fail "the installed server exited"; }
    sleep 0.1
  done
  [[ -n $port ]] || { cat "$log"; fail "the installed server did not listen within 20 s"; }
  say "installed server listening on port $port as uid $(ps -o uid= -p "$server_pid" | tr -d ' ')"
  [[ $(ps -o uid= -p "$server_pid" | tr -d ' ') == "$uid" ]] || fail "server not running as fesbench"
  grep -q "web client from $root/usr/share/fesbench/web" "$log" ||
    { cat "$log"; fail "the installed server does not serve the installed web client by default"; }
  http_get() {  # PATH → the whole answer (bash's /dev/tcp: no client needed)
    exec 3<>"/dev/tcp/127.0.0.1/$port"
    printf 'GET %s HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n' "$1" >&3
    cat <&3
    exec 3<&-
  }
  health=$(http_get /api/v1/health)
  grep -q '^HTTP/1.1 200' <<<"$health" || fail "health: $health"
  say "health: $(tail -1 <<<"$health")"
  http_get / | grep -q '^HTTP/1.1 200' || fail "GET / (the web client) is not 200"

  # Files and folders: the service user's only (docs/SAFETY.md, "Files").
  check_mode() {  # PATH MODE
    [[ -e $1 ]] || fail "missing $1"
    local got
    got=$(stat -c '%a %u' "$1")
    [[ $got == "$2 $uid" ]] || fail "$1 is mode/owner $got, expected $2 $uid"
  }
  check_mode "$state" 700
  for file in fesbench.db fesbench.db-wal fesbench.db-shm fesbench.db.lock admin.token; do
    check_mode "$state/$file" 600
  done
  # The backup timer's step, while the server runs.
  "${as_service_user[@]}" "$server" --config "$root/etc/fesbench/config.json" --db "$state/fesbench.db" \
    --data-dir "$state" --backup >"$root/backup.log" 2>&1 || { cat "$root/backup.log"; fail "--backup"; }
  cat "$root/backup.log"
  check_mode "$state/backups" 700
  backups=("$state"/backups/fesbench-*.db)
  check_mode "${backups[0]}" 600
  # SIGTERM: a clean stop, exit 0.
  kill -TERM "$server_pid"
  status=0
  wait "$server_pid" || status=$?
  server_pid=
  ((status == 0)) || { cat "$log"; fail "exit $status at SIGTERM"; }
  grep -q 'fesbench-server: stopped' "$log" || fail "no clean stop"
  # A database from a newer fesbench (a downgrade) is refused, naming its schema.
  "${as_service_user[@]}" "$server" "${args[@]}" --migrate >"$root/migrate.log" 2>&1 || { cat "$root/migrate.log"; fail "--migrate"; }
  grep -q 'is at schema version [0-9]*; nothing to migrate' "$root/migrate.log" || { cat "$root/migrate.log"; fail "--migrate said"; }
  latest=$(sed -n 's/.*at schema version \([0-9]*\);.*/\1/p' "$root/migrate.log")
  # The postinst's step backs the database up also when nothing is to migrate.
  grep -q "backup of schema version $latest in $state/backups/fesbench-.*-schema-$latest.db" \
    "$root/migrate.log" || { cat "$root/migrate.log"; fail "--migrate made no backup first"; }
  pre_migration=("$state"/backups/fesbench-*-schema-"$latest".db)
  check_mode "${pre_migration[0]}" 600
  newer=$((latest + 1))
  "${as_service_user[@]}" /usr/bin/python3 -c "import sqlite3,sys; c=sqlite3.connect(sys.argv[1]); c.execute('PRAGMA user_version = $newer'); c.commit()" "$state/fesbench.db"
  status=0
  "${as_service_user[@]}" "$server" "${args[@]}" --migrate >"$root/migrate.log" 2>&1 || status=$?
  cat "$root/migrate.log"
  ((status == 1)) || fail "--migrate on schema $newer: exit $status, expected 1"
  grep -q "schema version $newer, newer than this fesbench-server .* knows ($latest): refusing to downgrade" \
    "$root/migrate.log" || fail "the refusal does not name the schema versions"
  say "installed, served as fesbench, backed up, stopped, backed up by --migrate, and a schema-$newer database refused"
  ;;

units)
  root=$(mktemp -d /tmp/fesbench-units.XXXXXX)
  trap 'rm -rf "$root"' EXIT
  if [[ $(id -u) -eq 0 ]]; then
    install_root "$root"
  else
    dpkg-deb -x "$(deb)" "$root"
  fi
  # The targets the units name, from this machine's systemd, beside them.
  cp -n /lib/systemd/system/*.target "$root/lib/systemd/system/"
  units=(fesbench-server.service fesbench-backup.service fesbench-backup.timer)
  (cd "$root" && systemd-analyze verify --man=no --root="$root" "${units[@]/#/lib/systemd/system/}") ||
    fail "systemd-analyze verify"
  say "systemd-analyze verify: ${units[*]} pass"
  for unit in fesbench-server.service fesbench-backup.service; do
    report=$(systemd-analyze security --offline=true --root="$root" "$root/lib/systemd/system/$unit" 2>&1) ||
      { echo "$report"; fail "systemd-analyze security $unit"; }
    say "$(grep 'Overall exposure level' <<<"$report")"
  done
  ;;

*) fail "unknown step $step" ;;
esac
