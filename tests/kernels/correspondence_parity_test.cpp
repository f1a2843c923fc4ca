#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "cpu_ref/cpu_ref.h"
#include "ocl/device_ops.h"
#include "sphere_volume.h"
#include "test_scenes.h"

namespace vd {
namespace {

VdCorrParams Params() {
  VdCorrParams p{};
  p.eps_d = 0.02f;
  p.eps_n = 0.5f;
  p.eps_v = 0.8f;
  p.cam_to_world = test::IdentityPose();
  return p;
}

TEST(CorrespondenceTest, WeightFollowsThePapersKernels) {
  const VdCorrParams p = Params();
  // Perfect agreement facing the camera: every Phi = 1, w = 1.
  EXPECT_FLOAT_EQ(vd_corr_weight(0.f, 1.f, 1.f, p), 1.f);
  // Half the distance threshold: Phi_d = 0.5, w = ((0.5 + 1 + 1) / 3)^2.
  EXPECT_NEAR(vd_corr_weight(0.01f, 1.f, 1.f, p), std::pow(2.5f / 3.f, 2.f), 1e-6f);
  // Any kernel below zero prunes: too far, normals too different, silhouette.
  EXPECT_EQ(vd_corr_weight(0.021f, 1.f, 1.f, p), 0.f);
  EXPECT_EQ(vd_corr_weight(0.f, 0.4f, 1.f, p), 0.f);
  EXPECT_EQ(vd_corr_weight(0.f, 1.f, 0.15f, p), 0.f);
  EXPECT_GT(vd_corr_weight(0.f, 1.f, 0.25f, p), 0.f);
}

// Packs 8-bit R, G, B as the frames are uploaded (R in the low byte, alpha 255).
uint32_t Rgba(int r, int g, int b) { return uint32_t(r) | uint32_t(g) << 8 | uint32_t(b) << 16 | 255u << 24; }

// The colour rows' parameters at the engine's defaults when on (--w-photo 0.03).
VdPhotoParams PhotoParams(const VdPose& cam_to_world, const VdCamera& cam, float max_strength) {
  VdPhotoParams p{};
  p.cam_to_world = cam_to_world;
  p.cam = cam;
  p.scale = 0.03f;
  p.huber = 0.1f;
  p.min_gradient = 0.002f;
  p.max_strength = max_strength;
  p.max_jump = 0.05f;
  p.edge_radius = 4;
  return p;
}

// A plane at z = 1 m facing a 64 x 48 camera, every pixel's model sample coloured grey 100 (all on
// one triangle), every pixel's depth row valid with w_c = 0.8; the camera sits at a rotated and
// shifted pose. The intensity image is given directly.
struct ColourRowScene {
  VdCamera cam = test::TestCamera(64, 48);
  int n = 64 * 48;
  cpu::RasterMaps model;
  std::vector<vd_float4> obs_v;
  std::vector<uint32_t> colors = {Rgba(100, 100, 100), Rgba(100, 100, 100), Rgba(100, 100, 100)};
  std::vector<int32_t> tris = {0, 1, 2};
  std::vector<float> intensity;
  VdPhotoParams prm{};
  ColourRowScene() {
    model.vertex.resize(n);
    model.ids.assign(n, 0u);
    model.bary.assign(n, VD_F4(1.f, 0.f, 0.f, 0.f));
    for (int i = 0; i < n; ++i)
      model.vertex[i] = VD_F4((i % cam.width - cam.cx) / cam.fx, (i / cam.width - cam.cy) / cam.fy, 1.f, 1.f);
    obs_v = model.vertex;
    intensity.assign(n / 4, 0.f);
    // 30 degrees about y, then 10 cm along x.
    const float c = std::cos(0.5236f), s = std::sin(0.5236f);
    prm.cam_to_world.r0 = VD_F4(c, 0.f, s, 0.1f);
    prm.cam_to_world.r1 = VD_F4(0.f, 1.f, 0.f, 0.f);
    prm.cam_to_world.r2 = VD_F4(-s, 0.f, c, 0.f);
    prm = PhotoParams(prm.cam_to_world, cam, 100.f);
  }
  // The intensity I(u, v) = 100 / 255 + offset + gu (u - 30) + gv (v - 20) at full-resolution
  // pixels; the image is kept at half resolution, whose pixel (x, y) is centred at (2x + 1/2, 2y + 1/2).
  void Ramp(float offset, float gu, float gv) {
    const int hw = cam.width / 2;
    for (int i = 0; i < hw * (cam.height / 2); ++i)
      intensity[i] =
          100.f / 255.f + offset + gu * (2.f * float(i % hw) + 0.5f - 30.f) + gv * (2.f * float(i / hw) + 0.5f - 20.f);
  }
  // The colour row of pixel i (the first of its 2x2 block) in Rows().
  int RowOf(int i) const { return n + (i / cam.width / 2) * ((cam.width + 1) / 2) + (i % cam.width) / 2; }
  std::vector<VdCorrespondence> Rows() const {
    std::vector<VdCorrespondence> rows(2 * size_t(n));
    for (int i = 0; i < n; ++i) {
      rows[i] = VdCorrespondence{};
      rows[i].canonical = VD_F4(1.f, 2.f, 3.f, 0.8f);
    }
    cpu::PhotometricCorrespondences(model, obs_v.data(), colors.data(), tris.data(), intensity.data(), prm,
                                    rows.data());
    return rows;
  }
};

// The colour rows' blocks: one row per 2x2 block at its first pixel, odd sizes included (the last
// column and row form blocks of their own), each pixel with both coordinates even exactly once.
TEST(CorrespondenceTest, ColourRowBlocksCoverTheEvenPixelsOnce) {
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{5, 3}, {6, 4}, {1, 1}, {7, 2}, {640, 480}}) {
    const int blocks = vd_photo_rows(w, h);
    EXPECT_EQ(blocks, ((w + 1) / 2) * ((h + 1) / 2)) << w << "x" << h;
    std::vector<int> seen(size_t(w) * h, 0);
    for (int b = 0; b < blocks; ++b) {
      const int i = vd_photo_pixel(b, w);
      ASSERT_GE(i, 0);
      ASSERT_LT(i, w * h) << w << "x" << h << " block " << b;
      ASSERT_EQ(((i % w) | (i / w)) & 1, 0) << w << "x" << h << " block " << b;
      ++seen[size_t(i)];
    }
    for (int i = 0; i < w * h; ++i) ASSERT_EQ(seen[size_t(i)], (((i % w) | (i / w)) & 1) == 0 ? 1 : 0) << i;
  }
  EXPECT_EQ(vd_photo_rows(5, 3), 6);
}

