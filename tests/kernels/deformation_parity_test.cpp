#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <random>

#include "cpu_ref/cpu_ref.h"
#include "ocl/device_ops.h"
#include "shared/deformation.h"
#include "sphere_volume.h"
#include "device_ops_test.h"
#include "test_scenes.h"

namespace vd {
namespace {

VdVolume SmallVolume() { return test::TestVolume(20, 16, 12, 0.01f, VD_F4(-0.1f, -0.08f, 0.5f, 1.f)); }

// SmallVolume's field at rest (host copies): rest positions, identity rotations.
struct RestField {
  VdVolume vol = SmallVolume();
  size_t n = size_t(vol.dim_x) * vol.dim_y * vol.dim_z;
  std::vector<vd_float4> pos = std::vector<vd_float4>(n), rot = std::vector<vd_float4>(n);
  RestField() { cpu::DeformationReset(pos.data(), rot.data(), vol); }
};

TEST(DeformationParityTest, ResetGivesRestPositionsAndIdentityRotations) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  const VdVolume vol = SmallVolume();
  DeviceVolume dv;
  ASSERT_TRUE(ops.AllocVolume(vol, true, &dv).ok());
  const size_t n = dv.num_voxels();
  std::vector<vd_float4> pos(n), rot(n);
  cpu::DeformationReset(pos.data(), rot.data(), vol);
  EXPECT_EQ(test::Flatten(test::FromDevice(ctx, dv.def_pos, n)), test::Flatten(pos));
  EXPECT_EQ(test::Flatten(test::FromDevice(ctx, dv.def_rot, n)), test::Flatten(rot));
  // Grid point (3, 2, 1) sits at origin + voxel * (3, 2, 1) with no optimisations yet.
  const auto& p = pos[3 + vol.dim_x * (2 + vol.dim_y * 1)];
  EXPECT_FLOAT_EQ(p.x, -0.07f);
  EXPECT_FLOAT_EQ(p.y, -0.06f);
  EXPECT_FLOAT_EQ(p.z, 0.51f);
  EXPECT_EQ(p.w, 0.f);
  EXPECT_EQ(rot[17].w, 1.f);
}

TEST(DeformationParityTest, DeformVerticesIsTrilinearAndMatchesCpu) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  RestField field;
  auto& [vol, n, pos, rot] = field;
  // An affine field t_i = A t^_i + b: trilinear interpolation reproduces it exactly.
  auto affine = [](vd_float4 p) {
    return VD_F4(1.1f * p.x + 0.2f * p.y + 0.01f, -0.1f * p.x + 0.9f * p.y + 0.3f * p.z, p.z + 0.05f * p.x - 0.02f, 0.f);
  };
  for (auto& p : pos) p = affine(p);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> ux(0.f, vol.dim_x - 1.f), uy(0.f, vol.dim_y - 1.f), uz(0.f, vol.dim_z - 1.f);
  std::vector<vd_float4> grid(5000);
  for (auto& g : grid) g = VD_F4(ux(rng), uy(rng), uz(rng), 1.f);
  grid[0] = VD_F4(vol.dim_x - 1.f, vol.dim_y - 1.f, vol.dim_z - 1.f, 1.f);  // The far corner.
  std::vector<vd_float4> ref(grid.size());
  cpu::DeformVertices(grid.data(), int(grid.size()), pos.data(), vol, ref.data());
  for (size_t i = 0; i < grid.size(); ++i) {
    const vd_float4 rest = VD_F4(vol.origin.x + vol.voxel_size * grid[i].x, vol.origin.y + vol.voxel_size * grid[i].y,
                                 vol.origin.z + vol.voxel_size * grid[i].z, 0.f);
    const vd_float4 want = affine(rest);
    ASSERT_NEAR(ref[i].x, want.x, 1e-5f);
    ASSERT_NEAR(ref[i].y, want.y, 1e-5f);
    ASSERT_NEAR(ref[i].z, want.z, 1e-5f);
  }
  DeviceVolume dv;
  ASSERT_TRUE(ops.AllocVolume(vol, true, &dv).ok());
  ASSERT_TRUE(ctx->Upload(dv.def_pos, pos.data(), n).ok());
  DeviceMesh m;
  m.positions_grid = test::ToDevice(ctx, grid);
  auto out = ctx->Alloc<vd_float4>(grid.size());
  ASSERT_TRUE(out.ok());
  m.positions = std::move(out).value();
  m.num_vertices = grid.size();
  ASSERT_TRUE(ops.DeformVertices(dv, &m).ok());
  EXPECT_TRUE(test::AllClose(test::Flatten(test::FromDevice(ctx, m.positions, grid.size())), test::Flatten(ref), 1e-6f, 1e-6f));
}

