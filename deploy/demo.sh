#!/usr/bin/env bash
# The main job on the embedded default: a built-in synthetic deforming scene streamed through all
# three programs on this host, headless. Sets up what is missing, starts vdeform-server and a
# headless vdeform-viewer, streams the scene with vdeform-capture (lockstep, so nothing is lost),
# stops everything cleanly and prints a summary and the paths of what was written.
#   deploy/demo.sh [--scene NAME] [--frames N] [--voxel-size M] [--out DIR] [--web [--web-port N]]
# --web also starts vdeform-web, prints the page's URL, and keeps it and the server running after
# the stream until Ctrl-C, so the last mesh stays on the page.
# Environment: VD_LCM_URL overrides the LCM URL (default: a private host-only multicast group).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
scene=tube
frames=60
voxel=0.004
out="$here/out/demo"
web=0
web_port=8080
while [ $# -gt 0 ]; do
  case "$1" in
    --scene) scene=$2; shift 2 ;;
    --frames) frames=$2; shift 2 ;;
    --voxel-size) voxel=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --web) web=1; shift ;;
    --web-port) web_port=$2; shift 2 ;;
    -h|--help) sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "demo.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done

"$here/deploy/setup.sh"
bin="$here/build"
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$bin/pocl-cache}
# A port of our own so a demo never mixes with another LCM user on this host; ttl=0 keeps it on
# the host, and a 4 MB receive buffer holds whole frames (STACK.md measured loss without it).
port=$((7700 + RANDOM % 200))
url=${VD_LCM_URL:-"udpm://239.255.76.67:$port?ttl=0&recv_buf_size=4194304"}
# Larger socket buffers need root; without it LCM falls back to the system maximum.
if [ "$(id -u)" -eq 0 ] && [ "$(sysctl -n net.core.rmem_max 2>/dev/null || echo 0)" -lt 8388608 ]; then
  sysctl -qw net.core.rmem_max=8388608 || true
fi

rm -rf "$out"
mkdir -p "$out/meshes"
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -INT "$p" 2>/dev/null || true; done
  for p in "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
}
trap cleanup EXIT
trap 'echo "demo: interrupted"; exit 130' INT TERM

echo "demo: scene '$scene', $frames frames, ${voxel} m voxels, LCM $url"
"$bin/server/vdeform-server" --lcm-url "$url" --voxel-size "$voxel" --snapshot-dir "$out/snapshots" \
  >"$out/server.log" 2>&1 &
server=$!
pids+=("$server")
"$bin/viewer_client/vdeform-viewer" --headless --quiet --lcm-url "$url" --save-dir "$out/meshes" --png \
  >"$out/viewer.log" 2>&1 &
viewer=$!
pids+=("$viewer")
if [ "$web" -eq 1 ]; then
  "$bin/viewer_client/vdeform-web" --lcm-url "$url" --port "$web_port" --quiet >"$out/web.log" 2>&1 &
  web_pid=$!
  pids+=("$web_pid")
  for _ in $(seq 1 50); do
    grep -q "serving http" "$out/web.log" 2>/dev/null && break
    kill -0 "$web_pid" 2>/dev/null || { echo "demo: vdeform-web failed to start:"; cat "$out/web.log"; exit 1; }
    sleep 0.1
  done
  echo "demo: web viewer at $(grep -o 'http://[^ ]*' "$out/web.log" | head -1)"
fi
# The server is ready once it logs its device (kernels built).
for _ in $(seq 1 300); do
  grep -q "vdeform-server on" "$out/server.log" 2>/dev/null && break
  kill -0 "$server" 2>/dev/null || { echo "demo: the server failed to start:"; cat "$out/server.log"; exit 1; }
  sleep 0.1
done
t0=$(date +%s.%N)
"$bin/capture_client/vdeform-capture" --source "synthetic:$scene" --count "$frames" --lockstep \
  --lcm-url "$url" 2>&1 | tee "$out/capture.log"
t1=$(date +%s.%N)
# Let the last mesh reach the viewer, then stop the viewer and the server (SIGINT: clean exit).
sleep 1
kill -INT "$viewer"
wait "$viewer" || true
if [ "$web" -eq 1 ]; then
  echo "demo: the stream ended; the web viewer keeps showing it at $(grep -o 'http://[^ ]*' "$out/web.log" | head -1) until Ctrl-C"
  trap 'echo; echo "demo: stopping"' INT
  wait "$web_pid" || true
  trap 'echo "demo: interrupted"; exit 130' INT TERM
fi
kill -INT "$server" 2>/dev/null || true
wait "$server" || true
pids=()

echo
echo "== vdeform demo summary =="
grep -h "vdeform-capture:" "$out/capture.log" | tail -1 || true
grep -h -E "^vdeform-server: received|^stages" "$out/server.log" || true
awk -v a="$t0" -v b="$t1" -v n="$frames" 'BEGIN { printf "end-to-end: %.1f s, %.2f frames per second\n", b - a, n / (b - a) }'
grep -h -E "^  meshes received|^  bytes" "$out/viewer.log" | sed 's/^  /viewer: /' || true
nply=$(ls "$out/meshes"/*.mesh.ply 2>/dev/null | wc -l)
echo "received meshes (PLY): $out/meshes ($nply live meshes)"
if [ -f "$out/meshes/final.png" ]; then
  echo "picture of the final live mesh: $out/meshes/final.png"
else
  echo "demo: the viewer wrote no final.png" >&2
  exit 1
fi
echo "logs: $out/server.log $out/viewer.log $out/capture.log"
