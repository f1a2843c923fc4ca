#include "core/brick_sightings.h"

#include <algorithm>
#include <cmath>

#include "shared/brick_hash.h"
#include "shared/raster.h"

namespace vd {

void BrickSightings::See(const uint32_t* ids, int width, int height, int step, const int32_t* tris,
                         size_t num_triangles, const vd_float4* grid, uint32_t frame) {
  step = std::max(1, step);
  uint32_t last_key = VD_BRICK_EMPTY;
  for (int v = 0; v < height; v += step)
    for (int u = 0; u < width; u += step) {
      const uint32_t t = ids[size_t(v) * width + u];
      if (t == VD_RASTER_EMPTY || size_t(t) >= num_triangles) continue;
      const vd_float4 g = grid[tris[3 * size_t(t)]];
      const int bx = int(std::floor(g.x / VD_BRICK)), by = int(std::floor(g.y / VD_BRICK)),
                bz = int(std::floor(g.z / VD_BRICK));
      if (!vd_brick_coords_valid(bx, by, bz)) continue;
      const uint32_t key = vd_brick_pack(bx, by, bz);
      // Neighbouring pixels mostly cover the same brick: one map write a run.
      if (key == last_key) continue;
      last_key = key;
      last_[key] = frame;
    }
}

uint32_t BrickSightings::LastSeen(uint32_t key) const {
  const auto it = last_.find(key);
  return it == last_.end() ? 0u : it->second;
}

std::vector<uint32_t> BrickSightings::Oldest(const std::vector<uint32_t>& slot_keys, uint32_t frame,
                                             size_t count) const {
  std::vector<uint32_t> age(slot_keys.size(), 0u), order;
  for (size_t s = 0; s < slot_keys.size(); ++s) {
    if (slot_keys[s] == VD_BRICK_EMPTY) continue;
    int bx, by, bz;
    vd_brick_unpack(slot_keys[s], &bx, &by, &bz);
    uint32_t seen = 0;
    for (int dz = -kReach; dz <= kReach; ++dz)
      for (int dy = -kReach; dy <= kReach; ++dy)
        for (int dx = -kReach; dx <= kReach; ++dx)
          if (vd_brick_coords_valid(bx + dx, by + dy, bz + dz))
            seen = std::max(seen, LastSeen(vd_brick_pack(bx + dx, by + dy, bz + dz)));
    age[s] = seen;
    if (seen < frame) order.push_back(uint32_t(s));
  }
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return age[a] < age[b]; });
  if (order.size() > count) order.resize(count);
  return order;
}

}  // namespace vd
