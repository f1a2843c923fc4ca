#!/usr/bin/env bash
# Multi-host LCM on one machine: three network namespaces play three hosts on one LAN segment.
#
#   ns A (10.213.0.1) vdeform-capture --+
#   ns B (10.213.0.2) vdeform-server ---+-- bridge br0 in a fourth namespace (snooping off)
#   ns C (10.213.0.3) two vdeform-viewer+
#
# Each host namespace has lo and eth0 (a veth whose peer is a bridge port) and the multicast route
# 224.0.0.0/4 dev eth0: LCM has no interface option, the routing table picks the interface.
# Nothing is added to the caller's namespace; deleting the namespaces removes every link.
#
# Phase 1 (ttl=0 stays on the host): capture in A publishes frames with ttl=0 while lcm-logger
#   listens in A and in B. A's logger must record the frames (they are on the wire in A), B's
#   logger none, and the server in B must not count them.
# Phase 2 (ttl=1 crosses the segment), with every key: capture in A sends frames signed under the
#   frame key in lockstep with ttl=1 (every frame waits for the server's status from B, which must
#   verify under the output key, so both directions are exercised); the server in B must report
#   exactly those frames received and processed, none dropped or rejected; each viewer in C (URL
#   from $LCM_DEFAULT_URL, the other programs take --lcm-url; --key-file) must save one decodable
#   live mesh per frame (> 1000 vertices), receive status messages naming those counts and refuse
#   none of them; a SAVE_SNAPSHOT signed under the control key, sent from C, is taken in B.
#
#   netns_test.sh BUILD_DIR        exit 0 pass, 1 fail, 77 skip (not root, no netns/veth/bridge)
set -uo pipefail
build=${1:?usage: netns_test.sh BUILD_DIR}
frames=${VD_NETNS_FRAMES:-6}     # phase 2, lockstep
leak_frames=20                   # phase 1, 10 fps
port=$((7900 + $$ % 90))
group=239.255.76.67
url0="udpm://$group:$port?ttl=0&recv_buf_size=4194304"
url1="udpm://$group:$port?ttl=1&recv_buf_size=4194304"
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$build/pocl-cache}

skip() { echo "NETNS SKIP: $*"; exit 77; }
[ "$(id -u)" -eq 0 ] || skip "needs root to create network namespaces (run as root or under sudo)"
command -v ip >/dev/null || skip "iproute2 'ip' not found"
command -v lcm-logger >/dev/null || skip "lcm-logger (Debian liblcm-bin) not found"
for p in server/vdeform-server server/vdeform-control capture_client/vdeform-capture viewer_client/vdeform-viewer; do
  [ -x "$build/$p" ] || { echo "NETNS FAIL: $build/$p missing"; exit 1; }
done

tag=vdmh$$
nsA=${tag}a nsB=${tag}b nsC=${tag}c nsL=${tag}lan
# A run killed with SIGKILL (no trap) leaves its namespaces behind: remove those of this test
# whose creating shell is gone and that hold no process.
for ns in $(ip netns list 2>/dev/null | awk '{print $1}' | grep -E '^vdmh[0-9]+(a|b|c|lan)$'); do
  owner=$(echo "$ns" | sed -E 's/^vdmh([0-9]+).*/\1/')
  if ! kill -0 "$owner" 2>/dev/null && [ -z "$(ip netns pids "$ns" 2>/dev/null)" ]; then
    echo "removing stale namespace $ns" && ip netns del "$ns"
  fi
