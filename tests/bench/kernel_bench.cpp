// Each kernel on the OpenCL device against its CPU reference (same shared math, OpenMP, -O3) on
// the same data, per stage, in one run so the ratio survives a noisy machine.
//   vd_kernel_bench [--scene rigid|tube|cloth|folder:DIR] [--voxel-size M] [--reps N]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "core/engine.h"
#include "cpu_ref/cpu_ref.h"
#include "ocl/device_ops.h"
#include "shared/raster.h"
#include "vd/capture/source.h"

namespace vd {
namespace {

double MedianMs(int reps, const std::function<void()>& f) {
  std::vector<double> t;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    t.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::nth_element(t.begin(), t.begin() + t.size() / 2, t.end());
  return t[t.size() / 2];
}

void Check(const Status& s) {
  if (!s.ok()) {
    std::fprintf(stderr, "vd_kernel_bench: %s\n", s.ToString().c_str());
    std::exit(1);
  }
}

int Main(int argc, char** argv) {
  std::string scene = "synthetic:rigid";
  float voxel = 0.004f;
  int reps = 5;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--scene")) scene = argv[i + 1];
    if (!std::strcmp(argv[i], "--voxel-size")) voxel = std::stof(argv[i + 1]);
    if (!std::strcmp(argv[i], "--reps")) reps = std::stoi(argv[i + 1]);
  }
  auto source = OpenSource(scene, SourceOptions());
  Check(source.status());
  auto f = (*source)->Next();
  Check(f.status());
  const RgbdFrame frame = **f;
  EngineParams params;
  params.voxel_size = voxel;
  auto volr = Engine::PlaceVolume(frame, params);
  Check(volr.status());
  const VdVolume vol = *volr;
  auto ctx_or = ocl::Context::Create("");
  Check(ctx_or.status());
  ocl::Context* ctx = ctx_or->get();
  DeviceOps ops(ctx);
  Check(ops.Init());
  const int w = frame.intrinsics.width, h = frame.intrinsics.height, n = w * h;
  VdCamera cam{frame.intrinsics.fx, frame.intrinsics.fy, frame.intrinsics.cx, frame.intrinsics.cy, w, h, 0, 0};
  VdPose I = ToVdPose(Eigen::Matrix4d::Identity());
  std::printf("scene %s, %dx%d, grid %dx%dx%d (%.1f M points) at %.1f mm, device %s\n", scene.c_str(), w, h, vol.dim_x,
              vol.dim_y, vol.dim_z, double(vol.dim_x) * vol.dim_y * vol.dim_z / 1e6, voxel * 1000, ctx->Describe().c_str());
  std::printf("%-16s %10s %10s %8s\n", "stage", "cpu_ms", "ocl_ms", "ocl/cpu");
  auto row = [](const char* name, double c, double o) { std::printf("%-16s %10.2f %10.2f %8.2f\n", name, c, o, o / c); };

  // Preprocessing.
  std::vector<uint16_t> raw(frame.depth.begin<uint16_t>(), frame.depth.end<uint16_t>());
  std::vector<float> depth(n), bil(n), half(n / 4);
  std::vector<vd_float4> vmap(n), nmap(n);
  std::vector<uint32_t> rgba(n);
  cv::Mat rgba_mat(h, w, CV_8UC4, rgba.data());
  cv::cvtColor(frame.color, rgba_mat, cv::COLOR_BGR2RGBA);
  auto draw = ctx->Alloc<uint16_t>(n);
  auto ddepth = ctx->Alloc<float>(n), dbil = ctx->Alloc<float>(n), dhalf = ctx->Alloc<float>(n / 4);
  auto dv = ctx->Alloc<vd_float4>(n), dn = ctx->Alloc<vd_float4>(n);
  auto drgba = ctx->Alloc<uint32_t>(n);
  Check(ctx->Upload(*draw, raw.data(), n));
  Check(ctx->Upload(*drgba, rgba.data(), n));
  auto cpu_pre = [&] {
    cpu::DepthConvert(raw.data(), depth.data(), n, 1.f / frame.depth_scale, 0.2f, 3.5f);
    cpu::Bilateral(depth.data(), bil.data(), w, h, 2, 3.f, 0.02f);
    cpu::PyrDown(bil.data(), half.data(), w, h, 0.05f);
    cpu::VertexMap(bil.data(), vmap.data(), cam);
    cpu::NormalMap(vmap.data(), nmap.data(), w, h, 0.05f);
  };
  auto ocl_pre = [&] {
    Check(ops.DepthConvert(*draw, *ddepth, n, 1.f / frame.depth_scale, 0.2f, 3.5f));
    Check(ops.Bilateral(*ddepth, *dbil, w, h, 2, 3.f, 0.02f));
    Check(ops.PyrDown(*dbil, *dhalf, w, h, 0.05f));
    Check(ops.VertexMap(*dbil, *dv, cam));
    Check(ops.NormalMap(*dv, *dn, w, h, 0.05f));
    Check(ctx->Finish());
  };
  ocl_pre();
  row("preprocess", MedianMs(reps, cpu_pre), MedianMs(reps, ocl_pre));

