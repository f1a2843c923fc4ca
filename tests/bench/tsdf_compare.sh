#!/bin/sh
# Our TSDF integration + marching cubes against Open3D's CPU pipelines, back to back, repeated.
#   tests/bench/tsdf_compare.sh [BUILD_DIR] [extra open3d_tsdf_bench.py flags...]
# BUILD_DIR (default: build) must hold vd_kernel_bench and vdeform-server; they are copied first. Needs Debian's
# python3-open3d for the system python (/usr/bin/python3). REPEATS (default 2) sets the repetitions;
# OUT_DIR (default: a new temporary folder) receives one JSON per repetition.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
build=${1:-build}
[ $# -gt 0 ] && shift
repeats=${REPEATS:-2}
out_dir=${OUT_DIR:-$(mktemp -d)}
mkdir -p "$out_dir"
if ! /usr/bin/python3 -c 'import open3d' 2>/dev/null; then
  echo "tsdf_compare: /usr/bin/python3 cannot import open3d (apt-get install python3-open3d)" >&2
  exit 1
fi
for exe in "$build/tests/bench/vd_kernel_bench" "$build/tests/bench/vd_fusion_bench" "$build/server/vdeform-server"; do
  [ -x "$exe" ] || { echo "tsdf_compare: $exe is missing (build it first)" >&2; exit 1; }
done
# Snapshot our binaries: a rebuild of BUILD_DIR during the run must not change what is measured.
snap="$out_dir/vd-build"
mkdir -p "$snap/tests/bench" "$snap/server"
cp "$build/tests/bench/vd_kernel_bench" "$build/tests/bench/vd_fusion_bench" "$snap/tests/bench/"
cp "$build/server/vdeform-server" "$snap/server/"
echo "our binaries: copied from $build ($(date -u -r "$build/server/vdeform-server" '+server built %H:%M UTC'))"
# Both sides get the machine's two cores: Open3D through OpenMP, ours through PoCL's pthreads.
export OMP_NUM_THREADS=2
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$out_dir/pocl-cache}
echo "date: $(date -u '+%Y-%m-%d %H:%M UTC'), commit $(git -C "$here" rev-parse --short HEAD 2>/dev/null || echo '?')"
echo "cpu: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')"
i=1
while [ "$i" -le "$repeats" ]; do
  echo "--- repetition $i of $repeats, before: $(uptime | sed 's/.*load/load/')"
  /usr/bin/python3 "$here/open3d_tsdf_bench.py" --vd-build "$snap" --json "$out_dir/run$i.json" "$@"
  echo "--- repetition $i done, after: $(uptime | sed 's/.*load/load/')"
  i=$((i + 1))
done
echo "results: $out_dir/run*.json"
