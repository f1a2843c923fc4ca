#!/usr/bin/env bash
# The server's resident memory under a sustained flood (issue 15, bounded memory): a server with
# frame keys takes 3 signed frames of the tube, then vd_hostile_publisher floods its group with junk
# datagrams, junk frames, dangling fragments from 64 ports and complete 6.6 MB messages for
# SECONDS; the RSS from the server's status every STEP seconds.
#   tests/bench/flood_memory.sh BUILD_DIR [SECONDS] [STEP]
set -uo pipefail
build=$1
seconds=${2:-60}
step=${3:-10}
work=$(mktemp -d)
trap 'kill -INT $server 2>/dev/null; sleep 0.5; kill -9 $server 2>/dev/null; rm -rf "$work"' EXIT
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$build/pocl-cache}
group=239.255.76.67
port=$((7600 + $$ % 90))
url="udpm://$group:$port?ttl=0&recv_buf_size=4194304"
rss() { "$build/server/vdeform-control" --lcm-url "$url" --command status --wait 3 | sed -n 's/^resident_memory_bytes=//p'; }
counter() { "$build/server/vdeform-control" --lcm-url "$url" --command status --wait 3 | sed -n "s/^$1=//p"; }
openssl rand -hex 32 >"$work/frame.key" && chmod 600 "$work/frame.key"
"$build/server/vdeform-server" --lcm-url "$url" --voxel-size 0.008 --frame-key-file "$work/frame.key" \
  --snapshot-dir "$work/snap" --quiet >"$work/server.log" 2>&1 &
server=$!
until [ -n "$(rss 2>/dev/null)" ]; do sleep 0.2; done
"$build/capture_client/vdeform-capture" --source synthetic:tube --count 3 --lockstep --source-id cam \
  --frame-key-file "$work/frame.key" --lcm-url "$url" --quiet
sleep 1
base=$(rss)
echo "seconds rss_mb growth_pct malformed"
echo "0 $((base >> 20)) 0.0 $(counter rejected_malformed_message)"
for ((t = step; t <= seconds; t += step)); do
  "$build/tests/e2e/vd_hostile_publisher" flood --group $group --port $port --seconds "$step" >"$work/flood" || exit 1
  r=$(rss)
  echo "$t $((r >> 20)) $(awk -v a="$r" -v b="$base" 'BEGIN { printf "%.1f", 100 * (a - b) / b }') $(counter rejected_malformed_message)"
done
cat "$work/flood"