// New members of the active set start where their optimised neighbours put them as rigid pieces:
// under one rigid motion of the optimised half of the grid (a 75-degree turn, as at the ends of the
// long bend), every extrapolated point lands exactly on that motion of its rest position (moving it
// by the neighbours' mean displacement alone missed by 1.5 voxels). Device against CPU.
TEST(DeformationParityTest, ExtrapolationFollowsTheNeighboursRotationAndMatchesCpu) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  RestField field;
  auto& [vol, n, pos, rot] = field;
  const Eigen::Vector3f axis = Eigen::Vector3f(0.3f, 1.f, -0.2f).normalized();
  const Eigen::AngleAxisf turn(75.f * float(M_PI) / 180.f, axis);
  const Eigen::Quaternionf q(turn);
  const Eigen::Vector3f shift(0.02f, -0.01f, 0.03f);
  auto moved = [&](int i) {
    const Eigen::Vector3f r = turn * Eigen::Vector3f(pos[i].x, pos[i].y, pos[i].z) + shift;
    return r;
  };
  // Optimised (w = 3): x < 9. The layer x = 9 enters the active set now; x = 10 has no optimised
  // neighbour and stays as it is.
  std::vector<int> list;
  std::vector<Eigen::Vector3f> want(n);
  for (int z = 0; z < vol.dim_z; ++z)
    for (int y = 0; y < vol.dim_y; ++y)
      for (int x = 0; x <= 10; ++x) {
        const int i = x + vol.dim_x * (y + vol.dim_y * z);
        want[i] = moved(i);
        if (x < 9) {
          pos[i] = VD_F4(want[i].x(), want[i].y(), want[i].z(), 3.f);
          rot[i] = VD_F4(q.x(), q.y(), q.z(), q.w());
        } else {
          list.push_back(i);
        }
      }
  std::vector<vd_float4> pos_ref = pos, rot_ref = rot;
  cpu::Extrapolate(list.data(), int(list.size()), pos_ref.data(), rot_ref.data(), vol);
  double worst = 0;
  for (int i : list) {
    const int x = i % vol.dim_x;
    const Eigen::Vector3f got(pos_ref[i].x, pos_ref[i].y, pos_ref[i].z);
    if (x == 9) {
      worst = std::max(worst, double((got - want[i]).norm()));
      EXPECT_EQ(pos_ref[i].w, 0.f);
      EXPECT_NEAR(std::abs(rot_ref[i].w), std::abs(q.w()), 1e-6f);
    } else {
      EXPECT_EQ(pos_ref[i].x, pos[i].x);  // no optimised neighbour: kept
      EXPECT_EQ(pos_ref[i].w, 0.f);
    }
  }
  std::printf("worst extrapolated point %.3g m from the rigid motion (voxel %.3g m)\n", worst, vol.voxel_size);
  EXPECT_LT(worst, 1e-5);

  DeviceVolume dv;
  ASSERT_TRUE(ops.AllocVolume(vol, true, &dv).ok());
  ASSERT_TRUE(ctx->Upload(dv.def_pos, pos.data(), n).ok());
  ASSERT_TRUE(ctx->Upload(dv.def_rot, rot.data(), n).ok());
  DeviceActiveSet active;
  active.list = test::ToDevice(ctx, list);
  active.count = list.size();
  ASSERT_TRUE(ops.Extrapolate(dv, active).ok());
  EXPECT_TRUE(
      test::AllClose(test::Flatten(test::FromDevice(ctx, dv.def_pos, n)), test::Flatten(pos_ref), 1e-6f, 1e-6f));
  EXPECT_TRUE(test::AllClose(test::Flatten(test::FromDevice(ctx, dv.def_rot, n)), test::Flatten(rot_ref), 0.f, 0.f));
}

