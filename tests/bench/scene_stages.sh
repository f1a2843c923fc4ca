#!/bin/bash
# Per-stage milliseconds of the non-rigid pipeline on a synthetic scene: runs vd_scene_bench with
# the kernel profile on (VD_PROFILE_KERNELS=1: every launch waits for the device, so the totals
# add up to slightly more than a normal run) and sums the kernels by stage.
#   tests/bench/scene_stages.sh BUILD_DIR --scene tube [--voxel-size 0.004] [other engine flags]
set -euo pipefail
build=${1:?usage: scene_stages.sh BUILD_DIR --scene NAME [flags]}
shift
bench="$build/tests/bench/vd_scene_bench"
[[ -x "$bench" ]] || { echo "scene_stages.sh: $bench not built (configure with -DVD_BUILD_BENCH=ON)" >&2; exit 1; }
log=$(mktemp)
trap 'rm -f "$log"' EXIT
VD_PROFILE_KERNELS=1 "$bench" "$@" >"$log" 2>&1 || { cat "$log" >&2; exit 1; }
grep -v '^ \|^kernel profile' "$log"
frames=$(sed -n 's/.*, \([0-9]*\) frames (stride.*/\1/p' "$log" | head -1)
awk -v frames="$frames" '
  /^kernel profile/ { on = 1; next }
  on && NF == 3 {
    k = $1; ms = $2; g = "other";
    if (k ~ /^vd_mc_/) g = "marching cubes";
    else if (k ~ /^vd_deform|^vd_extrapolate/) g = "deformation";
    else if (k ~ /^vd_raster/) g = "rasterisation";
    else if (k ~ /^vd_correspondences/) g = "correspondences";
    else if (k ~ /^vd_procrustes/) g = "Procrustes";
    else if (k ~ /^vd_level_/) g = "hierarchy";
    else if (k ~ /^vd_system|^vd_constraint|^vd_btb|^vd_pcg|^vd_axpy|^vd_xpay|^vd_sub_from|^vd_dot4|^vd_solver_|^vd_energy/) g = "PCG (incl. B^T B, setup, energies)";
    else if (k ~ /^vd_active/) g = "active set";
    else if (k ~ /^vd_tsdf/) g = "fusion";
    else if (k ~ /^vd_icp/) g = "ICP";
    else if (k ~ /^vd_depth|^vd_bilateral|^vd_pyr|^vd_vertex|^vd_normal/) g = "preprocessing";
    else if (k ~ /^vd_scan/) g = "scans";
    sum[g] += ms; total += ms;
  }
  END {
    printf "kernel time per frame by stage (ms, %d frames, profiled):\n", frames;
    n = 0; for (g in sum) order[n++] = g;
    for (i = 0; i < n; ++i) for (j = i + 1; j < n; ++j) if (sum[order[j]] > sum[order[i]]) { t = order[i]; order[i] = order[j]; order[j] = t; }
    for (i = 0; i < n; ++i) printf "  %-40s %8.1f\n", order[i], sum[order[i]] / frames;
    printf "  %-40s %8.1f\n", "all kernels", total / frames;
  }' "$log"
