#!/usr/bin/env bash
# A hostile publisher on the LCM group, end to end on this host (issue 15). While a real capture
# streams signed frames in lockstep, vd_hostile_publisher, which speaks LCM's UDP wire format
# itself, sends exact replays of an earlier run and of the current one; mutated, truncated,
# oversized, foreign and forged frames (unsigned with huge, repeating and small sequence numbers,
# negative numbers, signed under another key); unsigned and wrongly signed commands with escaping
# snapshot paths; 200 REQUEST_MESH from 20 names; then a flood of junk datagrams, junk frames,
# dangling fragments from 64 ports and complete 6.6 MB messages. Meanwhile it forges the server's
# output: status messages naming the capture's frames as processed and meshes of made-up frames,
# unsigned and signed under a wrong key; the server signs its output (--output-key-file), the
# lockstep capture, a viewer and vdeform-web (--key-file) verify it. Asserted: every real frame processed
# (lockstep, exact: a forged status taken would have sent frames early, into the server's one-slot
# mailbox); the capture reports the forged statuses it ignored; the viewer saved exactly the real
# live meshes and counted the forged ones, the web bridge forwarded none of them; no forged frame reaches the model; each counter moved by
# exactly what was sent, by reason; REQUEST_MESH merged; the server's RSS grew by less than 5 %;
# nothing written anywhere (every snapshot command was forged).
#   hostile_test.sh BUILD_DIR
set -uo pipefail
build=$1
. "$(dirname "$0")/e2e_lib.sh"
vd_e2e_begin /tmp/vd-hostile-abs
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$build/pocl-cache}
group=239.255.76.67
port=$((7700 + $$ % 90))
url="udpm://$group:$port?ttl=0&recv_buf_size=4194304"
hostile="$build/tests/e2e/vd_hostile_publisher"
control="$build/server/vdeform-control"
fail() { echo "HOSTILE FAIL: $*"; for f in "$work"/*.log "$work"/s3; do echo "== $f"; tail -15 "$f"; done; exit 1; }
status() { "$control" --lcm-url "$url" --command status --wait 3 2>/dev/null; }
# field FILE KEY: a key=value field of a saved status or counts file (0 when absent).
field() { local v; v=$(sed -n "s/^$2=//p" "$1" | head -1); echo "${v:-0}"; }
delta() { echo $(($(field "$2" "$1") - $(field "$3" "$1"))); }  # KEY AFTER BEFORE

head -c 32 /dev/urandom | base64 >"$work/control.key"
for k in frame output; do
  openssl rand -hex 32 >"$work/$k.key" 2>/dev/null || od -An -tx1 -N32 /dev/urandom | tr -d ' \n' >"$work/$k.key"
done
chmod 600 "$work/control.key" "$work/frame.key" "$work/output.key"
mkdir -p "$work/run"
(cd "$work/run" && exec "$build/server/vdeform-server" --lcm-url "$url" --voxel-size 0.008 \
  --frame-key-file "$work/frame.key" --control-key-file "$work/control.key" --accept-sources camA \
  --output-key-file "$work/output.key" \
  --snapshot-dir "$work/run/snap") >"$work/server.log" 2>&1 &
server=$!
pids+=("$server")
state() { status | sed -n 's/^state=//p'; }
vd_wait_for_server "$server" "$work/server.log" state HOSTILE
capture() {  # count, log
  "$build/capture_client/vdeform-capture" --source synthetic:tube --count "$1" --lockstep --lockstep-timeout 5 \
    --lockstep-retries 10 \
    --source-id camA --frame-key-file "$work/frame.key" --output-key-file "$work/output.key" --lcm-url "$url" \
    --quiet >"$work/$2" 2>&1
}
record() {  # count, folder; sets rec to its pid
  "$hostile" record --lcm-url "$url" --count "$1" --out "$work/$2" --timeout 120 >"$work/record_$2.log" 2>&1 &
  rec=$!
}

# An earlier run of the real source, its first 3 frames recorded by the attacker. It is 10 frames
# long so that the server's working set has settled (buffers, arenas and the model grow over the
# first ~5 frames: 287 -> 295 MB, then ~0.1 MB a frame) before the memory baseline s0.
warmup=10
record 3 earlier
sleep 0.5
capture $warmup capture1.log || fail "first capture exited with $?"
wait "$rec" || fail "the attacker recorded no earlier run"
# The current run: a viewer with the output key saves its meshes; the attacker records its first
# 2 frames, then attacks and forges the server's output while it goes on.
mkdir -p "$work/view"
"$build/viewer_client/vdeform-viewer" --headless --no-request --key-file "$work/output.key" --save-dir "$work/view" \
  --lcm-url "$url" >"$work/viewer.log" 2>&1 &
viewer=$!
pids+=("$viewer")
"$build/viewer_client/vdeform-web" --key-file "$work/output.key" --port 0 --quiet --lcm-url "$url" >"$work/web.log" 2>&1 &
web=$!
pids+=("$web")
for _ in $(seq 1 50); do grep -q "listening on" "$work/viewer.log" && grep -q "serving" "$work/web.log" && break; sleep 0.1; done
grep -q "listening on" "$work/viewer.log" || fail "the viewer did not start"
grep -q "serving" "$work/web.log" || fail "vdeform-web did not start"
frames=10
record 2 current
sleep 0.5
capture $frames capture2.log &
cap=$!
pids+=("$cap")
wait "$rec" || fail "the attacker recorded nothing of the current run"
status >"$work/s0"
"$hostile" forge-output --group $group --port $port --source-id camA --current "$work/current" --seconds 2 \
  >"$work/forge" 2>"$work/forge.log" &
forger=$!
pids+=("$forger")
"$hostile" attack --group $group --port $port --source-id camA --earlier "$work/earlier" --current "$work/current" \
  >"$work/attack" 2>"$work/attack.log" || fail "attack failed: $(cat "$work/attack.log")"
wait "$forger" || fail "forge-output failed: $(cat "$work/forge.log")"
sleep 1.5
status >"$work/s1"
"$hostile" flood --group $group --port $port --seconds 2 >"$work/flood" 2>"$work/flood.log" || fail "flood failed"
sleep 1.5
status >"$work/s2"
wait "$cap" || fail "the real capture exited with $? (lockstep gave up?)"
sleep 1
status >"$work/s3"
kill -INT "$viewer" "$web"
wait "$viewer" || fail "viewer exited with $? after SIGINT"
wait "$web" || fail "vdeform-web exited with $? after SIGINT"
kill -INT "$server"
wait "$server" || fail "server exited with $? after SIGINT"
pids=()

# Every real frame processed, nothing else.
resent=$(sed -n 's/.*(\([0-9]*\) re-sent).*/\1/p' "$work/capture2.log")
[ "$(field "$work/s3" frames_processed)" -eq $((warmup + frames)) ] ||
  fail "processed $(field "$work/s3" frames_processed) frames, expected the $((warmup + frames)) real ones"
for k in frames_dropped frames_held frames_lost sequence_jumps frames_rate_limited; do
  [ "$(field "$work/s3" $k)" -eq 0 ] || fail "$k = $(field "$work/s3" $k)"
done
[ "$(field "$work/s3" source_restarts)" -eq 1 ] || fail "source_restarts = $(field "$work/s3" source_restarts)"
[ "$(field "$work/s3" last_source_id)" = camA ] || fail "last frame from $(field "$work/s3" last_source_id)"
# Each attack moved its counter by exactly what was sent (a lockstep re-send is one more duplicate).
for k in $(sed -n 's/^\(rejected_[a-z_]*\|frames_duplicate\|frames_foreign\)=.*/\1/p' "$work/attack"); do
  want=$(field "$work/attack" "$k")
  got=$(delta "$k" "$work/s1" "$work/s0")
  if [ "$k" = frames_duplicate ]; then
    [ "$got" -ge "$want" ] && [ "$got" -le $((want + ${resent:-0})) ] || fail "$k moved by $got, sent $want"
  else
    [ "$got" -eq "$want" ] || fail "$k moved by $got, sent $want"
  fi
  echo "attack: $k +$got (sent $want)"
done
refused=$(($(delta control_refused "$work/s1" "$work/s0") - $(delta control_rate_limited "$work/s1" "$work/s0")))
[ "$refused" -eq "$(field "$work/attack" control_refused)" ] || fail "control refused $refused, sent $(field "$work/attack" control_refused)"
merged=$(($(delta mesh_requests_merged "$work/s1" "$work/s0") + $(delta control_rate_limited "$work/s1" "$work/s0")))
[ "$merged" -ge 198 ] || fail "of 200 REQUEST_MESH only $merged were merged or rate-limited"
echo "attack: control refused +$refused, REQUEST_MESH: $merged of 200 merged or rate-limited"
# The flood: junk frames and 6.6 MB messages are malformed (some may be lost in the flood, none
# invented), nothing else moves.
junk=$(($(field "$work/flood" junk_frames) + $(field "$work/flood" oversized_messages)))
got=$(delta rejected_malformed_message "$work/s2" "$work/s1")
[ "$got" -le "$junk" ] || fail "$got malformed frames counted, $junk sent"
for k in rejected_bad_signature rejected_unsigned rejected_replayed rejected_oversized frames_foreign; do
  [ "$(delta $k "$work/s2" "$work/s1")" -eq 0 ] || fail "the flood moved $k"
done
echo "flood: $(field "$work/flood" garbage_datagrams) junk datagrams, $junk junk and 6.6 MB frames ($got counted" \
  "malformed), $(field "$work/flood" dangling_fragments) dangling fragments"
# Memory: flat across the attack and the flood.
rss0=$(field "$work/s0" resident_memory_bytes)
rss1=$(field "$work/s1" resident_memory_bytes)
rss2=$(field "$work/s2" resident_memory_bytes)
echo "server RSS: $((rss0 >> 20)) MB before the attack, $((rss1 >> 20)) MB before the flood," \
  "$((rss2 >> 20)) MB after it"
[ $((rss2 * 100)) -lt $((rss0 * 105)) ] || fail "RSS grew from $rss0 to $rss2 bytes (>= 5 %)"
# The flood's own share (the real capture has sent most of its frames by then): within 1 %.
[ $((rss2 * 100)) -lt $((rss1 * 101)) ] || fail "RSS grew from $rss1 to $rss2 bytes during the flood (>= 1 %)"
# Nothing written: no snapshot folder, no escaped file, nothing in the server's working folder.
[ ! -e "$work/run/snap" ] || fail "a snapshot folder was written: $(find "$work/run/snap")"
[ -z "$(find "$work" -name 'escape*')" ] || fail "an escaping path was written"
[ ! -e /tmp/vd-hostile-abs ] || fail "an absolute snapshot path was written"
[ "$(find "$work/run" -mindepth 1 | wc -l)" -eq 0 ] || fail "the server wrote: $(find "$work/run" -mindepth 1)"
grep -q "^vdeform-server: received" "$work/server.log" || fail "no server summary"
# The forged output: the capture ignored the forged statuses it heard (all it verified were
# unsigned or wrongly signed, none a replay of the server's own), the first run heard none; the
# viewer saved exactly the real live meshes of this run and refused the forged meshes and statuses.
forged_status=$(field "$work/forge" forged_status)
forged_meshes=$(field "$work/forge" forged_meshes)
grep -q "ignored 0 status messages not signed by the server" "$work/capture1.log" ||
  fail "the first capture ignored status messages: $(cat "$work/capture1.log")"
ignored=$(sed -n 's/.*ignored \([0-9]*\) status messages not signed by the server (\([0-9]*\) unsigned, \([0-9]*\) bad signature, \([0-9]*\) replayed).*/\1 \2 \3 \4/p' "$work/capture2.log")
read -r n_ign n_uns n_bad n_rep <<<"${ignored:-x x x x}"
[ "$n_uns" != x ] || fail "the capture did not report the statuses it ignored: $(cat "$work/capture2.log")"
[ "$n_uns" -ge 1 ] && [ "$n_bad" -ge 1 ] && [ "$n_rep" -eq 0 ] && [ "$n_ign" -le "$forged_status" ] ||
  fail "the capture ignored $ignored (total, unsigned, bad signature, replayed) of $forged_status forged statuses"
echo "forged output: $forged_status statuses, $forged_meshes meshes; the lockstep capture ignored $n_ign" \
  "($n_uns unsigned, $n_bad bad signature)"
saved=$(cd "$work/view" && ls frame-*.mesh.ply 2>/dev/null | tr '\n' ' ')
want=$(for k in $(seq 0 $((frames - 1))); do printf 'frame-%06d.mesh.ply ' "$k"; done)
[ "$saved" = "$want" ] || fail "the viewer saved [$saved], expected the real [$want]"
refused=$(sed -n 's/^  refused under --key-file: meshes \([0-9]*\) unsigned, \([0-9]*\) bad signature, \([0-9]*\) replayed; status \([0-9]*\) unsigned, \([0-9]*\) bad signature, \([0-9]*\) replayed$/\1 \2 \3 \4 \5 \6/p' "$work/viewer.log")
read -r m_uns m_bad m_rep s_uns s_bad s_rep <<<"${refused:-x x x x x x}"
[ "$m_uns" != x ] || fail "the viewer's summary has no refusals line"
[ "$m_uns" -ge 1 ] && [ "$m_bad" -ge 1 ] && [ $((m_uns + m_bad)) -le "$forged_meshes" ] && [ "$m_rep" -eq 0 ] &&
  [ "$s_uns" -ge 1 ] && [ "$s_bad" -ge 1 ] && [ $((s_uns + s_bad)) -le "$forged_status" ] && [ "$s_rep" -eq 0 ] ||
  fail "viewer refused meshes $m_uns/$m_bad/$m_rep, status $s_uns/$s_bad/$s_rep (unsigned/bad/replayed)"
echo "viewer: saved the $frames real live meshes; refused $m_uns unsigned and $m_bad wrongly signed meshes," \
  "$s_uns and $s_bad statuses"
# The web bridge: its last live mesh is the real last frame (a forged one is numbered 100000 and
# up), on the one real stream, and it refused forged meshes and statuses of both kinds.
line=$(grep "^vdeform-web: clients" "$work/web.log" | tail -1)
echo "$line" | grep -q "| seq $((frames - 1)) (" || fail "vdeform-web's last mesh is not the real last frame: $line"
echo "$line" | grep -q "streams)" && fail "vdeform-web heard more than the real stream: $line"
w=$(echo "$line" | sed -n 's/.*not signed by the server: meshes \([0-9]*\) unsigned, \([0-9]*\) bad signature, \([0-9]*\) replayed; status \([0-9]*\) unsigned, \([0-9]*\) bad signature, \([0-9]*\) replayed.*/\1 \2 \3 \4 \5 \6/p')
read -r w_uns w_bad w_rep ws_uns ws_bad ws_rep <<<"${w:-x x x x x x}"
[ "$w_uns" != x ] && [ "$w_uns" -ge 1 ] && [ "$w_bad" -ge 1 ] && [ "$w_rep" -eq 0 ] && [ "$ws_uns" -ge 1 ] &&
  [ "$ws_bad" -ge 1 ] && [ "$ws_rep" -eq 0 ] || fail "vdeform-web refused: $line"
echo "vdeform-web: forwarded up to the real seq $((frames - 1)); refused $w_uns + $w_bad meshes, $ws_uns + $ws_bad statuses"
echo "HOSTILE OK"