// M's surface on a sphere (radius 8 voxels in a 32 x 30 x 28 grid): the CPU's mesh, M, M's surface
// points (the solver's) and their flags, and a device grid holding the same sphere, meshed.
class SurfacePointsParityTest : public test::DeviceOpsTest {
 protected:
  void SetUp() override {
    test::DeviceOpsTest::SetUp();
    if (IsSkipped() || HasFatalFailure()) return;
    ASSERT_TRUE(ops_->AllocVolume(vol_, true, &dv_).ok());
    ASSERT_TRUE(ctx_->Upload(dv_.tsdf, sphere_.tsdf.data(), n_).ok());
    ASSERT_TRUE(ctx_->Upload(dv_.weight, sphere_.weight.data(), n_).ok());
    ASSERT_TRUE(ops_->MarkTouched(dv_).ok());
    ASSERT_TRUE(ops_->MarchingCubes(dv_, &dm_).ok());
    for (int i : solved_.list) surface_[i] = 1;
  }
  const test::AnalyticVolume sphere_ = test::MakeSphereVolume(
      test::TestVolume(32, 30, 28, 0.01f, VD_F4(-0.1f, -0.1f, 0.5f, 1.f)), 0.06f, 0.05f, 0.64f, 0.08f);
  const VdVolume& vol_ = sphere_.vol;
  const size_t n_ = sphere_.tsdf.size();
  const cpu::McMesh mesh_ =
      cpu::MarchingCubes(sphere_.tsdf.data(), sphere_.weight.data(), sphere_.color.data(), sphere_.vol);
  cpu::ActiveSet solved_;
  const cpu::ActiveSet m_ = cpu::BuildActiveSet(mesh_.codes.data(), vol_, &solved_);
  std::vector<uint8_t> surface_ = std::vector<uint8_t>(n_, 0);
  DeviceVolume dv_;
  DeviceMesh dm_;
};

// A solve limited to the view (EngineParams::solve_view_margin) takes the surface points whose field
// position is in it, as the CPU does: on a sphere half out of the image, about half of them.
TEST_F(SurfacePointsParityTest, ASolveLimitedToTheViewTakesTheSurfacePointsInItAndMatchesCpu) {
  std::vector<vd_float4> pos(n_), rot(n_);
  cpu::DeformationReset(pos.data(), rot.data(), vol_);
  // The sphere's centre projects to u = 161 of 160 columns: its right half is out of view.
  SolveView view;
  view.cam.fx = view.cam.fy = 200.f;
  view.cam.cx = 80.f;
  view.cam.cy = 60.f;
  view.cam.width = 160;
  view.cam.height = 120;
  view.world_to_cam.r0 = VD_F4(1.f, 0.f, 0.f, 0.2f);
  view.world_to_cam.r1 = VD_F4(0.f, 1.f, 0.f, 0.f);
  view.world_to_cam.r2 = VD_F4(0.f, 0.f, 1.f, 0.f);
  view.margin = 0.02f;
  const std::vector<uint8_t> in_view =
      cpu::ActiveInView(surface_, pos.data(), vol_.dim_x, view.cam, view.world_to_cam, view.margin);
  std::vector<int32_t> want;
  for (size_t i = 0; i < n_; ++i)
    if (in_view[i]) want.push_back(int32_t(i));
  std::printf("%zu of %zu surface points in view\n", want.size(), solved_.list.size());
  ASSERT_GT(want.size(), solved_.list.size() / 4);
  ASSERT_LT(want.size(), solved_.list.size() * 3 / 4);

  ASSERT_TRUE(ctx_->Upload(dv_.def_pos, pos.data(), n_).ok());
  DeviceActiveSet active, solved;
  ASSERT_TRUE(ops_->BuildActiveSet(dv_, &active, &solved, &view).ok());
  ASSERT_EQ(solved.count, want.size());
  EXPECT_EQ(test::FromDevice(ctx_, solved.list, solved.count), want);
  // M itself does not change with the view.
  ASSERT_TRUE(ops_->BuildActiveSet(dv_, &active, &solved).ok());
  EXPECT_EQ(solved.count, solved_.list.size());
}

