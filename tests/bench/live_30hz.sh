#!/usr/bin/env bash
# Live: a 30 Hz capture without lockstep feeds a running server (defaults, 4 mm). Prints what the
# capture sent, the server's processed fraction and rate, and its capture-to-mesh latency p50/p95.
#   tests/bench/live_30hz.sh BUILD_DIR [SCENE] [FRAMES]
set -euo pipefail
build=$(cd "$1" && pwd)
scene=${2:-tube}
frames=${3:-150}
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$build/pocl-cache}
work=$(mktemp -d)
trap 'kill -INT ${srv:-} 2>/dev/null || true; rm -rf "$work"' EXIT
url="udpm://239.255.76.67:$((7900 + $$ % 90))?ttl=0&recv_buf_size=4194304"
# A folder source: decoding PNG costs the capture far less than rendering the scene live.
"$build/capture_client/vdeform-capture" --source "synthetic:$scene" --write "$work/scene" --count "$frames" --quiet
date -u
"$build/server/vdeform-server" --lcm-url "$url" --quiet >"$work/server.log" 2>&1 &
srv=$!
sleep 4
"$build/capture_client/vdeform-capture" --source "folder:$work/scene" --fps 30 --lcm-url "$url" --quiet
sleep 3
"$build/server/vdeform-control" --command status --lcm-url "$url" --wait 3 | grep -E "^(frames_received|frames_processed|frames_dropped|fps|latency_ms_p50|latency_ms_p95)="
kill -INT "$srv"
wait "$srv"
srv=
grep -E "^vdeform-server: received|^stages|^latency" "$work/server.log"
