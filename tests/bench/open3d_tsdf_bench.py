#!/usr/bin/python3
"""TSDF integration + meshing: Open3D's CPU pipelines against ours, side by side in one run.

Open3D (Debian's python3-open3d, run with the system /usr/bin/python3):
  (a) o3d.pipelines.integration.ScalableTSDFVolume (hashed 16^3 volume units, legacy API)
  (b) o3d.t.geometry.VoxelBlockGrid on CPU:0 (hashed blocks, tensor API)
both fed the same N 7-Scenes frames with the ground-truth camera-to-world poses, the same voxel
size V, truncation 4 V, depth cut at 3.5 m and RGB colour. Per-frame integration is timed (image
decoding and tensor conversion are not), then one mesh extraction.

Ours (the lead's build, OpenCL on PoCL's CPU device):
  vd_kernel_bench  one frame fused into the dense grid placed from frame 0 (OpenCL and the CPU
                   reference), plus marching cubes over that grid;
  vdeform-server   the full offline pipeline over the same N frames with its own tracking (no
                   ground truth), per-stage means from --stats-json.

Each Open3D pipeline runs in its own child process so its peak resident memory is its own.
Everything runs back to back in one invocation; compare ratios, not absolute milliseconds.

  open3d_tsdf_bench.py [--frames N] [--voxel-sizes 0.01,0.02] [--vd-build DIR] [--json FILE]
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time

DEFAULT_DATA = "/work/shared/data/7scenes_redkitchen"
# 7-Scenes (Kinect v1) intrinsics as shipped in camera-intrinsics.txt.
FX, FY, CX, CY, WIDTH, HEIGHT = 585.0, 585.0, 320.0, 240.0, 640, 480
DEPTH_SCALE = 1000.0  # raw units per metre (16-bit millimetres)
DEPTH_MAX = 3.5  # metres; ours uses the same cut (EngineParams::max_depth)
TRUNC_VOXELS = 4.0  # ours: EngineParams::truncation_voxels


def rss_kib(field):
    """VmRSS / VmHWM of this process in KiB (Linux)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    return 0


def load_frames(data, count):
    import numpy as np
    import open3d as o3d

    frames = []
    for i in range(count):
        stem = os.path.join(data, "frame-%06d" % i)
        if not os.path.exists(stem + ".depth.png"):
            break
        depth = o3d.io.read_image(stem + ".depth.png")
        color = o3d.io.read_image(stem + ".color.jpg")
        d = np.asarray(depth)
        c = np.asarray(color)
        if d.dtype != np.uint16 or d.shape != (HEIGHT, WIDTH) or c.shape != (HEIGHT, WIDTH, 3):
            raise SystemExit("%s: unexpected image format %s %s / %s" % (stem, d.dtype, d.shape, c.shape))
        pose = np.loadtxt(stem + ".pose.txt").reshape(4, 4)
        if not np.all(np.isfinite(pose)):
            raise SystemExit("%s.pose.txt: non-finite pose" % stem)
        frames.append((depth, color, pose))
    if not frames:
        raise SystemExit("no frames in %s" % data)
    return frames


def run_scalable(frames, voxel):
    import numpy as np
    import open3d as o3d

    intr = o3d.camera.PinholeCameraIntrinsic(WIDTH, HEIGHT, FX, FY, CX, CY)
    vol = o3d.pipelines.integration.ScalableTSDFVolume(
        voxel_length=voxel, sdf_trunc=TRUNC_VOXELS * voxel,
        color_type=o3d.pipelines.integration.TSDFVolumeColorType.RGB8)
    prep_ms, int_ms = [], []
    for depth, color, pose in frames:
        t0 = time.perf_counter()
        rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(
            color, depth, depth_scale=DEPTH_SCALE, depth_trunc=DEPTH_MAX, convert_rgb_to_intensity=False)
        t1 = time.perf_counter()
        vol.integrate(rgbd, intr, np.linalg.inv(pose))
        t2 = time.perf_counter()
        prep_ms.append((t1 - t0) * 1e3)
        int_ms.append((t2 - t1) * 1e3)
    t0 = time.perf_counter()
    mesh = vol.extract_triangle_mesh()
    mc_ms = (time.perf_counter() - t0) * 1e3
    return {"prep_ms": prep_ms, "integrate_ms": int_ms, "extract_ms": mc_ms,
            "triangles": len(mesh.triangles), "vertices": len(mesh.vertices)}