  // Integration (the same frame fused repeatedly).
  const size_t nv = size_t(vol.dim_x) * vol.dim_y * vol.dim_z;
  std::vector<float> tsdf(nv, 1.f), weight(nv, 0.f);
  std::vector<uint32_t> color(nv, 0u);
  DeviceVolume dvol;
  Check(ops.AllocVolume(vol, false, &dvol));
  auto cpu_int = [&] { cpu::IntegrateTsdf(tsdf.data(), weight.data(), color.data(), vol, cam, I, depth.data(), rgba.data()); };
  auto ocl_int = [&] {
    Check(ops.IntegrateTsdfDense(dvol, cam, I, *ddepth, *drgba));
    Check(ctx->Finish());
  };
  ocl_int();
  row("integrate_dense", MedianMs(reps, cpu_int), MedianMs(reps, ocl_int));
  // "integrate": over the 8^3 bricks of the truncation band (the engine's path since session 3).
  std::vector<uint32_t> brick_flags;
  auto cpu_bint = [&] {
    cpu::IntegrateTsdfBricks(tsdf.data(), weight.data(), color.data(), vol, cam, I, depth.data(), rgba.data(),
                             &brick_flags);
  };
  auto ocl_bint = [&] {
    Check(ops.IntegrateTsdf(dvol, cam, I, *ddepth, *drgba));
    Check(ctx->Finish());
  };
  ocl_bint();
  row("integrate", MedianMs(reps, cpu_bint), MedianMs(reps, ocl_bint));
  std::printf("  (%zu of %zu bricks in the band)\n", ops.last_integrated_bricks(), brick_flags.size());

  // Marching cubes.
  cpu::McMesh mesh;
  DeviceMesh dmesh;
  auto cpu_mc = [&] { mesh = cpu::MarchingCubes(tsdf.data(), weight.data(), color.data(), vol); };
  auto ocl_mc = [&] {
    Check(ops.MarchingCubes(dvol, &dmesh));
    Check(ops.GridToWorld(vol, &dmesh));
    Check(ctx->Finish());
  };
  ocl_mc();
  row("marching_cubes", MedianMs(reps, cpu_mc), MedianMs(reps, ocl_mc));
  std::printf("  (%zu vertices, %zu triangles)\n", dmesh.num_vertices, dmesh.num_triangles);

  // Rasterisation of the extracted mesh.
  std::vector<vd_float4> world(mesh.positions_grid.size());
  for (size_t i = 0; i < world.size(); ++i) {
    const auto& g = mesh.positions_grid[i];
    world[i] = VD_F4(vol.origin.x + vol.voxel_size * g.x, vol.origin.y + vol.voxel_size * g.y,
                     vol.origin.z + vol.voxel_size * g.z, 1.f);
  }
  cpu::RasterMaps maps;
  DeviceRaster draster;
  auto cpu_ras = [&] {
    cpu::Rasterize(world.data(), mesh.normals.data(), mesh.triangles.data(), int(mesh.triangles.size() / 3), I, cam, &maps);
  };
  auto ocl_ras = [&] {
    Check(ops.Rasterize(dmesh, I, cam, &draster));
    Check(ctx->Finish());
  };
  ocl_ras();
  row("raster", MedianMs(reps, cpu_ras), MedianMs(reps, ocl_ras));

  // One ICP reduction at full resolution.
  VdIcpParams prm{};
  prm.cam_to_world = prm.world_to_model = prm.model_to_world = I;
  prm.model_cam = cam;
  prm.max_distance = 0.1f;
  prm.min_normal_dot = 0.8f;
  double acc[VD_ICP_ACC];
  auto cpu_icp = [&] { cpu::IcpReduce(vmap.data(), nmap.data(), maps.vertex.data(), maps.normal.data(), n, prm, acc); };
  auto ocl_icp = [&] { Check(ops.IcpReduce(*dv, *dn, draster.vertex, draster.normal, n, prm, acc)); };
  ocl_icp();
  row("icp_reduce", MedianMs(reps, cpu_icp), MedianMs(reps, ocl_icp));
  return 0;
}

}  // namespace
}  // namespace vd

int main(int argc, char** argv) { return vd::Main(argc, argv); }
