// Which bricks a deforming model drops when its pool is full (core/brick_sightings.h): the ones
// the rendered live model covered longest ago, never one in view or within two bricks of one
// in view (no device).
#include "core/brick_sightings.h"

#include <gtest/gtest.h>

#include <vector>

#include "shared/brick_hash.h"
#include "shared/raster.h"
#include "shared/tsdf.h"

namespace vd {
namespace {

// A 4x1 image whose pixels show triangles 0..3; triangle t's first vertex at grid point g[t].
struct View {
  std::vector<uint32_t> ids;
  std::vector<int32_t> tris;
  std::vector<vd_float4> grid;
};

// One pixel per brick: pixel i shows a triangle whose first vertex lies in brick (bx[i], 0, 0).
View Showing(const std::vector<int>& bx) {
  View v;
  for (size_t i = 0; i < bx.size(); ++i) {
    v.ids.push_back(uint32_t(i));
    v.tris.insert(v.tris.end(), {int32_t(i), int32_t(i), int32_t(i)});
    v.grid.push_back(VD_F4(float(VD_BRICK * bx[i]) + 3.5f, 2.f, 5.f, 1.f));
  }
  return v;
}

void See(BrickSightings& s, const View& v, uint32_t frame) {
  s.See(v.ids.data(), int(v.ids.size()), 1, 1, v.tris.data(), v.tris.size() / 3, v.grid.data(), frame);
}

uint32_t Key(int bx) { return vd_brick_pack(bx, 0, 0); }

TEST(BrickSightingsTest, MarksTheBrickUnderEachCoveredPixel) {
  BrickSightings s;
  View v = Showing({0, 1, -3});
  v.ids[1] = VD_RASTER_EMPTY;  // nothing rendered there
  See(s, v, 7);
  EXPECT_EQ(s.LastSeen(Key(0)), 7u);
  EXPECT_EQ(s.LastSeen(Key(1)), 0u);
  EXPECT_EQ(s.LastSeen(Key(-3)), 7u);
  See(s, Showing({-3}), 9);
  EXPECT_EQ(s.LastSeen(Key(-3)), 9u);
  EXPECT_EQ(s.LastSeen(Key(0)), 7u);
  // A triangle id past the faces (a raster of another mesh) marks nothing.
  View bad = Showing({20});
  bad.ids[0] = 5;
  See(s, bad, 10);
  EXPECT_EQ(s.LastSeen(Key(20)), 0u);
}

TEST(BrickSightingsTest, TheOldestGoFirstAndNothingInViewOrBesideIt) {
  BrickSightings s;
  See(s, Showing({10}), 1);
  See(s, Showing({20}), 2);
  See(s, Showing({30}), 3);
  See(s, Showing({40}), 4);
  // Slots: 40 (in view now), 41 (beside it, never seen itself), 30, 10, 20, 50 (never seen), an
  // empty slot, 42 (two from 40: a coarse corner of its ring's cells) and 43 (three from it).
  const std::vector<uint32_t> slots = {Key(40), Key(41),        Key(30), Key(10), Key(20),
                                       Key(50), VD_BRICK_EMPTY, Key(42), Key(43)};
  EXPECT_EQ(s.Oldest(slots, 4, 10), (std::vector<uint32_t>{5, 8, 3, 4, 2}));
  // At most `count`, oldest first (ties in slot order).
  EXPECT_EQ(s.Oldest(slots, 4, 2), (std::vector<uint32_t>{5, 8}));
  // A later frame with nothing in view: 40 and the bricks near it may go too, last.
  EXPECT_EQ(s.Oldest(slots, 5, 10), (std::vector<uint32_t>{5, 8, 3, 4, 2, 0, 1, 7}));
  // A brick seen two away in other directions too protects a brick: (12, 2, -2) keeps 10.
  See(s, View{{0u}, {0, 0, 0}, {VD_F4(8.f * 12 + 1.f, 8.f * 2 + 1.f, 8.f * -2 + 1.f, 1.f)}}, 5);
  EXPECT_EQ(s.Oldest(slots, 5, 10), (std::vector<uint32_t>{5, 8, 4, 2, 0, 1, 7}));
  s.Clear();
  EXPECT_EQ(s.size(), 0u);
  EXPECT_EQ(s.Oldest(slots, 5, 10), (std::vector<uint32_t>{0, 1, 2, 3, 4, 5, 7, 8}));
}

}  // namespace
}  // namespace vd
