#!/usr/bin/env bash
# Builds the libFuzzer targets (clang; coverage, ASan, UBSan) in their own build folder, writes seed
# corpora of valid encodings, replays the committed reproducers in tests/fuzz/regressions/<target>/,
# then fuzzes every target for SECONDS.
#   tests/fuzz/run_fuzz.sh [SECONDS] [--build-dir DIR] [--only NAME[,NAME...]] [--jobs N] [--parallel P]
#                          [--runs R --seed S]
# SECONDS per target (default 10), P targets at a time (default 1), N build jobs (default 2).
# --runs R --seed S: instead of SECONDS, R inputs per target from random seed S and a fresh corpus
# (the seeds only): the same inputs on every machine, so a test run cannot fail by luck. DIR
# defaults to build-fuzz/ in the repository (ignored by git); DIR/fuzz/corpus/ keeps what earlier
# runs found. A crash, leak, time-out or out-of-memory input fails the run and is saved in
# DIR/fuzz/artifacts/<target>/. VD_FUZZ_CC / VD_FUZZ_CXX pick the compilers (default clang, clang++).
# Exit: 0 all passed; 1 a target or the build failed; 2 bad arguments; 77 clang or its libFuzzer
# runtime is missing (Debian: clang libclang-rt-14-dev).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
repo=$(cd "$here/../.." && pwd)
seconds=10
build_dir=$repo/build-fuzz
only=""
jobs=2
parallel=1
runs=""
seed=""
while [ $# -gt 0 ]; do
  case "$1" in
    --build-dir) build_dir=$2; shift 2 ;;
    --only) only=$2; shift 2 ;;
    --jobs) jobs=$2; shift 2 ;;
    --parallel) parallel=$2; shift 2 ;;
    --runs) runs=$2; shift 2 ;;
    --seed) seed=$2; shift 2 ;;
    -h|--help) sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    [0-9]*) seconds=$1; shift ;;
    *) echo "run_fuzz: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
if [ -n "$runs" ] || [ -n "$seed" ]; then
  [[ "$runs" =~ ^[0-9]+$ && "$seed" =~ ^[0-9]+$ ]] || { echo "run_fuzz: --runs and --seed go together, as numbers" >&2; exit 2; }
fi
cc=${VD_FUZZ_CC:-clang}
cxx=${VD_FUZZ_CXX:-clang++}

skip() {
  echo "run_fuzz: SKIPPED: $*"
  exit 77
}
command -v cmake >/dev/null || skip "cmake not found"
command -v "$cxx" >/dev/null || skip "$cxx not found (install clang)"
probe=$(mktemp -d)
trap 'rm -rf "$probe"' EXIT
printf '#include <cstddef>\n#include <cstdint>\nextern "C" int LLVMFuzzerTestOneInput(const uint8_t*, size_t) { return 0; }\n' \
  >"$probe/probe.cpp"
if ! "$cxx" -fsanitize=fuzzer,address,undefined "$probe/probe.cpp" -o "$probe/probe" 2>"$probe/err"; then
  skip "$cxx cannot link -fsanitize=fuzzer (install libclang-rt-14-dev): $(head -n 3 "$probe/err" | tr '\n' ' ')"
fi

# Configure once; a folder configured otherwise is not ours to change.
mkdir -p "$build_dir"
if [ -f "$build_dir/CMakeCache.txt" ]; then
  grep -q '^VD_FUZZ:BOOL=ON' "$build_dir/CMakeCache.txt" ||
    { echo "run_fuzz: $build_dir is not a VD_FUZZ=ON build; pick another --build-dir" >&2; exit 1; }
else
  generator=()
  command -v ninja >/dev/null && generator=(-G Ninja)
  # RelWithDebInfo without -DNDEBUG: optimised, symbolised reports, and asserts stay on.
  if ! CC=$cc CXX=$cxx cmake -S "$repo" -B "$build_dir" "${generator[@]}" -DVD_FUZZ=ON \
      -DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O2 -g" \
      "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O2 -g" >"$build_dir/configure.log" 2>&1; then
    cat "$build_dir/configure.log"
    rm -f "$build_dir/CMakeCache.txt"
    echo "run_fuzz: configuring $build_dir failed" >&2
    exit 1
  fi
fi
build_start=$(date +%s)
cmake --build "$build_dir" -j "$jobs" || { echo "run_fuzz: build failed" >&2; exit 1; }
echo "run_fuzz: build took $(($(date +%s) - build_start)) s"

fuzz_dir=$build_dir/fuzz
bin=$fuzz_dir/bin
rm -rf "$fuzz_dir/seeds"
"$bin/vd_fuzz_seeds" "$fuzz_dir/seeds"
mkdir -p "$fuzz_dir/logs"

# One libFuzzer invocation; its output goes to the log, the exit status is returned.
run_target() {
  local log=$1
  shift
  local rc=0
  "$@" -timeout=10 -rss_limit_mb=2048 >"$log" 2>&1 || rc=$?
  return $rc
}

