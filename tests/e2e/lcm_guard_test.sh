#!/usr/bin/env bash
# deploy/lcm-guard.nft against what LCM 1.3.1's reassembly lets a datagram do, in a network
# namespace of its own (root, nft and ip netns, else skipped): with the guard loaded, a server
# survives a fragment whose offset wraps LCM's 32-bit bounds check and keeps its memory while one
# sender holds 200 MB of an incomplete message; the guard's counters show both dropped. Without the
# guard the same datagrams are sent once more and what happens is reported (with Debian 12's LCM
# 1.3.1 the server dies with SIGSEGV), not asserted: a fixed LCM would not crash.
#   lcm_guard_test.sh BUILD_DIR
set -uo pipefail
build=$1
. "$(dirname "$0")/e2e_lib.sh"
root=$(cd "$(dirname "$0")/../.." && pwd)
skip() { echo "LCM GUARD SKIP: $*"; exit 77; }
[ "$(id -u)" = 0 ] || skip "needs root (network namespace, nftables)"
command -v nft >/dev/null || skip "nft not found (apt-get install nftables)"
ns=vdguard$$
ip netns add "$ns" 2>/dev/null || skip "cannot create a network namespace"
work=$(mktemp -d)
server=""
cleanup() {
  [ -n "$server" ] && kill -9 "$server" 2>/dev/null
  ip netns pids "$ns" 2>/dev/null | xargs -r kill -9
  ip netns del "$ns" 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$build/pocl-cache}
ip -n "$ns" link set lo up
ip -n "$ns" route add 224.0.0.0/4 dev lo
group=239.255.76.67
port=7667
url="udpm://$group:$port?ttl=0&recv_buf_size=4194304"
fail() { echo "LCM GUARD FAIL: $*"; tail -5 "$work"/server_*.log; exit 1; }
in_ns() { ip netns exec "$ns" "$@"; }
rss() { in_ns "$build/server/vdeform-control" --lcm-url "$url" --command status --wait 3 2>/dev/null |
  sed -n 's/^resident_memory_bytes=//p'; }
start_server() {  # log name
  ip netns exec "$ns" "$build/server/vdeform-server" --lcm-url "$url" --voxel-size 0.008 --quiet \
    --snapshot-dir "$work/snap" >"$work/server_$1.log" 2>&1 &
  server=$!
  vd_wait_for_server "$server" "$work/server_$1.log" rss "LCM GUARD"
}
attack() {
  in_ns "$build/tests/e2e/vd_hostile_publisher" wrap --group $group --port $port >/dev/null &&
    in_ns "$build/tests/e2e/vd_hostile_publisher" fill --group $group --port $port --count 200 >/dev/null
}

in_ns nft -f "$root/deploy/lcm-guard.nft" || fail "cannot load deploy/lcm-guard.nft"
start_server guarded
before=$(rss)
attack || fail "the attack could not be sent"
sleep 1
kill -0 "$server" 2>/dev/null || fail "the server died behind the guard"
after=$(rss)
echo "guarded: server alive, RSS $((before >> 20)) MB before, $((after >> 20)) MB after 200 MB of an incomplete message"
[ $((after * 100)) -lt $((before * 105)) ] || fail "RSS grew from $before to $after bytes behind the guard"
counters=$(in_ns nft list table inet vdeform_lcm_guard | sed -n 's/.*counter packets \([0-9]*\) .*/\1/p' | tr '\n' ' ')
set -- $counters
[ "${1:-0}" -ge 3000 ] || fail "the guard dropped ${1:-0} fragments of the 200 MB message"
[ "${2:-0}" -ge 1 ] || fail "the guard dropped no wrapping fragment"
echo "guard counters: $1 fragments of messages over 8 MiB, $2 placed beyond 8 MiB"
kill -INT "$server"
wait "$server" || fail "server exited with $? after SIGINT"

in_ns nft delete table inet vdeform_lcm_guard
start_server unguarded
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