TEST(CorrespondenceTest, ColourRowIsTheLinearisedIntensityError) {
  ColourRowScene sc;
  sc.Ramp(0.02f, 0.01f, 0.005f);
  const auto rows = sc.Rows();
  const int i = 20 * sc.cam.width + 30;
  ASSERT_EQ(vd_photo_pixel(sc.RowOf(i) - sc.n, sc.cam.width), i);
  const VdCorrespondence& c = rows[sc.RowOf(i)];
  // Same canonical sample, four times the depth row's weight (a row on one pixel of each 2x2 block;
  // the residual 0.02 is under the Huber threshold), for the coarse levels alone.
  EXPECT_FLOAT_EQ(c.canonical.x, 1.f);
  EXPECT_FLOAT_EQ(c.canonical.z, 3.f);
  EXPECT_FLOAT_EQ(c.canonical.w, 3.2f);
  EXPECT_EQ(c.normal.w, VD_CORR_COARSE_ONLY);
  const vd_float4 p = sc.model.vertex[i];
  const vd_float4 s0 = vd_pose_apply(sc.prm.cam_to_world, p);
  // At the rendered point the row is s (I - c).
  EXPECT_NEAR(vd_dot3(c.normal, s0 - c.target), 0.03f * 0.02f, 1e-6f);
  // Moved by d (world), the row changes as s (I(pi(P + R^T d)) - I(pi(P))) to first order, and not
  // at all along the viewing ray.
  const float fx = sc.cam.fx, fy = sc.cam.fy;
  const vd_float4 dirs[4] = {VD_F4(1e-3f, 0.f, 0.f, 0.f), VD_F4(0.f, 1e-3f, 0.f, 0.f), VD_F4(0.f, 0.f, 1e-3f, 0.f),
                             VD_F4(-7e-4f, 4e-4f, 5e-4f, 0.f)};
  for (const vd_float4& d : dirs) {
    const VdPose& t = sc.prm.cam_to_world;
    // R^T d: the displacement in camera coordinates.
    const vd_float4 dc = VD_F4(t.r0.x * d.x + t.r1.x * d.y + t.r2.x * d.z, t.r0.y * d.x + t.r1.y * d.y + t.r2.y * d.z,
                               t.r0.z * d.x + t.r1.z * d.y + t.r2.z * d.z, 0.f);
    const vd_float4 q = p + dc;
    const float du = fx * q.x / q.z - fx * p.x / p.z, dv = fy * q.y / q.z - fy * p.y / p.z;
    const float expected = 0.03f * (0.01f * du + 0.005f * dv);
    EXPECT_NEAR(vd_dot3(c.normal, d), expected, 2e-7f) << d.x << " " << d.y << " " << d.z;
  }
  const vd_float4 ray = vd_pose_rotate(sc.prm.cam_to_world, p);
  EXPECT_NEAR(vd_dot3(c.normal, ray), 0.f, 1e-6f);
  // A bright spot far off the model's colour weighs linearly (Huber 0.1 at a residual of 0.5).
  sc.Ramp(0.5f, 0.01f, 0.005f);
  EXPECT_NEAR(sc.Rows()[sc.RowOf(i)].canonical.w, 3.2f * 0.1f / 0.5f, 1e-5f);
  // The cap: a row never weighs more than max_strength of a depth row, with the same zero.
  sc.prm.max_strength = 0.01f;
  sc.Ramp(0.02f, 0.01f, 0.005f);
  const VdCorrespondence capped = sc.Rows()[sc.RowOf(i)];
  ASSERT_GT(vd_length3(c.normal), 0.015f);
  EXPECT_NEAR(vd_length3(capped.normal), 0.01f, 1e-6f);
  EXPECT_NEAR(vd_dot3(capped.normal, s0 - capped.target) / vd_length3(capped.normal),
              vd_dot3(c.normal, s0 - c.target) / vd_length3(c.normal), 1e-6f);
}

