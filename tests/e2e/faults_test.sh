#!/usr/bin/env bash
# Faults, end to end over LCM on this host (issue 6): a viewer killed and restarted gets the
# current mesh within a second even while no new frame arrives; a capture client killed and
# restarted is seen as a restart and the stream goes on; control commands need the HMAC key;
# the server killed (SIGKILL) and restarted with --resume continues the checkpointed model; a torn
# checkpoint is reported in the status and a new model started; every process stops cleanly, the
# server without an error line. Frames are signed (--frame-key-file): unsigned ones are refused.
#   faults_test.sh BUILD_DIR
set -uo pipefail
build=$1
. "$(dirname "$0")/e2e_lib.sh"
vd_e2e_begin
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$build/pocl-cache}
port=$((7800 + $$ % 90))
url="udpm://239.255.76.67:$port?ttl=0&recv_buf_size=4194304"
server_bin="$build/server/vdeform-server"
control="$build/server/vdeform-control"
fail() { echo "FAULTS FAIL: $*"; for f in "$work"/*.log; do echo "== $f"; tail -15 "$f"; done; exit 1; }
# status KEY: one field of the server's status.
status() { "$control" --lcm-url "$url" --command status --wait 3 2>/dev/null | sed -n "s/^$1=//p"; }
# wait_for KEY OP VALUE SECONDS: until the status field compares true.
wait_for() {
  local end=$((SECONDS + $4)) v
  while [ $SECONDS -lt $end ]; do
    v=$(status "$1")
    [ -n "$v" ] && [ "$v" "$2" "$3" ] && return 0
    sleep 0.3
  done
  fail "status $1 did not reach $2 $3 within $4 s (last: ${v:-none})"
}

head -c 32 /dev/urandom | base64 >"$work/control.key"
chmod 600 "$work/control.key"
openssl rand -hex 32 >"$work/frame.key" 2>/dev/null || od -An -tx1 -N32 /dev/urandom | tr -d ' \n' >"$work/frame.key"
chmod 600 "$work/frame.key"
start_server() {  # extra flags
  "$server_bin" --lcm-url "$url" --voxel-size 0.008 --checkpoint "$work/ckpt" --checkpoint-interval 1 \
    --control-key-file "$work/control.key" --frame-key-file "$work/frame.key" --snapshot-dir "$work/snap" "$@" \
    >>"$work/server.log" 2>&1 &
  server=$!
  pids+=("$server")
  vd_wait_for_server "$server" "$work/server.log" "status state" FAULTS
}
start_capture() {
  "$build/capture_client/vdeform-capture" --source synthetic:tube --loop --fps 3 --source-id camA --lcm-url "$url" \
    --frame-key-file "$work/frame.key" --quiet >>"$work/capture.log" 2>&1 &
  capture=$!
  pids+=("$capture")
}

start_server
start_capture
mkdir -p "$work/view1"
"$build/viewer_client/vdeform-viewer" --headless --quiet --lcm-url "$url" --save-dir "$work/view1" >"$work/viewer1.log" 2>&1 &
viewer=$!
pids+=("$viewer")
wait_for frames_processed -ge 4 120
echo "streaming: $(status frames_processed) frames processed"

# 1. Viewer killed; while the capture is paused (no new frames), a new viewer gets the current
#    mesh through REQUEST_MESH within a second.
kill -9 "$viewer"
kill -STOP "$capture"
sleep 1
processed=$(status frames_processed)
mkdir -p "$work/view2"
t0=$(date +%s%N)
"$build/viewer_client/vdeform-viewer" --headless --quiet --lcm-url "$url" --save-dir "$work/view2" --count 1 \
  --timeout 10 >"$work/viewer2.log" 2>&1 || fail "restarted viewer got no mesh"
ms=$((($(date +%s%N) - t0) / 1000000))
[ "$(status frames_processed)" -eq "$processed" ] || fail "a frame arrived while the capture was paused"
n=$(ls "$work/view2"/frame-*.mesh.ply 2>/dev/null | wc -l)
[ "$n" -ge 1 ] || fail "restarted viewer saved no mesh"
echo "viewer restart: current mesh after $ms ms with no new frame"
[ "$ms" -le 1000 ] || fail "restarted viewer waited $ms ms (> 1 s) for the current mesh"
kill -CONT "$capture"

# 2. Capture killed and restarted (seq from 0 again, newer capture time): a restart, not stale.
wait_for frames_processed -ge $((processed + 2)) 60
kill -9 "$capture"
sleep 0.5
before=$(status frames_processed)
start_capture
wait_for source_restarts -eq 1 60
wait_for frames_processed -ge $((before + 3)) 60
[ "$(status frames_rejected)" -eq 0 ] || fail "frames rejected: $(status frames_rejected)"
echo "capture restart: counted (source_restarts=1), $(status frames_processed) frames processed"

# 2b. An unsigned capture under the same id: each of its frames refused as unsigned, none processed
#     as its own (the signed stream goes on).
"$build/capture_client/vdeform-capture" --source synthetic:cloth --count 3 --max-rate --source-id camA \
  --lcm-url "$url" --quiet >>"$work/capture_unsigned.log" 2>&1 || fail "unsigned capture exited with $?"
wait_for rejected_unsigned -eq 3 10
[ "$(status frames_rejected)" -eq 3 ] || fail "frames rejected: $(status frames_rejected), expected the 3 unsigned"
echo "unsigned frames: 3 sent, 3 refused (rejected_unsigned=3)"

# 3. Control: unsigned RESET refused, signed RESET taken.
"$control" --lcm-url "$url" --command reset >"$work/control.log" 2>&1 && fail "unsigned reset was taken"
[ "$(status control_refused)" -ge 1 ] || fail "refusal not counted"
"$control" --lcm-url "$url" --command reset --key-file "$work/control.key" >>"$work/control.log" 2>&1 ||
  fail "signed reset refused"
echo "control: unsigned reset refused, signed reset taken"
wait_for model_frames -ge 4 60

# 4. Server killed with SIGKILL (no shutdown checkpoint): the restarted one resumes the model of
#    the last periodic checkpoint.
wait_for checkpoint_utime -gt 0 30
sleep 1.5
kill -9 "$server"
wait "$server" 2>/dev/null
kill -STOP "$capture"
ls "$work/ckpt/checkpoint.vdck" >/dev/null || fail "no checkpoint file"
start_server --resume
resumed=$(status model_frames)
msg=$(status checkpoint_message)
echo "server restart: $msg, $resumed frames in the model"
[ "$resumed" -ge 3 ] || fail "resumed model has $resumed frames"
case "$msg" in "resumed from"*) ;; *) fail "checkpoint message: $msg" ;; esac
kill -CONT "$capture"
wait_for model_frames -ge $((resumed + 3)) 60
[ "$(status state)" = TRACKING ] || fail "not tracking after resume: $(status message)"
echo "after resume: $(status model_frames) frames in the model, state TRACKING"

# 5. A torn checkpoint: reported, kept aside, a new model started; the server keeps serving.
kill -9 "$server"
wait "$server" 2>/dev/null
for f in "$work"/ckpt/checkpoint*.vdck; do truncate -s 5000 "$f"; done
start_server --resume
msg=$(status checkpoint_message)
case "$msg" in *"resume failed"*torn*) ;; *) fail "torn checkpoint not reported: $msg" ;; esac
ls "$work"/ckpt/*.corrupt-* >/dev/null 2>&1 || fail "torn checkpoint not kept aside"
wait_for model_frames -ge 2 60
echo "torn checkpoint: reported ('${msg:0:60}...'), new model has $(status model_frames) frames"

# 6. Clean stop: SIGINT ends every process with status 0, the server writes a final checkpoint and
#    logs no error while stopping.
logged=$(wc -l <"$work/server.log")
kill -INT "$capture" "$server"
wait "$capture" || fail "capture exited with $? after SIGINT"
wait "$server" || fail "server exited with $? after SIGINT"
pids=()
grep -q "^vdeform-server: received" "$work/server.log" || fail "no server summary"
stop_errors=$(tail -n +$((logged + 1)) "$work/server.log" | grep '^E ')
[ -z "$stop_errors" ] || fail "errors logged on a clean stop: $stop_errors"
[ -s "$work/ckpt/checkpoint.vdck" ] || fail "no checkpoint after a clean stop"
echo "FAULTS OK"