done
work=$(mktemp -d)
pids=()
created=()
cleanup() {
  local p ns
  for p in "${pids[@]}"; do kill -INT "$p" 2>/dev/null; done
  sleep 0.5
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null; done
  # Anything else still inside our own namespaces (started by this script) goes too, so the
  # namespaces and their links really disappear.
  for ns in "${created[@]}"; do
    for p in $(ip netns pids "$ns" 2>/dev/null); do kill -9 "$p" 2>/dev/null; done
  done
  for ns in "${created[@]}"; do ip netns del "$ns" 2>/dev/null; done
  rm -rf "$work"
}
trap cleanup EXIT
trap 'exit 130' INT TERM
# Runs a command in the background and waits for it, so that a signal to this script runs the
# trap at once instead of after the command; returns the command's status.
run() {
  "$@" &
  local c=$! rc
  pids+=("$c")
  wait "$c"
  rc=$?
  forget "$c"
  return $rc
}
# Drops a reaped process from the list the clean-up signals (its id may be reused).
forget() {
  local p keep=()
  for p in "${pids[@]}"; do [ "$p" = "$1" ] || keep+=("$p"); done
  pids=("${keep[@]}")
}

fail() {
  echo "NETNS FAIL: $*"
  for f in "$work"/*.log; do
    [ -f "$f" ] || continue
    echo "== $f"
    tail -25 "$f"
  done
  exit 1
}

# --- keys: frames (capture, server), control (server, vdeform-control), output (server; capture
# and viewers verify) ---------------------------------------------------------------------------
for k in frame output; do
  openssl rand -hex 32 >"$work/$k.key" 2>/dev/null || od -An -tx1 -N32 /dev/urandom | tr -d ' \n' >"$work/$k.key"
done
head -c 32 /dev/urandom | base64 >"$work/control.key"
chmod 600 "$work/frame.key" "$work/output.key" "$work/control.key"

# --- topology ------------------------------------------------------------------------------
for ns in $nsL $nsA $nsB $nsC; do
  ip netns add "$ns" 2>"$work/netns.err" || skip "'ip netns add $ns' failed: $(cat "$work/netns.err")"
  created+=("$ns")
  ip -n "$ns" link set lo up || fail "lo up in $ns"
done
ip -n $nsL link add br0 type bridge mcast_snooping 0 2>"$work/bridge.err" ||
  skip "cannot create a Linux bridge: $(cat "$work/bridge.err")"
ip -n $nsL link set br0 up || fail "br0 up"
i=0
for ns in $nsA $nsB $nsC; do
  i=$((i + 1))
  ip -n $nsL link add "port$i" type veth peer name eth0 netns "$ns" 2>"$work/veth.err" ||
    skip "cannot create a veth pair: $(cat "$work/veth.err")"
  ip -n $nsL link set "port$i" master br0 up || fail "port$i to br0"
  ip -n "$ns" addr add "10.213.0.$i/24" dev eth0 || fail "address in $ns"
  ip -n "$ns" link set eth0 up || fail "eth0 up in $ns"
  ip -n "$ns" route add 224.0.0.0/4 dev eth0 || fail "multicast route in $ns"
done
# Link sanity without ping (not always installed): a UDP datagram from A makes A resolve C's
# address by ARP over the bridge; a failure here is the topology, not LCM.
for _ in $(seq 1 25); do
  ip netns exec $nsA bash -c 'echo probe >/dev/udp/10.213.0.3/9' 2>/dev/null
  ip -n $nsA neigh show 10.213.0.3 | grep -q lladdr && break
  sleep 0.2
done
ip -n $nsA neigh show 10.213.0.3 | grep -q lladdr || fail "10.213.0.3 does not answer ARP from $nsA over the bridge"
rmem=$(ip netns exec $nsB cat /proc/sys/net/core/rmem_max 2>/dev/null || echo 0)
echo "namespaces $nsA $nsB $nsC on bridge br0 in $nsL; multicast route 224.0.0.0/4 dev eth0; rmem_max $rmem"
[ "$rmem" -ge 4194304 ] || echo "warning: net.core.rmem_max $rmem < 4 MB (deploy/prepare-host.sh --apply)"

# --- server in B, viewers in C -----------------------------------------------------------------
t_start=$(date +%s.%N)
ip netns exec $nsB "$build/server/vdeform-server" --lcm-url "$url1" --voxel-size 0.008 \
  --frame-key-file "$work/frame.key" --control-key-file "$work/control.key" --output-key-file "$work/output.key" \
  --snapshot-dir "$work/snap" >"$work/server.log" 2>&1 &
server=$!
pids+=("$server")
viewers=()
for v in 1 2; do
  mkdir -p "$work/view$v"
  LCM_DEFAULT_URL="$url1" ip netns exec $nsC "$build/viewer_client/vdeform-viewer" --headless --quiet \
    --save-dir "$work/view$v" --key-file "$work/output.key" --timeout 60 >"$work/viewer$v.log" 2>&1 &
  viewers+=("$!")
  pids+=("$!")
done
for _ in $(seq 1 450); do
  grep -q "vdeform-server on" "$work/server.log" && break
  kill -0 "$server" 2>/dev/null || fail "server exited during start-up"
  sleep 0.1
done
grep -q "vdeform-server on" "$work/server.log" || fail "server not up after 45 s"
grep "vdeform-server on" "$work/server.log"

# --- phase 1: ttl=0 must stay in A -------------------------------------------------------------
ip netns exec $nsA lcm-logger -q -f --lcm-url="$url0" -c VDEFORM_FRAMES "$work/frames_in_A.lcmlog" >"$work/loggerA.log" 2>&1 &
loggerA=$!
pids+=("$loggerA")
ip netns exec $nsB lcm-logger -q -f --lcm-url="$url1" -c VDEFORM_FRAMES "$work/frames_in_B.lcmlog" >"$work/loggerB.log" 2>&1 &
loggerB=$!
pids+=("$loggerB")
sleep 1
run timeout 20 ip netns exec $nsA "$build/capture_client/vdeform-capture" --source synthetic:tube \
  --count $leak_frames --fps 10 --source-id ttl0-probe --lcm-url "$url0" --quiet >"$work/capture_ttl0.log" 2>&1 ||
  fail "ttl=0 capture exited with $? (124: timed out)"
sleep 1
kill -INT $loggerA
wait $loggerA || fail "lcm-logger in $nsA exited non-zero"
forget $loggerA
# Each logged event carries its channel name once. B's logger keeps running (it flushes every
# 100 ms) and must see the phase-2 frames: it is a working receiver, not a deaf one.
events() { grep -a -o VDEFORM_FRAMES "$1" 2>/dev/null | wc -l; }
inA=$(events "$work/frames_in_A.lcmlog")
inB=$(events "$work/frames_in_B.lcmlog")
sent0=$(sed -n 's/^vdeform-capture: sent \([0-9]*\) frames.*/\1/p' "$work/capture_ttl0.log")
echo "phase 1 (ttl=0): capture in A sent ${sent0:-?}; seen on the wire in A: $inA, in B: $inB"
[ "${sent0:-0}" -eq $leak_frames ] || fail "ttl=0 capture sent ${sent0:-no} of $leak_frames frames"
[ "$inA" -eq $leak_frames ] || fail "lcm-logger in A recorded $inA of $leak_frames ttl=0 frames (the positive control)"
[ "$inB" -eq 0 ] || fail "ttl=0 frames crossed from $nsA to $nsB: $inB recorded there"

# --- phase 2: ttl=1 crosses ---------------------------------------------------------------------
t2=$(date +%s.%N)
run timeout 45 ip netns exec $nsA "$build/capture_client/vdeform-capture" --source synthetic:tube --count "$frames" \
  --lockstep --lockstep-timeout 10 --lockstep-retries 1 --frame-key-file "$work/frame.key" \
  --output-key-file "$work/output.key" --lcm-url "$url1" --quiet >"$work/capture.log" 2>&1 ||
  fail "ttl=1 capture exited with $? (124: timed out; frames or status do not cross the bridge)"
t3=$(date +%s.%N)
cat "$work/capture.log"
run timeout 20 ip netns exec $nsC "$build/server/vdeform-control" --lcm-url "$url1" --command snapshot \
  --path from-c --key-file "$work/control.key" --wait 5 >"$work/control.log" 2>&1 ||
  fail "signed SAVE_SNAPSHOT from $nsC exited with $?: $(cat "$work/control.log")"
grep -q "snapshot taken" "$work/control.log" || fail "SAVE_SNAPSHOT: $(cat "$work/control.log")"
for _ in $(seq 1 50); do [ -s "$work/snap/from-c/live.ply" ] && break; sleep 0.1; done
[ -s "$work/snap/from-c/live.ply" ] || fail "the signed SAVE_SNAPSHOT from $nsC wrote no $work/snap/from-c/live.ply"
echo "signed SAVE_SNAPSHOT from C taken in B: $(ls "$work/snap/from-c" | tr '\n' ' ')"
sleep 1.5
kill -INT "${pids[@]}" 2>/dev/null
wait $loggerB || fail "lcm-logger in $nsB exited non-zero"
inB2=$(events "$work/frames_in_B.lcmlog")
echo "phase 2 (ttl=1): frames seen on the wire in B: $inB2"
[ "$inB2" -eq "$frames" ] || fail "lcm-logger in B recorded $inB2 frames, expected the $frames ttl=1 frames only"
for p in "$server" "${viewers[@]}"; do wait "$p" || fail "a program exited non-zero after SIGINT"; done
pids=()

line=$(grep "^vdeform-server: received" "$work/server.log") || fail "no server summary"
echo "server in B: $line"
# Exactly the phase-2 frames: none of the 20 ttl=0 frames arrived, none of ours were lost.
echo "$line" | grep -q "received $frames, processed $frames, dropped 0, rejected 0" || fail "server counters: $line"
echo "server in B counted 0 of the $leak_frames ttl=0 frames and all $frames ttl=1 frames"
grep -q "sent $frames frames (0 re-sent)" "$work/capture.log" || fail "lockstep capture: $(cat "$work/capture.log")"
grep -q "meshes and status are signed under the output key" "$work/server.log" || fail "the server's output is not signed"
grep -q "ignored 0 status messages not signed by the server" "$work/capture.log" ||
  fail "the lockstep capture refused the server's own status: $(cat "$work/capture.log")"
for v in 1 2; do
  log=$work/viewer$v.log
  n=$(ls "$work/view$v"/frame-*.mesh.ply 2>/dev/null | wc -l)
  [ "$n" -eq "$frames" ] || fail "viewer $v saved $n of $frames live meshes"
  minv=
  for f in "$work/view$v"/frame-*.mesh.ply; do
    verts=$(head -c 400 "$f" | grep -a -m1 "^element vertex" | awk '{print $3}')
    [ -n "$verts" ] && [ "$verts" -gt 1000 ] || fail "$f has ${verts:-no} vertices"
    [ -z "$minv" ] || [ "$verts" -lt "$minv" ] && minv=$verts
  done
  grep -q "meshes received .*failed 0$" "$log" || fail "viewer $v: mesh decode failures"
  status=$(sed -n 's/^  status messages \([0-9]*\), failed 0$/\1/p' "$log")
  [ -n "$status" ] || fail "viewer $v: no status count or failed status messages"
  [ "$status" -ge 4 ] || fail "viewer $v received only $status status messages"
  grep -q "last status: .*received $frames, processed $frames, dropped 0, rejected 0" "$log" ||
    fail "viewer $v: last status does not name the $frames frames"
  grep -q "refused under --key-file: meshes 0 unsigned, 0 bad signature, 0 replayed; status 0 unsigned, 0 bad signature, 0 replayed" "$log" ||
    fail "viewer $v refused some of the server's signed output: $(grep 'refused under' "$log")"
  echo "viewer $v in C: $n live meshes (min $minv vertices), $status status messages, $(grep -m1 'meshes received' "$log" | sed 's/^ *//'), $(grep -m1 '^  bytes' "$log" | sed 's/^ *//')"
done
awk -v a="$t_start" -v b="$t2" -v c="$t3" -v n="$frames" \
  'BEGIN { printf "timing: start-up + phase 1 %.1f s, phase 2 %.1f s (%.2f s per lockstep frame)\n", b - a, c - b, (c - b) / n }'
echo "NETNS OK"
