// TSDF fusion as Open3D's pipelines are benchmarked (tests/bench/open3d_tsdf_bench.py): N frames of a
// 7-Scenes-layout folder integrated with their ground-truth poses, integration timed per frame
// (depth conversion and upload untimed, like Open3D's RGBDImage preparation), then one marching
// cubes extraction. The grid is placed from frame 0 as the server places it with --rigid-only.
// --sparse 1 fuses into the brick table and pool of the sparse volume instead (docs/SPARSE_VOLUME.md:
// allocation from each frame's depth, then fusion into the bricks; marching cubes over the bricks).
//   vd_fusion_bench --data DIR [--voxel-size M] [--frames N] [--sparse 1]
// Prints key value lines: integrate_mean_ms, integrate_median_ms, extract_ms, triangles, bricks_mean;
// with --sparse also bricks_used, bricks_failed, pool_mb (12 bytes a voxel, as --rigid-only),
// first_frame_grid_mb, same_extent_dense_mb (the bricks' bounding box, dense).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/engine.h"
#include "ocl/brick_hash_ocl.h"
#include "ocl/device_ops.h"
#include "vd/capture/source.h"

namespace vd {
namespace {

void Check(const Status& s) {
  if (!s.ok()) {
    std::fprintf(stderr, "vd_fusion_bench: %s\n", s.ToString().c_str());
    std::exit(1);
  }
}

Eigen::Matrix4d ReadPose(const std::string& path) {
  std::ifstream in(path);
  Eigen::Matrix4d T;
  for (int i = 0; i < 16; ++i) in >> T(i / 4, i % 4);
  if (!in || !T.allFinite()) Check(NotFound("cannot read a 4x4 pose from " + path));
  return T;
}

double Ms(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

int Main(int argc, char** argv) {
  std::string data;
  float voxel = 0.01f;
  int frames = 100;
  bool sparse = false;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--data")) data = argv[i + 1];
    else if (!std::strcmp(argv[i], "--sparse"))
      sparse = std::stoi(argv[i + 1]) != 0;
    else if (!std::strcmp(argv[i], "--voxel-size")) voxel = std::stof(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--frames")) frames = std::stoi(argv[i + 1]);
    else Check(InvalidArgument(std::string("unknown flag ") + argv[i]));
  }
  if (data.empty() || frames < 1) Check(InvalidArgument("usage: vd_fusion_bench --data DIR [--voxel-size M] [--frames N]"));
  SourceOptions so;
  so.count = frames;
  auto source = OpenSource("folder:" + data, so);
  Check(source.status());
  std::vector<RgbdFrame> input;
  std::vector<Eigen::Matrix4d> poses;
  char name[64];
  for (int k = 0; k < frames; ++k) {
    auto f = (*source)->Next();
    Check(f.status());
    if (!f->has_value()) break;
    input.push_back(**f);
    std::snprintf(name, sizeof(name), "/frame-%06d.pose.txt", k);
    poses.push_back(ReadPose(data + name));
  }
  EngineParams params;
  params.voxel_size = voxel;
  params.rigid_only = true;
  auto vol = Engine::PlaceVolume(input[0], params);
  Check(vol.status());
  auto ctx_or = ocl::Context::Create("");
  Check(ctx_or.status());
  ocl::Context* ctx = ctx_or->get();
  DeviceOps ops(ctx);
  Check(ops.Init());
  const Intrinsics& k = input[0].intrinsics;
  const int w = k.width, h = k.height, n = w * h;
  const VdCamera cam{k.fx, k.fy, k.cx, k.cy, w, h, 0, 0};
  DeviceVolume dv;
  // The sparse volume: a pool of as many bricks as the dense grid's memory budget holds.
  std::optional<ocl::BrickTable> table;
  std::optional<ocl::BrickPool> pool;
  VdVolume brick_vol{};
  if (sparse) {
    const uint32_t slots = uint32_t(params.max_grid_mb * 1e6 / (12.0 * VD_BRICK_VOXELS));
    auto t = ocl::BrickTable::Create(*ctx, slots);
    Check(t.status());
    table.emplace(std::move(*t));
    auto p = ocl::BrickPool::Create(*ctx, slots);
    Check(p.status());
    pool.emplace(std::move(*p));
    brick_vol.voxel_size = voxel;
    brick_vol.truncation = params.truncation_voxels * voxel;
    brick_vol.max_weight = params.max_weight;
  } else {
    Check(ops.AllocVolume(*vol, false, &dv));
  }
  auto raw = ctx->Alloc<uint16_t>(n);
  auto depth = ctx->Alloc<float>(n);
  auto rgba = ctx->Alloc<uint32_t>(n);
  Check(raw.status());
  std::vector<uint32_t> rgba_host(n);
  std::vector<double> times;
  double bricks = 0;
  const Eigen::Matrix4d world0 = poses[0];
  for (size_t f = 0; f < input.size(); ++f) {
    // Untimed preparation: depth to metres on the device, colour to RGBA.
    const cv::Mat d = input[f].depth.isContinuous() ? input[f].depth : input[f].depth.clone();
    Check(ctx->Upload(*raw, d.ptr<uint16_t>(), n));
    cv::Mat rgba_mat(h, w, CV_8UC4, rgba_host.data());
    cv::cvtColor(input[f].color, rgba_mat, cv::COLOR_BGR2RGBA);
    Check(ctx->Upload(*rgba, rgba_host.data(), n));
    Check(ops.DepthConvert(*raw, *depth, n, 1.f / input[f].depth_scale, params.min_depth, params.max_depth));
    Check(ctx->Finish());
    // World = frame 0's camera, as the server's.
    const Eigen::Matrix4d world_to_cam = (world0.inverse() * poses[f]).inverse();
    const auto t0 = std::chrono::steady_clock::now();
    if (sparse) {
      const VdPose cam_to_world = ToVdPose(world_to_cam.inverse());
      Check(table->AllocateAndList(*ctx, *depth, cam, cam_to_world, brick_vol.truncation, VD_BRICK * voxel));
      Check(ocl::IntegrateBricks(*ctx, *table, *pool, brick_vol, cam, ToVdPose(world_to_cam), *depth, *rgba));
    } else {
      Check(ops.IntegrateTsdf(dv, cam, ToVdPose(world_to_cam), *depth, *rgba));
    }
    Check(ctx->Finish());
    times.push_back(Ms(t0));
    if (!sparse) bricks += double(ops.last_integrated_bricks());
    if (sparse) {
      auto c = table->Counts(*ctx);
      Check(c.status());
      bricks += c->visible;
    }
  }
  // Frame 0 also builds our kernels for their work-group sizes (PoCL compiles at the first launch, a
  // one-off a server pays at start-up): reported apart, and the mean of the frames after it.
  double steady = 0;
  for (size_t f = 1; f < times.size(); ++f) steady += times[f];
  steady /= double(std::max<size_t>(times.size() - 1, 1));
  std::printf("integrate_first_ms %.3f\nintegrate_steady_ms %.3f\n", times.empty() ? 0.0 : times[0], steady);
  if (sparse) {
    auto counts = table->Counts(*ctx);
    Check(counts.status());
    double sum = 0;
    for (double t : times) sum += t;
    std::vector<double> sorted = times;
    std::sort(sorted.begin(), sorted.end());
    std::printf("sparse at %.1f mm, %zu frames, pool %u bricks, device %s\n", voxel * 1000, times.size(), table->pool(),
                ctx->Describe().c_str());
    // The dense grid that would hold the same bricks: their bounding box.
    std::vector<uint32_t> keys(counts->used);
    if (!keys.empty()) Check(ctx->Download(table->slot_keys(), keys.data(), keys.size()));
    int lo[3] = {1 << 30, 1 << 30, 1 << 30}, hi[3] = {-(1 << 30), -(1 << 30), -(1 << 30)};
    for (uint32_t key : keys) {
      int b[3];
      vd_brick_unpack(key, &b[0], &b[1], &b[2]);
      for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], b[a]), hi[a] = std::max(hi[a], b[a]);
    }
    double box = 1;
    for (int a = 0; a < 3; ++a) box *= keys.empty() ? 0.0 : double(hi[a] - lo[a] + 1) * VD_BRICK;
    DeviceMesh mesh;
    Check(ops.MarchingCubes(*table, *pool, &mesh));  // warm-up: buffers sized, kernels built
    Check(ctx->Finish());
    const auto t0 = std::chrono::steady_clock::now();
    Check(ops.MarchingCubes(*table, *pool, &mesh));
    Check(ctx->Finish());
    const double extract = Ms(t0);
    std::printf(
        "integrate_mean_ms %.3f\nintegrate_median_ms %.3f\nextract_ms %.3f\ntriangles %zu\nbricks_mean %.0f\n"
        "bricks_used %u\nbricks_failed %u\npool_mb %.1f\nfirst_frame_grid_mb %.1f\nsame_extent_dense_mb %.1f\n",
        sum / times.size(), sorted[sorted.size() / 2], extract, mesh.num_triangles, bricks / times.size(), counts->used,
        counts->failed, counts->used * double(VD_BRICK_VOXELS) * 12 / 1e6,
        double(vol->dim_x) * vol->dim_y * vol->dim_z * 12 / 1e6, box * 12 / 1e6);
    return 0;
  }
  DeviceMesh mesh;
  Check(ops.MarchingCubes(dv, &mesh));  // warm-up: buffers sized, kernels built
  Check(ctx->Finish());
  const auto t0 = std::chrono::steady_clock::now();
  Check(ops.MarchingCubes(dv, &mesh));
  Check(ctx->Finish());
  const double extract = Ms(t0);
  double sum = 0;
  for (double t : times) sum += t;
  std::vector<double> sorted = times;
  std::sort(sorted.begin(), sorted.end());
  std::printf("grid %dx%dx%d at %.1f mm, %zu frames, device %s\n", vol->dim_x, vol->dim_y, vol->dim_z, voxel * 1000,
              times.size(), ctx->Describe().c_str());
  std::printf("integrate_mean_ms %.3f\nintegrate_median_ms %.3f\nextract_ms %.3f\ntriangles %zu\nbricks_mean %.0f\n",
              sum / times.size(), sorted[sorted.size() / 2], extract, mesh.num_triangles, bricks / times.size());
  return 0;
}

}  // namespace
}  // namespace vd

int main(int argc, char** argv) { return vd::Main(argc, argv); }