// After a solve over M's surface points, the ring follows them: under a rigid motion of the solved
// points every ring point lands on that motion and counts the solve; the solved points are not
// touched; device against CPU on a sphere's real active set.
TEST_F(SurfacePointsParityTest, RingPointsFollowTheSolvedSurfaceAndMatchCpu) {
  ASSERT_GT(m_.list.size(), solved_.list.size() + 500);
  const Eigen::AngleAxisf turn(60.f * float(M_PI) / 180.f, Eigen::Vector3f(0.5f, -1.f, 0.3f).normalized());
  const Eigen::Quaternionf q(turn);
  const Eigen::Vector3f shift(0.01f, 0.03f, -0.02f);
  std::vector<vd_float4> pos(n_), rot(n_);
  cpu::DeformationReset(pos.data(), rot.data(), vol_);
  std::vector<Eigen::Vector3f> want(n_);
  for (int i : m_.list) {
    want[i] = turn * Eigen::Vector3f(pos[i].x, pos[i].y, pos[i].z) + shift;
    if (surface_[i]) {  // solved: on the motion, 5 solves
      pos[i] = VD_F4(want[i].x(), want[i].y(), want[i].z(), 5.f);
      rot[i] = VD_F4(q.x(), q.y(), q.z(), q.w());
    } else {  // ring: stale (at rest), 2 solves
      pos[i].w = 2.f;
    }
  }
  std::vector<vd_float4> pos_ref = pos, rot_ref = rot;
  cpu::Follow(m_.list.data(), int(m_.list.size()), surface_.data(), pos_ref.data(), rot_ref.data(), vol_);
  double worst = 0;
  for (int i : m_.list) {
    const Eigen::Vector3f got(pos_ref[i].x, pos_ref[i].y, pos_ref[i].z);
    if (surface_[i]) {
      ASSERT_EQ(pos_ref[i].x, pos[i].x);
      ASSERT_EQ(pos_ref[i].w, 5.f);
      continue;
    }
    worst = std::max(worst, double((got - want[i]).norm()));
    EXPECT_EQ(pos_ref[i].w, 3.f);
    EXPECT_NEAR(std::abs(rot_ref[i].w), std::abs(q.w()), 1e-6f);
  }
  std::printf("worst ring point %.3g m from the rigid motion (voxel %.3g m)\n", worst, vol_.voxel_size);
  EXPECT_LT(worst, 1e-5);

  // The device: the same M and surface from its own build, then Follow.
  DeviceActiveSet active, solved_dev;
  ASSERT_TRUE(ops_->BuildActiveSet(dv_, &active, &solved_dev).ok());
  ASSERT_EQ(active.count, m_.list.size());
  ASSERT_TRUE(ctx_->Upload(dv_.def_pos, pos.data(), n_).ok());
  ASSERT_TRUE(ctx_->Upload(dv_.def_rot, rot.data(), n_).ok());
  ASSERT_TRUE(ops_->Follow(dv_, active).ok());
  EXPECT_TRUE(
      test::AllClose(test::Flatten(test::FromDevice(ctx_, dv_.def_pos, n_)), test::Flatten(pos_ref), 1e-6f, 1e-6f));
  EXPECT_TRUE(
      test::AllClose(test::Flatten(test::FromDevice(ctx_, dv_.def_rot, n_)), test::Flatten(rot_ref), 0.f, 0.f));
}