def run_vbg(frames, voxel, block_resolution, block_count):
    import numpy as np
    import open3d as o3d
    import open3d.core as o3c

    dev = o3c.Device("CPU:0")
    vbg = o3d.t.geometry.VoxelBlockGrid(
        attr_names=("tsdf", "weight", "color"),
        attr_dtypes=(o3c.float32, o3c.float32, o3c.float32),
        attr_channels=((1), (1), (3)),
        voxel_size=voxel, block_resolution=block_resolution, block_count=block_count, device=dev)
    intr = o3c.Tensor([[FX, 0, CX], [0, FY, CY], [0, 0, 1]], o3c.float64)
    prep_ms, int_ms = [], []
    for depth, color, pose in frames:
        t0 = time.perf_counter()
        d = o3d.t.geometry.Image.from_legacy(depth, dev)
        c = o3d.t.geometry.Image.from_legacy(color, dev)
        extr = o3c.Tensor(np.linalg.inv(pose), o3c.float64)
        t1 = time.perf_counter()
        coords = vbg.compute_unique_block_coordinates(d, intr, extr, DEPTH_SCALE, DEPTH_MAX, TRUNC_VOXELS)
        vbg.integrate(coords, d, c, intr, extr, DEPTH_SCALE, DEPTH_MAX, TRUNC_VOXELS)
        t2 = time.perf_counter()
        prep_ms.append((t1 - t0) * 1e3)
        int_ms.append((t2 - t1) * 1e3)
    t0 = time.perf_counter()
    # Weights start at 1 per observation: 0.5 keeps every observed voxel, like ours (weight > 0).
    mesh = vbg.extract_triangle_mesh(weight_threshold=0.5)
    mc_ms = (time.perf_counter() - t0) * 1e3
    blocks = vbg.hashmap().size()
    voxel_bytes = 4 + 4 + 12  # tsdf, weight, colour (3 x float32)
    return {"prep_ms": prep_ms, "integrate_ms": int_ms, "extract_ms": mc_ms,
            "triangles": int(mesh.triangle["indices"].shape[0]),
            "vertices": int(mesh.vertex["positions"].shape[0]),
            "blocks": int(blocks), "voxels": int(blocks) * block_resolution ** 3,
            "block_bytes": int(blocks) * block_resolution ** 3 * voxel_bytes}


def child_main(args):
    import open3d as o3d

    frames = load_frames(args.data, args.frames)
    base_kib = rss_kib("VmRSS")
    if args.child == "scalable":
        r = run_scalable(frames, args.voxel)
    else:
        r = run_vbg(frames, args.voxel, args.block_resolution, args.block_count)
    r.update({"method": args.child, "voxel": args.voxel, "block_resolution": args.block_resolution,
              "frames": len(frames), "open3d": o3d.__version__, "peak_rss_mb": rss_kib("VmHWM") / 1024.0, "frames_rss_mb": base_kib / 1024.0})
    print("RESULT " + json.dumps(r))


def run_child(args, method, voxel, block_resolution=16):
    """One Open3D pipeline in a fresh process. Open3D 0.16's VoxelBlockGrid extraction aborts now and
    then on an internal assertion ("GetVoxelAt returns nullptr", VoxelBlockGridImpl.h:1590) when the
    weight threshold is below ~1; such a run is repeated, up to --o3d-attempts, and counted."""
    cmd = [sys.executable, os.path.abspath(__file__), "--child", method, "--voxel", repr(voxel),
           "--frames", str(args.frames), "--data", args.data,
           "--block-resolution", str(block_resolution), "--block-count", str(args.block_count)]
    aborts = 0
    for _ in range(args.o3d_attempts):
        out = subprocess.run(cmd, capture_output=True, text=True)
        for line in out.stdout.splitlines():
            if line.startswith("RESULT "):
                r = json.loads(line[len("RESULT "):])
                r["aborted_attempts"] = aborts
                return r
        if "GetVoxelAt returns nullptr" not in out.stderr:
            break
        aborts += 1
        sys.stderr.write("open3d %s V=%g res %d: extraction assertion, attempt %d of %d\n" % (
            method, voxel, block_resolution, aborts, args.o3d_attempts))
    raise SystemExit("open3d child %s V=%g failed (rc %d):\n%s%s" % (method, voxel, out.returncode,
                                                                    out.stdout[-2000:], out.stderr[-4000:]))


