#!/usr/bin/env bash
# Load held with 1, 2 and 4 viewers: capture -> server -> V headless viewers over LCM on this host,
# lockstep (every frame processed, none dropped), the same frames each time. Prints per run the
# end-to-end frames per second, what each viewer received, and the message sizes; the ratios to
# the 1-viewer run of the same invocation are the comparable figures on a noisy machine.
#   tests/bench/viewer_load.sh BUILD_DIR [FRAMES=40] [VOXEL=0.004] [VIEWERS="1 2 4"]
set -uo pipefail
build=${1:?build dir}
frames=${2:-40}
voxel=${3:-0.004}
counts=${4:-1 2 4}
work=$(mktemp -d)
pids=()
trap 'kill -INT ${pids[*]:-} 2>/dev/null; sleep 1; kill -9 ${pids[*]:-} 2>/dev/null; rm -rf "$work"' EXIT
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$build/pocl-cache}
printf "%-8s %8s %8s %10s %12s %14s %12s %10s\n" viewers frames fps "vs 1" "frame KB" "live mesh KB" "per viewer" "failed"
base=""
for v in $counts; do
  url="udpm://239.255.76.67:$((7600 + $$ % 90))?ttl=0&recv_buf_size=4194304"
  pids=()
  "$build/server/vdeform-server" --lcm-url "$url" --voxel-size "$voxel" --quiet >"$work/server$v.log" 2>&1 &
  pids+=("$!")
  for i in $(seq 1 "$v"); do
    "$build/viewer_client/vdeform-viewer" --headless --quiet --lcm-url "$url" >"$work/viewer$v-$i.log" 2>&1 &
    pids+=("$!")
  done
  sleep 3
  t0=$(date +%s%N)
  "$build/capture_client/vdeform-capture" --source synthetic:tube --count "$frames" --lockstep --lockstep-timeout 30 \
    --lcm-url "$url" --quiet >"$work/capture$v.log" 2>&1
  t1=$(date +%s%N)
  sleep 2
  kill -INT "${pids[@]}" 2>/dev/null
  for p in "${pids[@]}"; do wait "$p"; done
  pids=()
  fps=$(awk -v n="$frames" -v a="$t0" -v b="$t1" 'BEGIN{printf "%.2f", n/((b-a)/1e9)}')
  [ -z "$base" ] && base=$fps
  frame_kb=$(sed -n 's/.*mean \([0-9.]*\) KB\/frame.*/\1/p' "$work/capture$v.log")
  live_min=999999 failed=0 bytes=0 lives=0
  for i in $(seq 1 "$v"); do
    f="$work/viewer$v-$i.log"
    l=$(sed -n 's/.*(live \([0-9]*\),.*/\1/p' "$f")
    b=$(sed -n 's/^  bytes \([0-9]*\) .*/\1/p' "$f")
    d=$(sed -n 's/.*decoded \([0-9]*\) .*/\1/p' "$f")
    fl=$(sed -n 's/.*), failed \([0-9]*\)$/\1/p' "$f")
    [ "${l:-0}" -lt "$live_min" ] && live_min=${l:-0}
    failed=$((failed + ${fl:-0}))
    bytes=$((bytes + ${b:-0} * 1))
    lives=$((lives + ${d:-0}))
  done
  mesh_kb=$(awk -v b="$bytes" -v n="$lives" 'BEGIN{printf "%.1f", (n ? b/n/1024 : 0)}')
  ratio=$(awk -v a="$fps" -v b="$base" 'BEGIN{printf "%.2f", a/b}')
  printf "%-8s %8s %8s %10s %12s %14s %12s %10s\n" "$v" "$frames" "$fps" "$ratio" "$frame_kb" "$mesh_kb" \
    "$live_min live" "$failed"
  grep -h "^vdeform-server: received" "$work/server$v.log" | sed 's/^/    /'
done