TEST(CorrespondenceTest, ColourRowsNeedTextureSmoothDepthAndADepthRow) {
  ColourRowScene sc;
  const int i = 20 * sc.cam.width + 30;
  // No texture: no row anywhere.
  sc.Ramp(0.02f, 0.f, 0.f);
  for (const auto& c : sc.Rows()) EXPECT_FALSE(c.canonical.w > 0.f && c.normal.x != 0.f);
  // Texture: one pixel of each 2x2 block at least edge_radius from the border has one, and the
  // rows end after the blocks.
  sc.Ramp(0.02f, 0.01f, 0.f);
  auto rows = sc.Rows();
  int count = 0;
  const int blocks = vd_photo_rows(sc.cam.width, sc.cam.height);
  ASSERT_EQ(blocks, sc.n / 4);
  for (int b = 0; b < sc.n; ++b) {
    if (b >= blocks) {
      EXPECT_EQ(rows[sc.n + b].canonical.w, 0.f);
      continue;
    }
    const int k = vd_photo_pixel(b, sc.cam.width);
    ASSERT_EQ(sc.RowOf(k), sc.n + b);
    count += rows[sc.n + b].canonical.w > 0.f;
  }
  EXPECT_EQ(count, (64 - 8) * (48 - 8) / 4);
  // A depth edge 3 or 4 pixels to the right drops the row; 5 pixels away it does not.
  for (int gap : {3, 4, 5}) {
    sc.obs_v = sc.model.vertex;
    for (int k = 0; k < sc.n; ++k)
      if (k % sc.cam.width >= 30 + gap) sc.obs_v[k].z = 1.2f;
    EXPECT_EQ(sc.Rows()[sc.RowOf(i)].canonical.w > 0.f, gap > 4) << gap;
  }
  // A pixel without a depth row has no colour row.
  sc.obs_v = sc.model.vertex;
  std::vector<VdCorrespondence> none(2 * size_t(sc.n));
  cpu::PhotometricCorrespondences(sc.model, sc.obs_v.data(), sc.colors.data(), sc.tris.data(), sc.intensity.data(),
                                  sc.prm, none.data());
  for (const auto& c : none) EXPECT_EQ(c.canonical.w, 0.f);
}

