#!/usr/bin/env bash
# End-to-end: vdeform-capture -> vdeform-server -> two vdeform-viewer processes over LCM on this
# host. Asserts every frame was processed (lockstep: no drops), nothing was rejected, and both
# viewers received and saved valid meshes for every frame.
#   stream_e2e_test.sh BUILD_DIR
set -uo pipefail
build=$1
frames=8
work=$(mktemp -d)
trap 'kill -INT ${pids[*]:-} 2>/dev/null; sleep 0.5; kill -9 ${pids[*]:-} 2>/dev/null; rm -rf "$work"' EXIT
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$build/pocl-cache}
port=$((7900 + $$ % 90))
url="udpm://239.255.76.67:$port?ttl=0&recv_buf_size=4194304"
fail() { echo "E2E FAIL: $*"; for f in "$work"/*.log; do echo "== $f"; tail -20 "$f"; done; exit 1; }
pids=()

"$build/server/vdeform-server" --lcm-url "$url" --voxel-size 0.008 >"$work/server.log" 2>&1 &
server=$!
pids+=("$server")
for v in 1 2; do
  mkdir -p "$work/view$v"
  "$build/viewer_client/vdeform-viewer" --headless --quiet --lcm-url "$url" --save-dir "$work/view$v" \
    --timeout 120 >"$work/viewer$v.log" 2>&1 &
  pids+=("$!")
done
for _ in $(seq 1 300); do
  grep -q "vdeform-server on" "$work/server.log" && break
  if ! kill -0 "$server" 2>/dev/null; then
    if grep -q "cannot open LCM" "$work/server.log"; then
      echo "E2E SKIP: LCM multicast unavailable on this host (see README: ip route add 224.0.0.0/4 dev lo)"
      exit 77
    fi
    fail "server exited during start-up"
  fi
  sleep 0.1
done
"$build/capture_client/vdeform-capture" --source synthetic:tube --count $frames --lockstep --lockstep-timeout 20 \
  --lcm-url "$url" --quiet >"$work/capture.log" 2>&1 || fail "capture exited with $?"
sleep 1.5
kill -INT "${pids[@]}"
for p in "${pids[@]}"; do wait "$p" || fail "a process exited non-zero after SIGINT"; done
pids=()

line=$(grep "^vdeform-server: received" "$work/server.log") || fail "no server summary"
echo "$line"
echo "$line" | grep -q "received $frames, processed $frames, dropped 0, rejected 0" || fail "server counters: $line"
for v in 1 2; do
  n=$(ls "$work/view$v"/frame-*.mesh.ply 2>/dev/null | wc -l)
  [ "$n" -eq "$frames" ] || fail "viewer $v saved $n of $frames live meshes"
  for f in "$work/view$v"/frame-*.mesh.ply; do
    verts=$(head -c 400 "$f" | grep -a -m1 "^element vertex" | awk '{print $3}')
    [ -n "$verts" ] && [ "$verts" -gt 1000 ] || fail "$f has ${verts:-no} vertices"
  done
  echo "viewer $v: $n live meshes, each > 1000 vertices"
done
echo "E2E OK"
