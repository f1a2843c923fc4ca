#!/usr/bin/env bash
# The guards in front of LCM 1.3.1's fragment reassembly, against what its reassembly lets a
# datagram do: a fragment whose offset wraps LCM's 32-bit bounds check (the copy lands 4 GB past the
# buffer), then one sender filling 200 MB of an incomplete message.
#   1. The server's own guard (a socket filter every vdeform program attaches to LCM's receive
#      socket; no root, no nft): the server survives and its RSS stays within 5 %. Asserted.
#   2. deploy/lcm-guard.nft with the in-process guard off ($VD_NO_LCM_GUARD=1): the same, and the
#      nft counters show both attacks dropped. Asserted; needs root and nft, else left out.
#   3. Neither guard: what happens is reported, not asserted (with Debian 12's LCM 1.3.1 the server
#      dies with SIGSEGV; a fixed LCM would not). It shows the attack of 1 and 2 is real.
# As root the test runs in a network namespace of its own; otherwise on the host, on its own port.
#   lcm_guard_test.sh BUILD_DIR
set -uo pipefail
build=$1
. "$(dirname "$0")/e2e_lib.sh"
root=$(cd "$(dirname "$0")/../.." && pwd)
work=$(mktemp -d)
server=""
ns=""
cleanup() {
  [ -n "$server" ] && kill -9 "$server" 2>/dev/null
  if [ -n "$ns" ]; then
    ip netns pids "$ns" 2>/dev/null | xargs -r kill -9
    ip netns del "$ns" 2>/dev/null
  fi
  rm -rf "$work"
}
trap cleanup EXIT
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$build/pocl-cache}
group=239.255.76.67
port=$((7600 + $$ % 90))
if [ "$(id -u)" = 0 ] && ip netns add "vdguard$$" 2>/dev/null; then
  ns=vdguard$$
  ip -n "$ns" link set lo up
  ip -n "$ns" route add 224.0.0.0/4 dev lo
  port=7667  # the port deploy/lcm-guard.nft names
fi
url="udpm://$group:$port?ttl=0&recv_buf_size=4194304"
# A prefix, not a function: a function run with & is a subshell, and $! would name the subshell
# (which ignores the SIGINT the test sends) instead of the server. ip netns exec execs in place.
pre=()
[ -n "$ns" ] && pre=(ip netns exec "$ns")
fail() { echo "LCM GUARD FAIL: $*"; tail -5 "$work"/server_*.log; exit 1; }
in_ns() { "${pre[@]}" "$@"; }
rss() { in_ns "$build/server/vdeform-control" --lcm-url "$url" --command status --wait 3 2>/dev/null |
  sed -n 's/^resident_memory_bytes=//p'; }
start_server() {  # log name
  "${pre[@]}" "$build/server/vdeform-server" --lcm-url "$url" --voxel-size 0.008 --quiet \
    --snapshot-dir "$work/snap" >"$work/server_$1.log" 2>&1 &
  server=$!
  vd_wait_for_server "$server" "$work/server_$1.log" rss "LCM GUARD"
}
attack() {
  in_ns "$build/tests/e2e/vd_hostile_publisher" wrap --group $group --port $port >/dev/null &&
    in_ns "$build/tests/e2e/vd_hostile_publisher" fill --group $group --port $port --count 200 >/dev/null
}
survives() {  # phase name: the attack, then the server must be alive with its RSS within 5 %
  local before after
  before=$(rss)
  attack || fail "the attack could not be sent"
  sleep 1
  kill -0 "$server" 2>/dev/null || fail "$1: the server died"
  after=$(rss)
  echo "$1: server alive, RSS $((before >> 20)) MB before, $((after >> 20)) MB after 200 MB of an incomplete message"
  [ $((after * 100)) -lt $((before * 105)) ] || fail "$1: RSS grew from $before to $after bytes"
  kill -INT "$server"
  wait "$server" || fail "$1: server exited with $? after SIGINT"
}

start_server inprocess
survives "in-process guard"

if [ -n "$ns" ] && command -v nft >/dev/null; then
  in_ns nft -f "$root/deploy/lcm-guard.nft" || fail "cannot load deploy/lcm-guard.nft"
  VD_NO_LCM_GUARD=1 start_server nft
  survives "nft guard alone"
  counters=$(in_ns nft list table inet vdeform_lcm_guard | sed -n 's/.*counter packets \([0-9]*\) .*/\1/p' | tr '\n' ' ')
  set -- $counters
  [ "${1:-0}" -ge 3000 ] || fail "the nft guard dropped ${1:-0} fragments of the 200 MB message"
  [ "${2:-0}" -ge 1 ] || fail "the nft guard dropped no wrapping fragment"
  echo "nft guard counters: $1 fragments of messages over 8 MiB, $2 placed beyond 8 MiB"
  in_ns nft delete table inet vdeform_lcm_guard
else
  echo "nft guard: left out (needs root, a network namespace and nft)"
fi

VD_NO_LCM_GUARD=1 start_server unguarded
attack
sleep 1
if kill -0 "$server" 2>/dev/null; then
  echo "unguarded: the server survived (this LCM checks fragment offsets without wrapping)"
  kill -INT "$server"
  wait "$server"
else
  wait "$server"
  echo "unguarded: the server died with exit status $? (LCM 1.3.1's wrapping fragment check)"
fi
server=""
echo "LCM GUARD OK"
