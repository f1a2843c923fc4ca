#pragma once
// When a deforming model on the bricks last saw each of its bricks (issue 17: a full pool drops
// the bricks seen longest ago). A rigid model knows it from the depth's band (the table's listing
// stamps); a deforming one fuses only its active set, which holds the whole surface whether in
// view or not, so "seen" is taken from the rendered live model instead: the canonical brick under
// each pixel it covers. A brick within two of one seen counts as seen too: it carries the field
// those points are solved with (the one-ring of the surface's cells reaches the next brick, and a
// coarse cell of a ring point, at most a brick a side, one further).
#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "shared/vd_types.h"

namespace vd {

class BrickSightings {
 public:
  // Marks `frame` on the brick of each triangle covering a pixel of the rendered live model, every
  // `step`-th pixel in x and y (ids: width x height triangle ids, VD_RASTER_EMPTY: none; tris the
  // faces, grid the vertices in canonical grid units, bricks of VD_BRICK voxels from the origin).
  void See(const uint32_t* ids, int width, int height, int step, const int32_t* tris, size_t num_triangles,
           const vd_float4* grid, uint32_t frame);
  // The frame the brick of `key` was last seen in (0: never).
  uint32_t LastSeen(uint32_t key) const;
  // Up to `count` of the slots (slot_keys[s]: the key of slot s's brick) whose brick and the 124
  // within two of it (kReach) were all last seen before `frame`, seen longest ago first (ties in slot order).
  std::vector<uint32_t> Oldest(const std::vector<uint32_t>& slot_keys, uint32_t frame, size_t count) const;
  // Forgets every sighting (a model restored from a checkpoint starts without them).
  void Clear() { last_.clear(); }
  size_t size() const { return last_.size(); }

 private:
  // Bricks (per axis) a sighting protects: with one, the corners of coarse cells two bricks from the
  // surface could be dropped and allocated again every frame (a 2 m strip sliding 80 cm through
  // the view with a 36 MB pool: 1727 bricks dropped over the take instead of 1043, and up to 129 of
  // a frame's ring and corners not allocated; the "pass" scene's 1.8 m strip drops 609 against 598).
  static constexpr int kReach = 2;
  std::unordered_map<uint32_t, uint32_t> last_;
};

}  // namespace vd
