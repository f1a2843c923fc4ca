#!/usr/bin/env bash
# Soak run: capture -> server -> viewer over LCM for N frames (synthetic scene, looping), with
# periodic checkpoints; samples the server's resident memory from its status every few seconds.
# Prints the samples and the growth between the first quarter and the end.
#   tests/bench/soak.sh BUILD_DIR [FRAMES=3000] [SCENE=tube] [VOXEL=0.008]
set -uo pipefail
build=${1:?build dir}
frames=${2:-3000}
scene=${3:-tube}
voxel=${4:-0.008}
work=$(mktemp -d)
pids=()
trap 'kill -INT ${pids[*]:-} 2>/dev/null; sleep 1; kill -9 ${pids[*]:-} 2>/dev/null; rm -rf "$work"' EXIT
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$build/pocl-cache}
url="udpm://239.255.76.67:$((7700 + $$ % 90))?ttl=0&recv_buf_size=4194304"
status() { "$build/server/vdeform-control" --lcm-url "$url" --command status --wait 3 2>/dev/null; }
"$build/server/vdeform-server" --lcm-url "$url" --voxel-size "$voxel" --checkpoint "$work/ckpt" \
  --checkpoint-interval 10 --quiet >"$work/server.log" 2>&1 &
pids+=("$!")
"$build/viewer_client/vdeform-viewer" --headless --quiet --lcm-url "$url" >"$work/viewer.log" 2>&1 &
pids+=("$!")
sleep 3
"$build/capture_client/vdeform-capture" --source "synthetic:$scene" --loop --lockstep --lcm-url "$url" --quiet \
  >"$work/capture.log" 2>&1 &
pids+=("$!")
start=$SECONDS
echo "seconds,frames_processed,model_frames,resident_mb,fps"
first_rss=""
while :; do
  sleep 5
  s=$(status) || continue
  n=$(echo "$s" | sed -n 's/^frames_processed=//p')
  m=$(echo "$s" | sed -n 's/^model_frames=//p')
  rss=$(echo "$s" | sed -n 's/^resident_memory_bytes=//p')
  fps=$(echo "$s" | sed -n 's/^fps=//p')
  [ -n "$n" ] || continue
  mb=$(awk -v b="$rss" 'BEGIN{printf "%.1f", b/1048576}')
  echo "$((SECONDS - start)),$n,$m,$mb,$fps"
  [ -z "$first_rss" ] && [ "$n" -ge $((frames / 4)) ] && first_rss=$mb && first_n=$n
  [ "$n" -ge "$frames" ] && break
done
echo "soak: $n frames in $((SECONDS - start)) s; resident memory ${first_rss} MB at frame $first_n, $mb MB at frame $n"
awk -v a="$first_rss" -v b="$mb" 'BEGIN{printf "soak: growth over the last three quarters: %.1f MB (%.2f%%)\n", b-a, 100*(b-a)/a}'
grep -ci "error\|warning" "$work/server.log" | sed 's/^/server log warnings+errors: /'
