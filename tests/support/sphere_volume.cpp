#include "sphere_volume.h"

#include <algorithm>
#include <cmath>

namespace vd::test {

VdVolume TestVolume(int dim_x, int dim_y, int dim_z, float voxel_size, vd_float4 origin) {
  VdVolume vol{};
  vol.dim_x = dim_x;
  vol.dim_y = dim_y;
  vol.dim_z = dim_z;
  vol.voxel_size = voxel_size;
  vol.origin = origin;
  vol.truncation = 4 * voxel_size;
  vol.max_weight = 64.f;
  return vol;
}

AnalyticVolume MakeAnalyticVolume(const VdVolume& vol, const std::function<float(float, float, float)>& sdf) {
  AnalyticVolume g;
  g.vol = vol;
  const size_t n = size_t(vol.dim_x) * vol.dim_y * vol.dim_z;
  g.tsdf.resize(n);
  g.weight.assign(n, 1.f);
  g.color.assign(n, 0u);
  for (int z = 0; z < vol.dim_z; ++z)
    for (int y = 0; y < vol.dim_y; ++y)
      for (int x = 0; x < vol.dim_x; ++x) {
        const float d = sdf(vol.origin.x + vol.voxel_size * x, vol.origin.y + vol.voxel_size * y,
                            vol.origin.z + vol.voxel_size * z);
        g.tsdf[x + size_t(vol.dim_x) * (y + size_t(vol.dim_y) * z)] = std::clamp(d / vol.truncation, -1.f, 1.f);
      }
  return g;
}

AnalyticVolume MakeSphereVolume(const VdVolume& vol, float cx, float cy, float cz, float radius) {
  return MakeAnalyticVolume(vol, [=](float x, float y, float z) {
    return std::sqrt((x - cx) * (x - cx) + (y - cy) * (y - cy) + (z - cz) * (z - cz)) - radius;
  });
}

}  // namespace vd::test
