#!/usr/bin/env bash
# Live: a 30 Hz capture without lockstep feeds a running server (defaults, 4 mm). Prints what the
# capture sent, the server's processed fraction and rate, its capture-to-mesh latency p50/p95, and
# the CPU each server thread used while the capture ran, in % of one core (vd-worker: the frame
# loop; vd-sift: feature detection; vd-receive: LCM and decoding; vd-output: mesh encoding;
# vdeform-server: the OpenCL runtime's workers), and the capture's own CPU (capture), which on one
# machine shares the same cores.
#   tests/bench/live_30hz.sh BUILD_DIR [SCENE] [FRAMES]
set -euo pipefail
build=$(cd "$1" && pwd)
scene=${2:-tube}
frames=${3:-150}
mode=${4:-folder}
case "$mode" in folder | synthetic) ;; *) echo "live_30hz: mode must be folder or synthetic" >&2; exit 2 ;; esac
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$build/pocl-cache}
work=$(mktemp -d)
trap 'kill -INT ${srv:-} 2>/dev/null || true; rm -rf "$work"' EXIT
url="udpm://239.255.76.67:$((7900 + $$ % 90))?ttl=0&recv_buf_size=4194304"
# A folder source: decoding PNG costs the capture far less than rendering the scene live.
# (synthetic mode: only the 3 warm-up frames are written.)
written=$frames
[ "$mode" = synthetic ] && written=3
"$build/capture_client/vdeform-capture" --source "synthetic:$scene" --write "$work/scene" --count "$written" --quiet
# PoCL builds each kernel on its first launch (seconds each, then cached in POCL_CACHE_DIR): a
# few frames offline first, so that the live run measures the frame loop, not the compiler.
"$build/server/vdeform-server" --input "folder:$work/scene" --count 3 --quiet >/dev/null 2>&1 ||
  echo "live_30hz: the offline warm-up failed (the live run goes on)" >&2
date -u
"$build/server/vdeform-server" --lcm-url "$url" --quiet >"$work/server.log" 2>&1 &
srv=$!
sleep 4
# utime + stime (clock ticks) of every server thread, by thread name.
# Detection runs on short-lived threads (std::async): their time is the process's total less the
# threads alive at the end, reported as vd-sift.
threads() {
  for t in /proc/"$srv"/task/*; do echo "$(tr ' ' _ <"$t"/comm) $(awk '{print $14 + $15}' "$t"/stat)"; done 2>/dev/null
  echo "process $(awk '{print $14 + $15}' /proc/"$srv"/stat)"
}
if [ "$mode" = synthetic ]; then
  "$build/capture_client/vdeform-capture" --source "synthetic:$scene" --frames "$frames" --fps 30 --lcm-url "$url" \
    --quiet
else
threads >"$work/cpu0"
t0=$(date +%s.%N)
# The capture shares the two cores: its own CPU (user + system over its run) is printed too.
TIMEFORMAT='%U %S %R'
{ time "$build/capture_client/vdeform-capture" --source "folder:$work/scene" --fps 30 --lcm-url "$url" --quiet \
  2>"$work/capture.err"; } 2>"$work/capture.time"
t1=$(date +%s.%N)
cat "$work/capture.err" >&2
threads >"$work/cpu1"
awk -v t0="$t0" -v t1="$t1" -v hz="$(getconf CLK_TCK)" '
  NR == FNR { a[$1] += $2; next } { b[$1] += $2 }
  END {
    live = 0
    for (k in b) if (k != "process" && k != "vd-sift") live += b[k] - a[k]
    b["vd-sift"] += (b["process"] - a["process"]) - live
    for (k in b) if (k != "process") printf "cpu_%s=%.0f%%\n", k, 100 * (b[k] - a[k]) / hz / (t1 - t0)
  }' "$work/cpu0" "$work/cpu1" | sort
awk '{ printf "cpu_capture=%.0f%%\n", 100 * ($1 + $2) / $3 }' "$work/capture.time"
fi
sleep 3
"$build/server/vdeform-control" --command status --lcm-url "$url" --wait 3 | grep -E "^(frames_received|frames_processed|frames_dropped|fps|latency_ms_p50|latency_ms_p95)="
kill -INT "$srv"
wait "$srv"
srv=
grep -E "^vdeform-server: received|^stages|^latency" "$work/server.log"
