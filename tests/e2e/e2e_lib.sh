# Sourced by the e2e scripts. They define fail (print the logs, exit 1) before using these.

# vd_wait_for_server PID LOG PROBE NAME: returns once PROBE (a command, word-split) prints
# something, i.e. the server publishes its status. Exits 77 (skipped) when the server could not
# open LCM (no multicast route), fails when it exits or stays silent for 60 s.
vd_wait_for_server() {
  local pid=$1 log=$2 probe=$3 name=$4
  for _ in $(seq 1 300); do
    [ -n "$($probe)" ] && return 0
    if ! kill -0 "$pid" 2>/dev/null; then
      grep -q "cannot open LCM" "$log" &&
        { echo "$name SKIP: LCM multicast unavailable (ip route add 224.0.0.0/4 dev lo)"; exit 77; }
      fail "server exited during start-up"
    fi
    sleep 0.2
  done
  fail "server did not publish a status"
}

# vd_e2e_begin [PATH...]: a scratch folder $work, the array pids of the processes to stop, and an
# exit trap (also on SIGINT/SIGTERM) that resumes, interrupts and after 0.5 s kills them, then
# removes $work and the PATHs.
vd_e2e_begin() {
  work=$(mktemp -d)
  pids=()
  vd_e2e_paths=("$@")
  trap vd_e2e_end EXIT
  trap 'exit 1' INT TERM
}
vd_e2e_end() {
  kill -CONT ${pids[*]:-} 2>/dev/null
  kill -INT ${pids[*]:-} 2>/dev/null
  sleep 0.5
  kill -9 ${pids[*]:-} 2>/dev/null
  rm -rf "$work" "${vd_e2e_paths[@]}"
}