def run_kernel_bench(args, voxel):
    exe = os.path.join(args.vd_build, "tests/bench/vd_kernel_bench")
    out = subprocess.run([exe, "--scene", "folder:" + args.data, "--voxel-size", repr(voxel),
                          "--reps", str(args.kernel_reps)], capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit("vd_kernel_bench failed (rc %d): %s" % (out.returncode, out.stderr[-2000:]))
    r = {}
    m = re.search(r"grid (\d+)x(\d+)x(\d+)", out.stdout)
    if not m:
        raise SystemExit("vd_kernel_bench: no grid line in:\n" + out.stdout)
    r["grid"] = [int(g) for g in m.groups()]
    for stage in ("integrate", "marching_cubes"):
        m = re.search(r"^%s\s+([\d.]+)\s+([\d.]+)" % stage, out.stdout, re.M)
        if not m:
            raise SystemExit("vd_kernel_bench: no %s row in:\n%s" % (stage, out.stdout))
        r[stage + "_cpu_ms"] = float(m.group(1))
        r[stage + "_ocl_ms"] = float(m.group(2))
    m = re.search(r"\((\d+) vertices, (\d+) triangles\)", out.stdout)
    r["triangles"] = int(m.group(2)) if m else -1
    return r


def run_fusion_bench(args, voxel, sparse=False):
    """vd_fusion_bench: the same frames with the ground-truth poses, integration timed per frame,
    one extraction: the job Open3D's rows do. sparse: into the brick pool of the sparse volume."""
    exe = os.path.join(args.vd_build, "tests/bench/vd_fusion_bench")
    out = subprocess.run([exe, "--data", args.data, "--voxel-size", repr(voxel), "--frames", str(args.frames),
                          "--sparse", "1" if sparse else "0"],
                         capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit("vd_fusion_bench failed (rc %d): %s" % (out.returncode, out.stderr[-2000:]))
    r = {}
    for key in ("integrate_mean_ms", "integrate_median_ms", "integrate_first_ms", "integrate_steady_ms", "extract_ms",
                "triangles", "bricks_mean"):
        m = re.search(r"^%s ([\d.]+)$" % key, out.stdout, re.M)
        if not m:
            raise SystemExit("vd_fusion_bench: no %s in:\n%s" % (key, out.stdout))
        r[key] = float(m.group(1))
    m = re.search(r"grid (\d+)x(\d+)x(\d+)", out.stdout)
    r["grid"] = [int(g) for g in m.groups()] if m else []
    return r


def run_server(args, voxel):
    exe = os.path.join(args.vd_build, "server/vdeform-server")
    with tempfile.TemporaryDirectory() as tmp:
        stats = os.path.join(tmp, "stats.json")
        out = subprocess.run([exe, "--input", "folder:" + args.data, "--voxel-size", repr(voxel),
                              "--count", str(args.frames), "--stats-json", stats, "--quiet", "--rigid-only"],
                             capture_output=True, text=True)
        if out.returncode != 0 or not os.path.exists(stats):
            raise SystemExit("vdeform-server failed (rc %d): %s" % (out.returncode, out.stderr[-2000:]))
        with open(stats) as f:
            return json.load(f)


def stage_mean(stats, name):
    """Mean ms of one stage in the server's --stats-json ({"stages": {name: {"mean_ms": ...}}})."""
    return float(stats["stages"][name]["mean_ms"])


def mean(xs):
    return sum(xs) / len(xs)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=DEFAULT_DATA, help="7-Scenes sequence folder (frame-%%06d.*)")
    ap.add_argument("--frames", type=int, default=100, help="frames to integrate (from frame 0)")
    ap.add_argument("--voxel-sizes", default="0.01,0.02", help="comma-separated voxel sizes, metres")
    ap.add_argument("--block-resolutions", default="8,16", help="VoxelBlockGrid block edges to run, voxels (8, 16)")
    ap.add_argument("--block-count", type=int, default=10000,
                    help="VoxelBlockGrid initial hash capacity (Open3D's default; it grows when full)")
    ap.add_argument("--vd-build", default="/work/main/build", help="our build dir (empty: skip ours)")
    ap.add_argument("--kernel-reps", type=int, default=5, help="vd_kernel_bench --reps")
    ap.add_argument("--o3d-attempts", type=int, default=4,
                    help="runs of one Open3D pipeline before giving up on its extraction assertion")
    ap.add_argument("--json", default="", help="also write all results here")
    ap.add_argument("--child", choices=("scalable", "vbg"), help=argparse.SUPPRESS)
    ap.add_argument("--voxel", type=float, help=argparse.SUPPRESS)
    ap.add_argument("--block-resolution", type=int, default=16, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.frames < 1:
        ap.error("--frames must be >= 1, got %d" % args.frames)
    if args.o3d_attempts < 1:
        ap.error("--o3d-attempts must be >= 1, got %d" % args.o3d_attempts)
    if args.block_count < 1:
        ap.error("--block-count must be >= 1, got %d" % args.block_count)
    if args.child:
        child_main(args)
        return
    try:
        voxels = [float(v) for v in args.voxel_sizes.split(",") if v]
        resolutions = [int(r) for r in args.block_resolutions.split(",") if r]
    except ValueError as e:
        ap.error(str(e))
    if not resolutions or any(r not in (8, 16) for r in resolutions):
        ap.error("--block-resolutions must be 8 and/or 16, got %r" % args.block_resolutions)
    if not voxels or any(not (0.001 <= v <= 0.1) for v in voxels):
        ap.error("--voxel-sizes must lie in [0.001, 0.1] m, got %r" % args.voxel_sizes)

    results = []
    for v in voxels:
        row = {"voxel": v}
        row["scalable"] = run_child(args, "scalable", v)
        row["vbg"] = [run_child(args, "vbg", v, r) for r in resolutions]
        if args.vd_build:
            row["kernel"] = run_kernel_bench(args, v)
            row["fusion"] = run_fusion_bench(args, v)
            row["fusion_sparse"] = run_fusion_bench(args, v, sparse=True)
            row["server"] = run_server(args, v)
        results.append(row)
        print_row(row)
        sys.stdout.flush()
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"frames": args.frames, "omp_num_threads": os.environ.get("OMP_NUM_THREADS", ""),
                       "results": results}, f, indent=1)