TEST(CorrespondenceParityTest, SphereAgainstAShiftedObservationMatchesCpu) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  const VdCamera cam = test::TestCamera(160, 120);
  const int n = cam.width * cam.height;
  // Model: marching cubes of an analytic sphere, as canonical grid positions and world positions.
  const test::AnalyticVolume sphere = test::MakeSphereVolume(
      test::TestVolume(48, 48, 48, 0.01f, VD_F4(-0.24f, -0.24f, 0.76f, 1.f)), 0.f, 0.f, 1.f, 0.2f);
  const VdVolume& vol = sphere.vol;
  cpu::McMesh mc = cpu::MarchingCubes(sphere.tsdf.data(), sphere.weight.data(), sphere.color.data(), vol);
  std::vector<vd_float4> world(mc.positions_grid.size());
  for (size_t i = 0; i < world.size(); ++i)
    world[i] = VD_F4(vol.origin.x + 0.01f * mc.positions_grid[i].x, vol.origin.y + 0.01f * mc.positions_grid[i].y,
                     vol.origin.z + 0.01f * mc.positions_grid[i].z, 1.f);
  cpu::RasterMaps model;
  cpu::Rasterize(world.data(), mc.normals.data(), mc.triangles.data(), int(mc.triangles.size() / 3),
                 test::IdentityPose(), cam, &model);
  // Observation: the same sphere 5 mm closer.
  const auto depth = test::SphereDepth(cam, 0.995f, 0.2f, 100.f);
  std::vector<float> d2(depth);
  for (float& d : d2)
    if (d > 50.f) d = 0.f;
  std::vector<vd_float4> ov(n), on(n);
  cpu::VertexMap(d2.data(), ov.data(), cam);
  cpu::NormalMap(ov.data(), on.data(), cam.width, cam.height, 0.05f);
  const VdCorrParams prm = Params();
  std::vector<VdCorrespondence> ref(n);
  cpu::Correspondences(model, ov.data(), on.data(), mc.positions_grid.data(), mc.triangles.data(), prm, n, ref.data());

  int valid = 0;
  double mean_w = 0;
  for (const auto& c : ref) {
    if (c.canonical.w <= 0.f) continue;
    ++valid;
    mean_w += c.canonical.w;
    // The canonical point lies on the model sphere (grid units -> metres).
    const float x = vol.origin.x + 0.01f * c.canonical.x, y = vol.origin.y + 0.01f * c.canonical.y,
                z = vol.origin.z + 0.01f * c.canonical.z;
    ASSERT_NEAR(std::sqrt(x * x + y * y + (z - 1.f) * (z - 1.f)), 0.2f, 0.002f);
    ASSERT_LE(c.canonical.w, 1.f);
  }
  // The sphere covers ~2060 pixels (radius ~25.6 px); silhouette pixels are pruned by the view term.
  EXPECT_GT(valid, 1600);
  // 5 mm apart with eps_d = 2 cm: Phi_d ~ 0.75 in the centre, so w ~ 0.84 at best.
  EXPECT_LT(mean_w / valid, 0.9);
  EXPECT_GT(mean_w / valid, 0.4);

  DeviceMesh dm;
  dm.positions_grid = test::ToDevice(ctx, mc.positions_grid);
  dm.triangles = test::ToDevice(ctx, mc.triangles);
  dm.num_vertices = mc.positions_grid.size();
  dm.num_triangles = mc.triangles.size() / 3;
  DeviceRaster dr;
  dr.cam = cam;
  dr.vertex = test::ToDevice(ctx, model.vertex);
  dr.normal = test::ToDevice(ctx, model.normal);
  dr.ids = test::ToDevice(ctx, model.ids);
  dr.bary = test::ToDevice(ctx, model.bary);
  auto dov = test::ToDevice(ctx, ov), don = test::ToDevice(ctx, on);
  auto out = ctx->Alloc<VdCorrespondence>(n);
  ASSERT_TRUE(out.ok());
  ASSERT_TRUE(ops.Correspondences(dr, dov, don, dm, prm, *out).ok());
  const auto dev = test::FromDevice(ctx, *out, n);
  auto flatten = [](const std::vector<VdCorrespondence>& v) {
    std::vector<float> f;
    for (const auto& c : v)
      f.insert(f.end(), {c.canonical.x, c.canonical.y, c.canonical.z, c.canonical.w, c.target.x, c.target.y, c.target.z,
                         c.target.w, c.normal.x, c.normal.y, c.normal.z, c.normal.w});
    return f;
  };
  EXPECT_TRUE(test::AllClose(flatten(dev), flatten(ref), 1e-5f, 1e-5f));

  // The colour rows on the same pixels: a striped image against the model's (uniform) colour.
  std::vector<uint32_t> rgba(n);
  for (int k = 0; k < n; ++k) {
    const int g = int(127.5f + 120.f * std::sin(0.7f * float(k % cam.width)) * std::cos(0.45f * float(k / cam.width)));
    rgba[k] = Rgba(g, 255 - g, g / 2);
  }
  std::vector<float> intensity(n / 4);
  cpu::Intensity(rgba.data(), intensity.data(), cam.width, cam.height);
  const VdPhotoParams pp = PhotoParams(prm.cam_to_world, cam, 0.5f);
  std::vector<VdCorrespondence> rows(2 * size_t(n));
  std::copy(ref.begin(), ref.end(), rows.begin());
  cpu::PhotometricCorrespondences(model, ov.data(), mc.colors.data(), mc.triangles.data(), intensity.data(), pp,
                                  rows.data());
  int colour_rows = 0;
  const int blocks = vd_photo_rows(cam.width, cam.height);
  for (int b = 0; b < blocks; ++b) {
    if (!(rows[n + b].canonical.w > 0.f)) continue;
    ++colour_rows;
    // One pixel of each 2x2 block, from that pixel's depth row; only the coarse levels solve it, a
    // depth row is the fine level's.
    const int k = vd_photo_pixel(b, cam.width);
    ASSERT_EQ((k % cam.width) % 2 + (k / cam.width) % 2, 0) << k;
    ASSERT_EQ(rows[n + b].canonical.x, rows[k].canonical.x) << b;
    ASSERT_EQ(rows[n + b].normal.w, VD_CORR_COARSE_ONLY) << b;
    ASSERT_FALSE(vd_fine_row(rows[n + b])) << b;
    ASSERT_TRUE(vd_fine_row(rows[k])) << k;
  }
  for (size_t r = size_t(n) + blocks; r < rows.size(); ++r) ASSERT_EQ(rows[r].canonical.w, 0.f) << r;
  // Most of the sphere's inner pixels (those 4 px inside its outline) have texture; one in four of
  // them gets a row.
  EXPECT_GT(colour_rows, 250) << colour_rows;
  EXPECT_LT(colour_rows, valid / 4) << colour_rows;
  dm.colors = test::ToDevice(ctx, mc.colors);
  auto drgba = test::ToDevice(ctx, rgba);
  auto tmp = ctx->Alloc<float>(n / 4), dint = ctx->Alloc<float>(n / 4);
  auto drows = ctx->Alloc<VdCorrespondence>(2 * size_t(n));
  ASSERT_TRUE(tmp.ok() && dint.ok() && drows.ok());
  ASSERT_TRUE(ops.Intensity(drgba, *tmp, *dint, cam.width, cam.height).ok());
  ASSERT_TRUE(ops.Correspondences(dr, dov, don, dm, prm, *drows).ok());
  ASSERT_TRUE(ops.PhotometricCorrespondences(dr, dov, dm, *dint, pp, *drows).ok());
  const size_t used = size_t(n) + blocks;
  rows.resize(used);
  EXPECT_TRUE(test::AllClose(flatten(test::FromDevice(ctx, *drows, used)), flatten(rows), 1e-5f, 1e-5f));
  // A buffer without room for the colour rows is refused, not overrun.
  EXPECT_FALSE(ops.PhotometricCorrespondences(dr, dov, dm, *dint, pp, *out).ok());

  // A mesh without owning bricks gives no hints; a mesh over the bricks (DeviceMesh::brick_slots)
  // gives each row its triangle's first vertex's owner, and each colour row its depth row's.
  for (const VdCorrespondence& c : rows) ASSERT_EQ(c.target.w, -1.f);
  std::vector<int32_t> owners(mc.positions_grid.size());
  for (size_t v = 0; v < owners.size(); ++v) owners[v] = int32_t((v * 7) % 1009);
  dm.brick_slots = test::ToDevice(ctx, owners);
  dm.num_brick_slots = owners.size();
  std::vector<VdCorrespondence> hinted(2 * size_t(n));
  cpu::Correspondences(model, ov.data(), on.data(), mc.positions_grid.data(), mc.triangles.data(), prm, n,
                       hinted.data(), owners.data());
  cpu::PhotometricCorrespondences(model, ov.data(), mc.colors.data(), mc.triangles.data(), intensity.data(), pp,
                                  hinted.data());
  int checked = 0;
  for (int k = 0; k < n; ++k) {
    if (!(hinted[k].canonical.w > 0.f)) continue;
    ASSERT_EQ(hinted[k].target.w, float(owners[mc.triangles[3 * model.ids[k]]])) << k;
    const int b = (k / cam.width / 2) * ((cam.width + 1) / 2) + (k % cam.width) / 2;
    if (vd_photo_pixel(b, cam.width) == k && hinted[n + b].canonical.w > 0.f) {
      ASSERT_EQ(hinted[n + b].target.w, hinted[k].target.w) << k;
    }
    ++checked;
  }
  EXPECT_EQ(checked, valid);
  ASSERT_TRUE(ops.Correspondences(dr, dov, don, dm, prm, *drows).ok());
  ASSERT_TRUE(ops.PhotometricCorrespondences(dr, dov, dm, *dint, pp, *drows).ok());
  hinted.resize(used);
  EXPECT_TRUE(test::AllClose(flatten(test::FromDevice(ctx, *drows, used)), flatten(hinted), 1e-5f, 1e-5f));
}

}  // namespace
}  // namespace vd
