// Where a deforming model on the bricks grows (core/growth.h PlanGrowth): depth the rendered live
// model does not explain, taken into the canonical space through the nearest rendered surface's
// displacement, on a small exact scene (no device).
#include "core/growth.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "shared/brick_hash.h"
#include "shared/raster.h"
#include "shared/tsdf.h"

namespace vd {
namespace {

constexpr float kVoxel = 0.004f, kTruncation = 0.02f;

VdCamera Camera() {
  VdCamera c{};
  c.width = 64;
  c.height = 48;
  c.fx = c.fy = 500.f;  // 2 mm a pixel at 1 m: 4 samples a brick side
  c.cx = 32.f;
  c.cy = 24.f;
  return c;
}

VdPose Identity() {
  VdPose p{};
  p.r0 = VD_F4(1.f, 0.f, 0.f, 0.f);
  p.r1 = VD_F4(0.f, 1.f, 0.f, 0.f);
  p.r2 = VD_F4(0.f, 0.f, 1.f, 0.f);
  return p;
}

uint32_t KeyOf(float x, float y, float z) {
  const float b = VD_BRICK * kVoxel;
  return vd_brick_pack(int(std::floor(x / b)), int(std::floor(y / b)), int(std::floor(z / b)));
}

// A wall 1 m in front of the camera; the model (one triangle, its first vertex 1 m away, moved
// 5 cm along x from its canonical place) is rendered on the columns left of `model_columns`.
struct Scene {
  VdCamera cam = Camera();
  cv::Mat depth = cv::Mat(48, 64, CV_16UC1, cv::Scalar(1000));
  std::vector<uint32_t> ids;
  std::vector<int32_t> tris{0, 1, 2};
  vd_float4 displacement = VD_F4(0.05f, 0.f, 0.f, 0.f);
  std::vector<vd_float4> deformed{VD_F4(-0.2f, 0.f, 1.f, 1.f), VD_F4(-0.2f, 0.1f, 1.f, 1.f),
                                  VD_F4(-0.1f, 0.f, 1.f, 1.f)};
  std::vector<vd_float4> grid;
  explicit Scene(int model_columns) : ids(64 * 48, VD_RASTER_EMPTY) {
    for (int v = 0; v < 48; ++v)
      for (int u = 0; u < model_columns; ++u) ids[v * 64 + u] = 0;
    for (const vd_float4& d : deformed)
      grid.push_back(VD_F4((d.x - displacement.x) / kVoxel, (d.y - displacement.y) / kVoxel,
                           (d.z - displacement.z) / kVoxel, 0.f));
  }
  std::vector<GrowthBrick> Plan(const GrowthParams& p = GrowthParams()) const {
    return PlanGrowth(depth, 0.001f, 0.2f, 3.5f, cam, Identity(), ids.data(), tris.data(), 1, deformed.data(),
                      grid.data(), kVoxel, kTruncation, p);
  }
  // The keys the samples of columns [u0, u1) fall in, moved back by `d`, with the band along the ray.
  std::set<uint32_t> Keys(int u0, int u1, vd_float4 d, int stride) const {
    std::set<uint32_t> out;
    for (int v = 0; v < cam.height; v += stride)
      for (int u = (u0 + stride - 1) / stride * stride; u < u1; u += stride) {
        const vd_float4 f = VD_F4((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.f, 0.f);
        const float len = std::sqrt(vd_dot3(f, f));
        for (float o : {-kTruncation, 0.f, kTruncation})
          out.insert(KeyOf(f.x - d.x + o * f.x / len, f.y - d.y + o * f.y / len, f.z - d.z + o * f.z / len));
      }
    return out;
  }
};

TEST(GrowthTest, UnexplainedDepthGrowsWhereTheNearestSurfaceMovedIt) {
  const Scene scene(24);
  GrowthParams p;
  const std::vector<GrowthBrick> plan = scene.Plan(p);
  ASSERT_FALSE(plan.empty());
  // Samples at columns 24..32 lie within min_gap (3 samples of 4 px) of the model's last column
  // (20): its edge, not grown. Beyond, every brick is one the far samples name.
  const std::set<uint32_t> far = scene.Keys(p.stride * (5 + p.min_gap), 64, scene.displacement, p.stride);
  std::set<uint32_t> planned;
  for (const GrowthBrick& b : plan) {
    planned.insert(b.key);
    EXPECT_TRUE(far.count(b.key)) << b.key;
    EXPECT_GE(b.samples, p.min_samples);
    // The model's triangle moved 5 cm along x, unrotated.
    EXPECT_NEAR(b.motion.r0.w, 0.05f, 1e-5f);
    EXPECT_NEAR(b.motion.r1.w, 0.f, 1e-5f);
    EXPECT_NEAR(b.motion.r0.x, 1.f, 1e-5f);
    EXPECT_NEAR(b.motion.r1.y, 1.f, 1e-5f);
  }
  // The brick of the far right sample at the centre row (moved back 5 cm) is there.
  EXPECT_TRUE(planned.count(KeyOf((60 - scene.cam.cx) / scene.cam.fx - 0.05f, 0.f, 1.f)));
  EXPECT_GT(planned.size(), far.size() / 3);
  // Most samples first.
  for (size_t i = 1; i < plan.size(); ++i) EXPECT_GE(plan[i - 1].samples, plan[i].samples);
}

TEST(GrowthTest, ExplainedDepthAndMissingDepthGrowNothing) {
  Scene scene(64);  // the model covers the view at the observed depth
  EXPECT_TRUE(scene.Plan().empty());
  Scene holes(24);
  holes.depth.setTo(cv::Scalar(0));  // no depth: nothing to explain
  EXPECT_TRUE(holes.Plan().empty());
  Scene beyond(24);
  beyond.depth.setTo(cv::Scalar(5000));  // past max_depth
  EXPECT_TRUE(beyond.Plan().empty());
}

TEST(GrowthTest, WithNoSurfaceNearANewObjectIsTakenWhereTheCameraSeesIt) {
  Scene scene(0);
  GrowthParams p;
  p.max_bricks = 1 << 20;
  const std::vector<GrowthBrick> plan = scene.Plan(p);
  ASSERT_FALSE(plan.empty());
  const std::set<uint32_t> all = scene.Keys(0, 64, VD_F4(0.f, 0.f, 0.f, 0.f), p.stride);
  for (const GrowthBrick& b : plan) {
    EXPECT_TRUE(all.count(b.key));
    EXPECT_EQ(b.motion.r0.w, 0.f);
    EXPECT_EQ(b.motion.r0.x, 1.f);
  }
  p.max_bricks = 3;
  EXPECT_EQ(scene.Plan(p).size(), 3u) << "at most max_bricks a frame";
}

// A surface nearer than the observation by more than the band: the depth is not explained (an
// object in front of the model), so it grows.
TEST(GrowthTest, DepthInFrontOfTheRenderedSurfaceIsUnexplained) {
  Scene scene(64);
  scene.depth.setTo(cv::Scalar(1000));
  scene.depth(cv::Rect(40, 0, 24, 48)).setTo(cv::Scalar(700));
  GrowthParams p;
  p.min_gap = 0;
  const std::vector<GrowthBrick> plan = scene.Plan(p);
  ASSERT_FALSE(plan.empty());
  for (const GrowthBrick& b : plan) {
    int bx, by, bz;
    vd_brick_unpack(b.key, &bx, &by, &bz);
    EXPECT_LE(bz * VD_BRICK * kVoxel, 0.72f + kTruncation) << "at the near object's depth";
  }
}

// A triangle's motion: rotation and translation recovered from its corners; a degenerate one moves
// by its first corner only.
TEST(GrowthTest, TriangleMotionRecoversARigidMotion) {
  const float a = 0.4f, c = std::cos(a), s = std::sin(a);
  const vd_float4 t = VD_F4(0.1f, -0.2f, 0.3f, 0.f);
  auto move = [&](vd_float4 p) { return VD_F4(c * p.x - s * p.z + t.x, p.y + t.y, s * p.x + c * p.z + t.z, 1.f); };
  const vd_float4 canon[3] = {VD_F4(0.1f, 0.f, 1.f, 1.f), VD_F4(0.11f, 0.f, 1.f, 1.f), VD_F4(0.1f, 0.012f, 1.01f, 1.f)};
  const vd_float4 moved[3] = {move(canon[0]), move(canon[1]), move(canon[2])};
  const VdPose m = TriangleMotion(canon, moved);
  const vd_float4 q = VD_F4(0.3f, -0.1f, 0.8f, 1.f), want = move(q), got = vd_pose_apply(m, q);
  EXPECT_NEAR(got.x, want.x, 1e-4f);
  EXPECT_NEAR(got.y, want.y, 1e-4f);
  EXPECT_NEAR(got.z, want.z, 1e-4f);
  const vd_float4 flat[3] = {canon[0], canon[0], canon[0]};
  const vd_float4 flat_moved[3] = {moved[0], moved[0], moved[0]};
  const VdPose d = TriangleMotion(flat, flat_moved);
  EXPECT_EQ(d.r0.x, 1.f);
  EXPECT_NEAR(d.r0.w, moved[0].x - canon[0].x, 1e-6f);
}

}  // namespace
}  // namespace vd
