#pragma once
// The dense volume the marching-cubes, active-set, hierarchy, correspondence and solver tests
// start from: the truncated signed distance of an analytic surface, every voxel observed.
#include <cstdint>
#include <functional>
#include <vector>

#include "shared/vd_types.h"

namespace vd::test {

struct AnalyticVolume {
  VdVolume vol{};
  // Signed distance / vol.truncation, clamped to [-1, 1]; x fastest, then y, then z.
  std::vector<float> tsdf;
  // 1 everywhere: every voxel observed, so marching cubes sees the whole surface.
  std::vector<float> weight;
  // 0 everywhere; tests of colour write their own pattern.
  std::vector<uint32_t> color;
};

// dim_x x dim_y x dim_z voxels of voxel_size metres from origin (the corner voxel's centre), with
// the truncation of 4 voxels and the maximum weight of 64 the engine uses.
VdVolume TestVolume(int dim_x, int dim_y, int dim_z, float voxel_size, vd_float4 origin);

// sdf(x, y, z): signed distance in metres at the world point of a grid point,
// vol.origin + vol.voxel_size * (i, j, k).
AnalyticVolume MakeAnalyticVolume(const VdVolume& vol, const std::function<float(float, float, float)>& sdf);

// A sphere of `radius` metres around the world point (cx, cy, cz).
AnalyticVolume MakeSphereVolume(const VdVolume& vol, float cx, float cy, float cz, float radius);

}  // namespace vd::test