shopt -s nullglob
results=$fuzz_dir/results
rm -rf "$results"
mkdir -p "$results"

# Replays one target's committed reproducers, then fuzzes it. Writes into $results/NAME.*: row
# (its line of the summary), execs, failed (present when it failed), report (what to show).
fuzz_one() {
  local name=$1 max_len=$2 seeds=$3 dict=$4
  local out=$results/$name
  local reproducers=() f
  for f in "$here/regressions/$name"/*; do
    case "$(basename "$f")" in README*|*.md) continue ;; esac
    [ -f "$f" ] && reproducers+=("$f")
  done
  if [ ${#reproducers[@]} -gt 0 ]; then
    local replay_log=$fuzz_dir/logs/$name.regressions.log
    if ! run_target "$replay_log" "$bin/$name" "${reproducers[@]}"; then
      { echo "run_fuzz: $name FAILED on a committed reproducer:"; tail -n 40 "$replay_log"; } >"$out.report"
      touch "$out.failed"
      printf '%-20s %10s %8s %6s %7s %5s  %s\n' "$name" - - - - "${#reproducers[@]}" REGRESSION >"$out.row"
      echo 0 >"$out.execs"
      return
    fi
  fi

  local corpus=$fuzz_dir/corpus/$name artifacts=$fuzz_dir/artifacts/$name log=$fuzz_dir/logs/$name.log
  local budget=(-max_total_time="$seconds")
  if [ -n "$runs" ]; then
    # Deterministic: a fresh corpus each time, a fixed number of inputs from a fixed seed.
    corpus=$fuzz_dir/corpus-fixed/$name
    rm -rf "$corpus"
    budget=(-runs="$runs" -seed="$seed")
  fi
  mkdir -p "$corpus" "$artifacts"
  local seed_dirs=() sets=() set extra=() result=ok
  if [ "$seeds" != "-" ]; then
    IFS=, read -ra sets <<<"$seeds"
    for set in "${sets[@]}"; do seed_dirs+=("$fuzz_dir/seeds/$set"); done
  fi
  [ "$dict" != "-" ] && extra+=("-dict=$dict")
  # -close_fd_mask=2: libpng and libjpeg print a line per bad input to the target's stderr;
  # libFuzzer, the sanitizers and VD_FUZZ_CHECK report through their own copy of it.
  if ! run_target "$log" "$bin/$name" "${budget[@]}" -max_len="$max_len" -close_fd_mask=2 \
      -artifact_prefix="$artifacts/" -print_final_stats=1 "${extra[@]}" "$corpus" "${seed_dirs[@]}"; then
    result=FAILED
    touch "$out.failed"
    {
      echo "run_fuzz: $name FAILED; the end of $log:"
      tail -n 60 "$log"
      echo "run_fuzz: reproducer(s): $(ls -t "$artifacts" | head -n 3 | sed "s|^|$artifacts/|" | tr '\n' ' ')"
      echo "run_fuzz: once fixed, copy the reproducer into tests/fuzz/regressions/$name/"
    } >"$out.report"
  fi
  local execs rate cov files
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -n 1)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -n 1 | cut -d' ' -f2)
  files=$(find "$corpus" -type f | wc -l)
  echo "${execs:-0}" >"$out.execs"
  printf '%-20s %10s %8s %6s %7s %5s  %s\n' "$name" "${execs:--}" "${rate:--}" "${cov:--}" "$files" \
    "${#reproducers[@]}" "$result" >"$out.row"
}

start=$(date +%s)
names=()
while read -r name max_len seeds dict; do
  [ -n "$name" ] || continue
  if [ -n "$only" ] && [[ ",$only," != *",$name,"* ]]; then continue; fi
  names+=("$name")
  while [ "$(jobs -rp | wc -l)" -ge "$parallel" ]; do wait -n || true; done
  fuzz_one "$name" "$max_len" "$seeds" "$dict" &
done <"$fuzz_dir/targets.txt"
wait

failed=()
total_execs=0
for name in "${names[@]}"; do
  [ -f "$results/$name.report" ] && cat "$results/$name.report"
  [ -f "$results/$name.failed" ] && failed+=("$name")
  total_execs=$((total_execs + $(cat "$results/$name.execs" 2>/dev/null || echo 0)))
done
printf '%-20s %10s %8s %6s %7s %5s  %s\n' target execs exec/s cov corpus regr result
for name in "${names[@]}"; do cat "$results/$name.row" 2>/dev/null || printf '%-20s (no result)\n' "$name"; done
elapsed=$(($(date +%s) - start))
echo "run_fuzz: ${#names[@]} targets, $total_execs executions in $elapsed s ($([ -n "$runs" ] && echo "$runs runs from seed $seed" || echo "$seconds s") each, $parallel at a time)," \
  "${#failed[@]} failed${failed:+: ${failed[*]}}"
[ ${#failed[@]} -eq 0 ]