// Moving a rigid motion out of the field: every optimised point takes t' = A t and R' = q_A R,
// points never optimised keep their rest state; device against CPU.
TEST(DeformationParityTest, FieldRigidMovesOptimisedPointsAndMatchesCpu) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  RestField field;
  auto& [vol, n, pos, rot] = field;
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  for (size_t i = 0; i < n; i += 3) {
    pos[i] = pos[i] + VD_F4(0.01f * u(rng), 0.01f * u(rng), 0.01f * u(rng), 0.f);
    pos[i].w = float(1 + i % 5);
    const Eigen::Quaternionf r =
        Eigen::Quaternionf(Eigen::AngleAxisf(0.3f * u(rng), Eigen::Vector3f(u(rng), u(rng), 1.f).normalized()));
    rot[i] = VD_F4(r.x(), r.y(), r.z(), r.w());
  }
  const Eigen::AngleAxisf turn(0.1f, Eigen::Vector3f(1.f, -0.5f, 0.2f).normalized());
  const Eigen::Quaternionf qa(turn);
  const Eigen::Matrix3f ra = turn.toRotationMatrix();
  const Eigen::Vector3f ta(0.01f, 0.02f, -0.03f);
  VdPose a;
  a.r0 = VD_F4(ra(0, 0), ra(0, 1), ra(0, 2), ta.x());
  a.r1 = VD_F4(ra(1, 0), ra(1, 1), ra(1, 2), ta.y());
  a.r2 = VD_F4(ra(2, 0), ra(2, 1), ra(2, 2), ta.z());
  const vd_float4 q = VD_F4(qa.x(), qa.y(), qa.z(), qa.w());
  std::vector<vd_float4> pos_ref = pos, rot_ref = rot;
  cpu::TransformField(pos_ref.data(), rot_ref.data(), int(n), a, q);
  for (size_t i = 0; i < n; ++i) {
    if (i % 3) {
      ASSERT_EQ(pos_ref[i].x, pos[i].x) << i;
      ASSERT_EQ(rot_ref[i].w, rot[i].w) << i;
      continue;
    }
    const Eigen::Vector3f want = ra * Eigen::Vector3f(pos[i].x, pos[i].y, pos[i].z) + ta;
    ASSERT_NEAR(pos_ref[i].x, want.x(), 1e-6f);
    ASSERT_NEAR(pos_ref[i].y, want.y(), 1e-6f);
    ASSERT_NEAR(pos_ref[i].z, want.z(), 1e-6f);
    ASSERT_EQ(pos_ref[i].w, pos[i].w);
    const Eigen::Quaternionf got(rot_ref[i].w, rot_ref[i].x, rot_ref[i].y, rot_ref[i].z);
    const Eigen::Quaternionf composed = qa * Eigen::Quaternionf(rot[i].w, rot[i].x, rot[i].y, rot[i].z);
    ASSERT_NEAR(std::abs(got.dot(composed)), 1.f, 1e-6f) << i;
  }
  DeviceVolume dv;
  ASSERT_TRUE(ops.AllocVolume(vol, true, &dv).ok());
  ASSERT_TRUE(ctx->Upload(dv.def_pos, pos.data(), n).ok());
  ASSERT_TRUE(ctx->Upload(dv.def_rot, rot.data(), n).ok());
  ASSERT_TRUE(ops.TransformField(dv, a, q).ok());
  EXPECT_TRUE(
      test::AllClose(test::Flatten(test::FromDevice(ctx, dv.def_pos, n)), test::Flatten(pos_ref), 1e-6f, 1e-6f));
  EXPECT_TRUE(
      test::AllClose(test::Flatten(test::FromDevice(ctx, dv.def_rot, n)), test::Flatten(rot_ref), 1e-6f, 1e-6f));
}

}  // namespace
}  // namespace vd
