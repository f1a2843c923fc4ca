#!/usr/bin/env bash
# The deployment files (deploy/): every flag of the programs is documented in their environment
# files, the systemd units are headless and restart on failure (and pass systemd-analyze verify
# where it exists), and prepare-host.sh --check reports what it finds.
#   deploy_test.sh BUILD_DIR
set -u
build=$1
root=$(cd "$(dirname "$0")/../.." && pwd)
fail=0
bad() { echo "FAIL: $*"; fail=1; }

check_flags() {  # program, env file, help text
  local flags
  flags=$(echo "$3" | grep -oE '^  --[a-z0-9-]+' | sed 's/^  //' | sort -u)
  [ -n "$flags" ] || bad "$1 --help lists no flags"
  local n=0
  for f in $flags; do
    n=$((n + 1))
    grep -qE "^#   $f( |:|$)" "$2" || bad "$f of $1 is not documented in $(basename "$2")"
  done
  echo "$1: $n flags, all documented in $(basename "$2")"
}
check_flags vdeform-server "$root/deploy/vdeform-server.env" "$("$build/server/vdeform-server" --help)"
check_flags vdeform-capture "$root/deploy/vdeform-capture.env" "$("$build/capture_client/vdeform-capture" --help)"
check_flags vdeform-web "$root/deploy/vdeform-web.env" "$("$build/viewer_client/vdeform-web" --help)"

for unit in "$root"/deploy/systemd/*.service; do
  name=$(basename "$unit")
  grep -q '^Restart=on-failure' "$unit" || bad "$name does not restart on failure"
  grep -q '^EnvironmentFile=/etc/vdeform/' "$unit" || bad "$name has no environment file"
  grep -q '^UnsetEnvironment=DISPLAY' "$unit" || bad "$name does not drop DISPLAY"
  if command -v systemd-analyze >/dev/null 2>&1; then
    # The binaries are not installed here: that one complaint is expected.
    out=$(systemd-analyze verify "$unit" 2>&1 | grep -v 'is not executable' | grep -v '^$')
    [ -z "$out" ] || bad "systemd-analyze verify $name: $out"
  fi
done
grep -q '^POCL_CACHE_DIR=' "$root/deploy/vdeform-server.env" || bad "server.env does not set POCL_CACHE_DIR"

# The server flags in the env file's VDEFORM_SERVER_ARGS and the Containerfile's CMD exist, and
# every build output the Containerfile installs is built (the image itself cannot be built here:
# no container daemon, no registry).
server_help=$("$build/server/vdeform-server" --help)
args=$(sed -n 's/^VDEFORM_SERVER_ARGS="\(.*\)"/\1/p' "$root/deploy/vdeform-server.env")
cmd=$(sed -n 's/^CMD \[\(.*\)\]/\1/p' "$root/deploy/Containerfile" | tr -d '",')
for f in $(echo "$args $cmd" | grep -oE -- '--[a-z0-9-]+' | sort -u); do
  echo "$server_help" | grep -qE "^  $f( |$)" || bad "deploy uses $f, which vdeform-server does not know"
done
for out in $(grep -oE '/src/vdeform/build/[A-Za-z0-9_/.-]+' "$root/deploy/Containerfile" | sed 's|/src/vdeform/build/||'); do
  [ -x "$build/$out" ] || bad "the Containerfile installs build/$out, which the build does not make"
done

# prepare-host.sh: a well-formed report whatever the host, and a failing check when the
# requirement cannot be met (a receive buffer larger than any host has).
out=$("$root/deploy/prepare-host.sh" --check)
rc=$?
[ "$rc" = 0 ] || [ "$rc" = 1 ] || bad "prepare-host.sh --check exited $rc"
echo "$out" | grep -qE '^(OK|FIX)  +rmem: ' || bad "prepare-host.sh --check printed no rmem line: $out"
echo "$out" | grep -qE '^(OK|FIX)  +mcast: ' || bad "prepare-host.sh --check printed no mcast line: $out"
out=$(VDEFORM_RMEM=999999999999 "$root/deploy/prepare-host.sh" --check)
[ $? = 1 ] || bad "prepare-host.sh --check passed an impossible receive buffer"
echo "$out" | grep -qE '^FIX  rmem: ' || bad "no FIX line for the receive buffer: $out"
"$root/deploy/prepare-host.sh" --nonsense >/dev/null 2>&1
[ $? = 2 ] || bad "prepare-host.sh accepted an unknown mode"
"$root/deploy/prepare-host.sh" --check --dev no-such-interface0 >/dev/null 2>&1
[ $? = 2 ] || bad "prepare-host.sh accepted an interface that does not exist"

[ "$fail" = 0 ] && echo "deploy files: OK"
exit "$fail"
