#!/usr/bin/env bash
# Same-run A/B of two builds on one synthetic scene, in ABBA order (A B B A per round) so that a
# host that drifts slower or faster during the run weighs on both alike. Prints each run's frame
# total, its non-rigid stage and the sum of the other device stages (preprocess, raster, ICP,
# marching cubes: unchanged by a solver change, so they show the host's own drift), then the means.
#   tests/bench/ab_scene.sh BUILD_A BUILD_B [SCENE] [ROUNDS] [FRAMES]
# AB_FLAGS_A / AB_FLAGS_B: extra vd_scene_bench flags for each side (one build, two settings:
#   AB_FLAGS_B=--sparse-volume tests/bench/ab_scene.sh build build tube).
set -euo pipefail
if [[ $# -lt 2 || $1 == -h || $1 == --help ]]; then
  sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//'
  exit 0
fi
a=$(cd "$1" && pwd)
b=$(cd "$2" && pwd)
scene=${3:-tube}
rounds=${4:-2}
frames=${5:-60}
out=$(mktemp)
runs=$(mktemp)
trap 'rm -f "$out" "$runs"' EXIT
for ((i = 1; i <= rounds; ++i)); do
  for which in A B B A; do
    build=$a
    flags=${AB_FLAGS_A:-}
    [[ $which == B ]] && build=$b && flags=${AB_FLAGS_B:-}
    POCL_CACHE_DIR=${POCL_CACHE_DIR:-$build/pocl-cache} "$build/tests/bench/vd_scene_bench" --scene "$scene" \
      --frames "$frames" $flags >"$out" 2>&1 || { echo "vd_scene_bench failed in $build:" >&2; tail -5 "$out" >&2; exit 1; }
    grep '^stages' "$out" | awk -v w="$which" -v s="$scene" '{
      for (i = 1; i <= NF; ++i) {
        if ($i == "nonrigid") nr = $(i + 1); if ($i == "raster") ra = $(i + 1); if ($i == "icp") ic = $(i + 1)
        if ($i == "marching_cubes") mc = $(i + 1); if ($i == "preprocess") pp = $(i + 1); if ($i == "total") t = $(i + 1)
      }
      printf "%s %s: total %s ms, nonrigid %s ms, others %.1f ms\n", s, w, t, nr, ra + ic + mc + pp }' | tee -a "$runs"
    grep -o 'worst frame [0-9.]* mm; last frame drift [0-9.]* mm\|displacement [0-9.]* mm' "$out" | head -1 | sed 's/^/    /'
  done
done
awk '{ w = $2; sub(":", "", w); n[w]++; t[w] += $4; r[w] += $7; o[w] += $10 }
  END { for (w in n) printf "mean %s over %d runs: total %.1f ms, nonrigid %.1f ms, others %.1f ms\n", w, n[w], t[w] / n[w], r[w] / n[w], o[w] / n[w] }' "$runs" | sort