def median(xs):
    ys = sorted(xs)
    return ys[len(ys) // 2]


def print_row(row):
    v = row["voxel"]
    s = row["scalable"]
    n = s["frames"]
    print("\n=== V = %g m, %d frames (Open3D %s, OMP_NUM_THREADS=%s) ===" % (
        v, n, s["open3d"], os.environ.get("OMP_NUM_THREADS", "unset")))
    hdr = "%-40s %11s %11s %11s %10s %9s"
    print(hdr % ("method", "integ mean", "integ med", "extract ms", "triangles", "peak MB"))
    fmt = "%-40s %11.2f %11.2f %11.1f %10s %9s"
    o3d_rows = [("Open3D ScalableTSDFVolume", s)]
    o3d_rows += [("Open3D VoxelBlockGrid res %d" % g["block_resolution"], g) for g in row["vbg"]]
    for name, r in o3d_rows:
        print(fmt % (name, mean(r["integrate_ms"]), median(r["integrate_ms"]), r["extract_ms"], r["triangles"],
                     "%.0f" % (r["peak_rss_mb"] - r["frames_rss_mb"])))
    print("  (untimed prep per frame: RGBDImage %.2f ms, tensor images %.2f ms)" % (
        mean(s["prep_ms"]), mean(row["vbg"][0]["prep_ms"])))
    for g in row["vbg"]:
        print("  (VBG res %d: %d blocks = %.1f M voxels, %.0f MB of voxel data; %d aborted extraction attempts)" % (
            g["block_resolution"], g["blocks"], g["voxels"] / 1e6, g["block_bytes"] / 1e6, g["aborted_attempts"]))
    if "kernel" not in row:
        return
    k, sv = row["kernel"], row["server"]
    gx, gy, gz = k["grid"]
    nvox = gx * gy * gz
    srv_int, srv_mc = stage_mean(sv, "integrate"), stage_mean(sv, "marching_cubes")
    srv_int_med = float(sv["stages"]["integrate"]["median_ms"])
    print(fmt % ("ours vd_kernel_bench OpenCL (1 frame)", k["integrate_ocl_ms"], k["integrate_ocl_ms"],
                 k["marching_cubes_ocl_ms"], k["triangles"], "-"))
    print(fmt % ("ours vd_kernel_bench CPU ref (1 frame)", k["integrate_cpu_ms"], k["integrate_cpu_ms"],
                 k["marching_cubes_cpu_ms"], k["triangles"], "-"))
    fu = row["fusion"]
    print(fmt % ("ours vd_fusion_bench (GT poses)", fu["integrate_mean_ms"], fu["integrate_median_ms"],
                 fu["extract_ms"], "%d" % fu["triangles"], "-"))
    print("  (fusion bench grid %s, %d bricks integrated per frame on average)" % (
        "x".join(str(g) for g in fu["grid"]), fu["bricks_mean"]))
    fs = row.get("fusion_sparse")
    if fs:
        print(fmt % ("ours vd_fusion_bench sparse (GT poses)", fs["integrate_mean_ms"], fs["integrate_median_ms"],
                     fs["extract_ms"], "%d" % fs["triangles"], "-"))
    print(fmt % ("ours vdeform-server (tracked)", srv_int, srv_int_med, srv_mc, "-",
                 "%.0f" % (sv["peak_resident_bytes"] / 1e6)))
    print("  (our dense grid %dx%dx%d = %.1f M voxels x 12 B = %.0f MB; server OpenCL peak %.0f MB; %d frames, "
          "tracking lost %d; kernel bench = median of reps on frame 0, extract = marching cubes once)" % (
              gx, gy, gz, nvox / 1e6, nvox * 12 / 1e6, sv["peak_device_bytes"] / 1e6, sv["frames"],
              sv["tracking_lost"]))
    print("ratios ours / Open3D (< 1: ours faster):")
    for oname, r in o3d_rows:
        oi, oe = mean(r["integrate_ms"]), r["extract_ms"]
        ours = [("fusion bench", fu["integrate_mean_ms"], fu["extract_ms"])]
        if fs:
            ours.append(("fusion sparse", fs["integrate_mean_ms"], fs["extract_ms"]))
        ours += [("server", srv_int, srv_mc), ("kernel OpenCL", k["integrate_ocl_ms"], k["marching_cubes_ocl_ms"])]
        for lbl, i, m in ours:
            print("  ours (%-13s) / %-30s integrate per frame %6.2fx   %d x integrate + 1 extraction %6.2fx" % (
                lbl, oname, i / oi, n, (n * i + m) / (n * oi + oe)))
    # Frame 0 holds one-off costs: ours builds its kernels for their work-group sizes there (PoCL
    # compiles at the first launch; a server pays it once at start-up). The same ratios over frames
    # 1..N-1 on both sides.
    print("steady state, frame 0 left out on both sides (ours: first frame %s ms):" % ", ".join(
        "%s %.1f" % (lbl, f["integrate_first_ms"]) for lbl, f in (("dense", fu), ("sparse", fs)) if f))
    for oname, r in o3d_rows:
        oi, oe = mean(r["integrate_ms"][1:]), r["extract_ms"]
        for lbl, f in (("fusion bench", fu), ("fusion sparse", fs)):
            if not f:
                continue
            i, m = f["integrate_steady_ms"], f["extract_ms"]
            print("  ours (%-13s) / %-30s integrate per frame %6.2fx   %d x integrate + 1 extraction %6.2fx" % (
                lbl, oname, i / oi, n - 1, ((n - 1) * i + m) / ((n - 1) * oi + oe)))


if __name__ == "__main__":
    main()
