// The non-rigid solver on the brick pool (shared/lattice.h; docs/SPARSE_VOLUME.md "The solver on a
// lattice"): the bricks its coarse levels need against the CPU, the levels and their restriction
// against the CPU on the bricks, and the whole hierarchical solve against the dense grid's over the
// same lattice, point for point.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>

#include "brick_scene.h"
#include "core/hierarchy.h"
#include "cpu_ref/brick_hash_ref.h"
#include "cpu_ref/cpu_ref.h"
#include "cpu_ref/features_ref.h"
#include "ocl/features_ocl.h"
#include "ocl/hierarchy_ocl.h"
#include "shared/active_set.h"
#include "device_ops_test.h"
#include "test_scenes.h"

namespace vd {
namespace {

using test::FromDevice;
using test::ToDevice;
using Coords = std::array<int, 3>;

std::set<uint32_t> KeysOf(const std::vector<uint32_t>& keys) {
  std::set<uint32_t> out;
  for (uint32_t k : keys)
    if (k != VD_BRICK_EMPTY) out.insert(k);
  return out;
}

// The sphere's bricks with the one-ring and the coarse corners allocated, the field at rest, the
// active set over them, and the dense grid over the same lattice (its origin a multiple of 8
// voxels, so that the coarse levels' points coincide).
class SparseSolverParityTest : public test::DeviceOpsTest {
 protected:
  void SetUp() override {
    test::DeviceOpsTest::SetUp();
    if (IsSkipped() || HasFatalFailure()) return;
    test::FuseSphere(ctx_, 2, &f_, /*with_field=*/true);
    if (HasFatalFailure()) return;
    ASSERT_TRUE(ops_->MarchingCubes(*f_.table, *f_.pool, &mesh_).ok());
    ASSERT_TRUE(ops_->BuildActiveSet(*f_.table, &active_).ok());
    auto ring = ops_->AllocateActiveRing(*f_.table);
    ASSERT_TRUE(ring.ok()) << ring.status().ToString();
    Refresh();
    before_corners_ = f_.Reference(ctx_);
    used_before_corners_ = f_.counts.used;
    auto corners = f_.table->AllocateLevelCorners(*ctx_, active_, kCoarsest);
    ASSERT_TRUE(corners.ok()) << corners.status().ToString();
    corners_added_ = *corners;
    Refresh();
    std::printf("bricks: %u with the one-ring, %u after the coarse corners; %zu active points\n", used_before_corners_,
                f_.counts.used, size_t(active_.count));
  }

  // After allocations: the counts, the new slots' field at rest, the mesh and the active set again
  // (its map then covers the new slots).
  void Refresh() {
    const uint32_t old_used = f_.counts.used;
    auto counts = f_.table->Counts(*ctx_);
    ASSERT_TRUE(counts.ok());
    f_.counts = *counts;
    ASSERT_TRUE(f_.pool->RestField(*ctx_, *f_.table, old_used, f_.counts.used - old_used, f_.vol.voxel_size).ok());
    ASSERT_TRUE(ops_->MarchingCubes(*f_.table, *f_.pool, &mesh_).ok());
    ASSERT_TRUE(ops_->BuildActiveSet(*f_.table, &active_).ok());
  }

  // Global grid coordinates of pool entry e.
  Coords GlobalOf(const cpu::BrickTable& ref, int32_t e) const {
    Coords g;
    vd_brick_voxel(ref.slot_keys[e / VD_BRICK_VOXELS], e % VD_BRICK_VOXELS, &g[0], &g[1], &g[2]);
    return g;
  }

  static constexpr int kCoarsest = 4;  // three levels: spacings 1, 2, 4
  test::FusedBricks f_;
  DeviceMesh mesh_;
  DeviceActiveSet active_;
  cpu::BrickTable before_corners_{1, 1};
  uint32_t used_before_corners_ = 0, corners_added_ = 0;
};

// The bricks the coarse levels need: the same keys as the CPU's, and afterwards every fine point's
// coarse corners exist at spacings 2 and 4.
TEST_F(SparseSolverParityTest, CoarseCornerBricksMatchTheCpu) {
  const std::vector<int32_t> list = FromDevice(ctx_, active_.list, active_.count);
  cpu::BrickTable ref = before_corners_;
  cpu::BrickLevelAllocate(list.data(), list.size(), kCoarsest, used_before_corners_, &ref);
  const cpu::BrickTable got = f_.Reference(ctx_);
  EXPECT_EQ(KeysOf(got.keys), KeysOf(ref.keys));
  EXPECT_GT(corners_added_, 0u);
  EXPECT_EQ(ref.counters[VD_BRICK_COUNT_FAILED], 0u);
  const std::vector<int32_t> nbr = cpu::BrickNeighbours(got, f_.counts.used);
  const VdLattice fine = vd_lattice_bricks(f_.vol.voxel_size, 1);
  for (int s : {2, 4}) {
    const VdLattice coarse = vd_lattice_level(fine, s);
    size_t missing = 0;
    for (int32_t e : list) {
      int slot, x, y, z;
      vd_lattice_point(fine, e, &slot, &x, &y, &z);
      for (int o = 0; o < 8; ++o) missing += vd_level_corner(coarse, nbr.data(), s, slot, x, y, z, o) < 0;
    }
    EXPECT_EQ(missing, 0u) << "s = " << s;
  }
  // Asking again adds nothing.
  auto again = f_.table->AllocateLevelCorners(*ctx_, active_, kCoarsest);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(*again, 0u);
  EXPECT_FALSE(f_.table->AllocateLevelCorners(*ctx_, active_, 3).ok()) << "3 does not divide a brick";
}

// The whole hierarchical solve (3 levels, cached B^T B) on the bricks and on the dense grid with the
// same active points and constraints: the coarse levels hold the same points, and every solved
// position agrees to float rounding. The levels and the restriction on the bricks also match the CPU.
TEST_F(SparseSolverParityTest, HierarchicalSolveOnBricksMatchesTheDenseGrid) {
  ocl::Context* ctx = ctx_;
  DeviceOps& ops = *ops_;
  const cpu::BrickTable ref = f_.Reference(ctx);
  const uint32_t used = f_.counts.used;
  const size_t m = active_.count;
  const std::vector<int32_t> list_b = FromDevice(ctx, active_.list, m);

  // The dense grid over the same lattice and the same members.
  std::vector<float> dt, dw;
  std::vector<uint32_t> dc;
  int lo[3];
  const VdVolume dense = f_.DenseOver(ref, 2, &dt, &dw, &dc, lo, /*align=*/8);
  DeviceVolume dv;
  ASSERT_TRUE(ops.AllocVolume(dense, true, &dv).ok());
  ASSERT_TRUE(ctx->Upload(dv.tsdf, dt.data(), dt.size()).ok());
  ASSERT_TRUE(ctx->Upload(dv.weight, dw.data(), dw.size()).ok());
  ASSERT_TRUE(ctx->Upload(dv.color, dc.data(), dc.size()).ok());
  const size_t nd = dt.size();
  std::vector<int32_t> dense_of(m);
  for (size_t k = 0; k < m; ++k) {
    const Coords g = GlobalOf(ref, list_b[k]);
    ASSERT_TRUE(g[0] >= lo[0] && g[1] >= lo[1] && g[2] >= lo[2] && g[0] - lo[0] < dense.dim_x &&
                g[1] - lo[1] < dense.dim_y && g[2] - lo[2] < dense.dim_z);
    dense_of[k] = vd_grid_index(dense, g[0] - lo[0], g[1] - lo[1], g[2] - lo[2]);
  }
  cpu::ActiveSet da;
  da.list = dense_of;
  std::sort(da.list.begin(), da.list.end());
  da.compact.assign(nd, -1);
  for (size_t k = 0; k < m; ++k) da.compact[da.list[k]] = int32_t(k);
  da.neighbours.resize(6 * m);
  for (size_t k = 0; k < m; ++k) {
    int x, y, z;
    vd_grid_coords(da.list[k], dense, &x, &y, &z);
    vd_active_neighbours_of(da.compact.data(), dense, x, y, z, &da.neighbours[6 * k]);
  }
  // The same graph: every member's six neighbours are the same points on both.
  const std::vector<int32_t> nb_b = FromDevice(ctx, active_.neighbours, 6 * m);
  for (size_t k = 0; k < m; ++k)
    for (int j = 0; j < 6; ++j) {
      const int32_t b = nb_b[6 * k + j], d = da.neighbours[6 * size_t(da.compact[dense_of[k]]) + j];
      ASSERT_EQ(b < 0, d < 0) << k << " " << j;
      if (b >= 0) ASSERT_EQ(dense_of[size_t(b)], da.list[size_t(d)]);
    }
  DeviceActiveSet dact;
  dact.count = m;
  dact.list = ToDevice(ctx, da.list);
  dact.compact = ToDevice(ctx, da.compact);
  dact.neighbours = ToDevice(ctx, da.neighbours);

  // Constraints at the mesh's vertices, targets off the surface along the normal, every seventh
  // pruned; the dense grid's in its own grid coordinates.
  const size_t nv = mesh_.num_vertices;
  const std::vector<vd_float4> pos = FromDevice(ctx, mesh_.positions_grid, nv),
                               nrm = FromDevice(ctx, mesh_.normals, nv);
  std::vector<VdCorrespondence> cons_b, cons_d;
  const float h = f_.vol.voxel_size;
  for (size_t i = 0; i < nv; ++i) {
    VdCorrespondence c{};
    c.canonical = pos[i];
    c.canonical.w = i % 7 == 0 ? 0.f : 0.3f + 0.1f * float(i % 5);
    c.normal = nrm[i];
    c.normal.w = 0.f;
    c.target =
        VD_F4(h * pos[i].x, h * pos[i].y, h * pos[i].z, 0.f) + c.normal * (0.004f + 0.002f * std::sin(0.1f * float(i)));
    c.target.w = 0.f;
    cons_b.push_back(c);
    c.canonical = VD_F4(pos[i].x - lo[0], pos[i].y - lo[1], pos[i].z - lo[2], c.canonical.w);
    cons_d.push_back(c);
  }
  ASSERT_GT(cons_b.size(), 5000u);
  auto d_cons_b = ToDevice(ctx, cons_b), d_cons_d = ToDevice(ctx, cons_d);

  SolverParams params;
  params.levels = 3;
  // Every PCG step runs its 20 iterations on both sides: an early stop is a threshold test, and a
  // residual that crosses it one iteration apart on the two lattices (38 against 40 iterations
  // once in a loaded run) makes two different solves, not one solve rounded in another order.
  params.pcg_tolerance = 1e-30f;  // valid (0 < tol < 1), never reached
  HierarchicalSolver hb(&ops, params), hd(&ops, params);
  const DeviceLattice lb = DeviceLattice::Bricks(*f_.table, h);
  ASSERT_TRUE(hb.Prepare(lb, used, active_).ok());
  ASSERT_TRUE(hd.Prepare(dv, dact).ok());
  const VdLattice fine_lat = lb.lat;
  const std::vector<int32_t> nbr = cpu::BrickNeighbours(ref, used);
  for (int l = 1; l <= 2; ++l) {
    const int s = 1 << l;
    const DeviceActiveSet& cb = hb.level_active(l);
    const DeviceActiveSet& cd = hd.level_active(l);
    // The level on the bricks against the CPU.
    const VdLattice cl = hb.level_lattice(l).lat;
    const cpu::ActiveSet want = cpu::BuildLevel(fine_lat, nbr.data(), list_b, s, cl, hb.level_lattice(l).Entries(used));
    ASSERT_EQ(cb.count, want.list.size()) << "level " << l;
    EXPECT_EQ(FromDevice(ctx, cb.list, cb.count), want.list);
    EXPECT_EQ(FromDevice(ctx, cb.compact, want.compact.size()), want.compact);
    EXPECT_EQ(FromDevice(ctx, cb.neighbours, 6 * cb.count), want.neighbours);
    // The same coarse points as the dense grid's level.
    EXPECT_EQ(cb.count, cd.count) << "level " << l;
    std::set<Coords> on_bricks, on_dense;
    for (int32_t e : want.list) {
      int slot, x, y, z, g[3];
      vd_lattice_point(cl, e, &slot, &x, &y, &z);
      vd_lattice_global(cl, ref.slot_keys.data(), slot, x, y, z, &g[0], &g[1], &g[2]);
      on_bricks.insert({g[0] * s, g[1] * s, g[2] * s});
    }
    const VdLattice cdl = hd.level_lattice(l).lat;
    for (int32_t e : FromDevice(ctx, cd.list, cd.count)) {
      int slot, x, y, z;
      vd_lattice_point(cdl, e, &slot, &x, &y, &z);
      on_dense.insert({lo[0] + x * s, lo[1] + y * s, lo[2] + z * s});
    }
    EXPECT_EQ(on_bricks, on_dense) << "level " << l;
    // Restriction of a displaced fine state on the bricks against the CPU.
    std::vector<vd_float4> x_f(m), rot_f(m, VD_F4(0.f, 0.f, 0.f, 1.f));
    for (size_t k = 0; k < m; ++k) {
      const Coords g = GlobalOf(ref, list_b[k]);
      x_f[k] =
          VD_F4(h * g[0] + 0.002f * std::sin(0.3f * g[1]), h * g[1], h * g[2] + 0.001f * std::cos(0.2f * g[0]), 0.f);
    }
    auto d_x_f = ToDevice(ctx, x_f), d_rot_f = ToDevice(ctx, rot_f);
    auto d_x0 = ctx->Alloc<vd_float4>(cb.count), d_r0 = ctx->Alloc<vd_float4>(cb.count);
    ASSERT_TRUE(d_x0.ok() && d_r0.ok());
    ASSERT_TRUE(ocl::RestrictState(*ctx, lb, active_, hb.level_lattice(l), cb, s, d_x_f, d_rot_f, *d_x0, *d_r0).ok());
    std::vector<vd_float4> x0(cb.count), r0(cb.count);
    const std::vector<int32_t> compact_b = FromDevice(ctx, active_.compact, size_t(used) * VD_BRICK_VOXELS);
    cpu::LevelRestrict(vd_active(cl, nbr.data(), ref.slot_keys.data(), want.list.data(), want.compact.data()),
                       int(cb.count), s,
                       vd_active(fine_lat, nbr.data(), ref.slot_keys.data(), list_b.data(), compact_b.data()),
                       x_f.data(), rot_f.data(), x0.data(), r0.data());
    EXPECT_TRUE(test::AllClose(test::Flatten(FromDevice(ctx, *d_x0, cb.count)), test::Flatten(x0), 1e-6f, 1e-6f));
  }

  auto sb = hb.Solve(f_.pool->def_pos, f_.pool->def_rot, d_cons_b, cons_b.size(), true);
  ASSERT_TRUE(sb.ok()) << sb.status().ToString();
  auto sd = hd.Solve(dv, d_cons_d, cons_d.size(), true);
  ASSERT_TRUE(sd.ok()) << sd.status().ToString();
  EXPECT_EQ(sb->constraints, sd->constraints);
  EXPECT_GT(sb->constraints, int(cons_b.size() * 3 / 4));
  EXPECT_NEAR(sb->energy_initial, sd->energy_initial, 1e-4 * sd->energy_initial);
  EXPECT_NEAR(sb->energy_final, sd->energy_final, 1e-3 * sd->energy_final + 1e-9);
  EXPECT_LT(sd->energy_final, 0.5 * sd->energy_initial) << "the solve did something";

  const std::vector<vd_float4> xb = FromDevice(ctx, hb.fine().positions(), m),
                               xd = FromDevice(ctx, hd.fine().positions(), m);
  float worst = 0.f, moved = 0.f;
  for (size_t k = 0; k < m; ++k) {
    const vd_float4 a = xb[k], b = xd[size_t(da.compact[dense_of[k]])];
    worst = std::max({worst, std::fabs(a.x - b.x), std::fabs(a.y - b.y), std::fabs(a.z - b.z)});
    const Coords g = GlobalOf(ref, list_b[k]);
    moved = std::max(moved, std::fabs(a.x - h * g[0]) + std::fabs(a.y - h * g[1]) + std::fabs(a.z - h * g[2]));
  }
  std::printf(
      "solve: %d constraints, %d + %d PCG iterations, E %.4g -> %.4g (dense %.4g -> %.4g); largest move %.2f mm, "
      "largest difference %.3g mm\n",
      sb->constraints, sb->pcg_iterations, sd->pcg_iterations, sb->energy_initial, sb->energy_final, sd->energy_initial,
      sd->energy_final, 1e3 * moved, 1e3 * worst);
  EXPECT_GT(moved, 0.002f);
  EXPECT_LT(worst, 1e-5f) << "metres: float rounding of sums in another order, not a different solve";
  // Written back into the pool's field, where the bricks' deformed mesh reads it.
  ASSERT_TRUE(hb.WriteBack(f_.pool->def_pos, f_.pool->def_rot).ok());
  const std::vector<vd_float4> field = FromDevice(ctx, f_.pool->def_pos, size_t(used) * VD_BRICK_VOXELS);
  for (size_t k = 0; k < m; k += 97) {
    EXPECT_EQ(field[list_b[k]].x, xb[k].x);
    EXPECT_EQ(field[list_b[k]].w, 1.f) << "one optimisation counted";
  }
}

// Non-rigid fusion on the bricks (vd_tsdf_integrate_active over pool voxels): the same voxels as the
// CPU reference from a moved field, with the gates (K_min, K_min for new space) and carving on.
TEST_F(SparseSolverParityTest, ActiveFusionOnBricksMatchesTheCpu) {
  ocl::Context* ctx = ctx_;
  const uint32_t used = f_.counts.used;
  const size_t m = active_.count, n = size_t(used) * VD_BRICK_VOXELS;
  const std::vector<int32_t> list = FromDevice(ctx, active_.list, m);
  // The field: every point moved up to 6 mm along z; a third optimised too few times to be fused.
  std::vector<vd_float4> field = FromDevice(ctx, f_.pool->def_pos, n);
  for (size_t k = 0; k < m; ++k) {
    vd_float4& p = field[size_t(list[k])];
    p.z += 0.006f * std::sin(0.05f * float(k));
    p.w = k % 3 == 0 ? 2.f : 12.f;
  }
  ASSERT_TRUE(ctx->Upload(f_.pool->def_pos, field.data(), n).ok());
  test::FusedBricks::Voxels want = f_.Download(ctx);
  const std::vector<float> weight_before = want.weight;
  VdFusionParams fp{};
  fp.k_min = 3.f;
  fp.k_min_new = 12.f;
  fp.carve_rate = 0.25f;
  fp.carve_radius = 1;
  ASSERT_TRUE(ops_->IntegrateActive(*f_.pool, active_, fp, f_.vol, f_.cam, f_.world_to_cam, f_.dd, f_.dc).ok());
  cpu::IntegrateActive(want.tsdf.data(), want.weight.data(), want.color.data(), list.data(), int(m), field.data(), fp,
                       f_.vol, f_.cam, f_.world_to_cam, f_.depth.data(), f_.rgba.data());
  const test::FusedBricks::Voxels got = f_.Download(ctx);
  EXPECT_TRUE(test::AllClose(got.tsdf, want.tsdf, 1e-6f, 1e-5f));
  EXPECT_TRUE(test::AllClose(got.weight, want.weight, 1e-6f, 1e-6f));
  EXPECT_EQ(got.color, want.color);
  // It did fuse (and only the members optimised often enough): weights changed at members only.
  size_t changed = 0, gated_changed = 0;
  std::vector<uint8_t> member(n, 0);
  for (size_t k = 0; k < m; ++k) member[size_t(list[k])] = k % 3 == 0 ? 2 : 1;
  for (size_t i = 0; i < n; ++i) {
    if (got.weight[i] == weight_before[i]) continue;
    EXPECT_NE(member[i], 0) << "voxel " << i << " is not active but changed";
    changed += member[i] == 1;
    gated_changed += member[i] == 2;
  }
  std::printf("active fusion on bricks: %zu of %zu members changed weight\n", changed, m);
  EXPECT_GT(changed, m / 3);
  EXPECT_EQ(gated_changed, 0u);
}

// The feature kernels on the bricks' field (VD_FIELD_ARGS with the table's hash): prediction S(g)
// and lifting (Newton on S(g) = f) against the CPU, a point whose cell is not allocated moved as
// at rest, and the lift finding the canonical point again.
TEST_F(SparseSolverParityTest, FeaturesOnBricksMatchTheCpu) {
  ocl::Context* ctx = ctx_;
  const uint32_t used = f_.counts.used;
  const size_t n = size_t(used) * VD_BRICK_VOXELS;
  const float h = f_.vol.voxel_size;
  // A smooth field: every allocated point moved by up to 3 mm.
  std::vector<vd_float4> field = FromDevice(ctx, f_.pool->def_pos, n);
  for (vd_float4& t : field) {
    t.x += 0.003f * std::sin(9.f * t.y);
    t.y += 0.002f * std::cos(7.f * t.x);
    t.z += 0.002f;
  }
  ASSERT_TRUE(ctx->Upload(f_.pool->def_pos, field.data(), n).ok());
  const cpu::BrickTable ref = f_.Reference(ctx);
  const std::vector<int32_t> nbr = FromDevice(ctx, f_.table->neighbours(), size_t(used) * VD_BRICK_NEIGHBOURS);
  const VdVolume vol = DeviceField::Bricks(*f_.table, *f_.pool, h).vol;
  // Points on the surface (every 50th mesh vertex, between grid points), one far from any brick,
  // one invalid.
  const std::vector<vd_float4> verts = FromDevice(ctx, mesh_.positions_grid, mesh_.num_vertices);
  std::vector<vd_float4> g;
  for (size_t i = 0; i < verts.size(); i += 50) g.push_back(VD_F4(verts[i].x, verts[i].y, verts[i].z, 1.f));
  ASSERT_GT(g.size(), 100u);
  g.push_back(VD_F4(verts[0].x + 200.5f, verts[0].y, verts[0].z, 1.f));
  g.push_back(VD_F4(verts[1].x, verts[1].y, verts[1].z, 0.f));
  const size_t m = g.size();
  std::vector<vd_float4> want(m);
  cpu::FeaturePredict(g.data(), int(m), field.data(), vol, want.data(), ref.keys.data(), ref.slots.data(),
                      f_.table->capacity(), nbr.data());
  auto d_g = ToDevice(ctx, g);
  auto d_out = ctx->Alloc<vd_float4>(m);
  ASSERT_TRUE(d_out.ok());
  const DeviceField df = DeviceField::Bricks(*f_.table, *f_.pool, h);
  ASSERT_TRUE(ocl::PredictFeatures(*ctx, m, d_g, df, *d_out).ok());
  EXPECT_TRUE(test::AllClose(test::Flatten(FromDevice(ctx, *d_out, m)), test::Flatten(want), 1e-6f, 1e-6f));
  const vd_float4 far = want[m - 2];
  EXPECT_NEAR(far.x, h * g[m - 2].x, 1e-6f) << "no brick: at rest";
  EXPECT_EQ(want[m - 1].w, 0.f);
  EXPECT_GT(std::fabs(want[0].z - h * g[0].z), 0.0015f) << "moved by the field";

  // Lifting the predicted points from their rest position (the first frame's start): Newton finds
  // the canonical points again.
  std::vector<vd_float4> points(want.begin(), want.end() - 2);
  const size_t k = points.size();
  std::vector<int32_t> pixels(k, -1);
  VdLiftParams lp{};
  lp.world_to_cam = test::IdentityPose();
  lp.max_depth_gap = 0.03f;
  lp.tolerance = 1e-5f;
  lp.iterations = 10;
  lp.no_model = 1;
  std::vector<vd_float4> lifted(k);
  const std::vector<uint32_t> ids(1, VD_RASTER_EMPTY);
  const std::vector<vd_float4> none(1, VD_F4(0.f, 0.f, 0.f, 0.f));
  const std::vector<int32_t> tris(3, 0);
  cpu::FeatureLift(points.data(), pixels.data(), int(k), ids.data(), none.data(), none.data(), none.data(), tris.data(),
                   field.data(), vol, lp, lifted.data(), ref.keys.data(), ref.slots.data(), f_.table->capacity(),
                   nbr.data());
  auto d_points = ToDevice(ctx, points);
  auto d_pixels = ToDevice(ctx, pixels);
  auto d_ids = ToDevice(ctx, ids);
  auto d_none = ToDevice(ctx, none);
  auto d_tris = ToDevice(ctx, tris);
  auto d_lifted = ctx->Alloc<vd_float4>(k);
  ASSERT_TRUE(d_lifted.ok());
  ASSERT_TRUE(
      ocl::LiftFeatures(*ctx, k, d_points, d_pixels, d_ids, d_none, d_none, d_none, d_tris, df, lp, *d_lifted).ok());
  const std::vector<vd_float4> got = FromDevice(ctx, *d_lifted, k);
  size_t found = 0;
  float worst = 0.f;
  for (size_t i = 0; i < k; ++i) {
    ASSERT_EQ(got[i].w, lifted[i].w) << i;
    EXPECT_NEAR(got[i].x, lifted[i].x, 1e-4f) << i;
    EXPECT_NEAR(got[i].y, lifted[i].y, 1e-4f) << i;
    EXPECT_NEAR(got[i].z, lifted[i].z, 1e-4f) << i;
    if (lifted[i].w != 1.f) continue;
    ++found;
    worst = std::max(
        {worst, std::fabs(lifted[i].x - g[i].x), std::fabs(lifted[i].y - g[i].y), std::fabs(lifted[i].z - g[i].z)});
  }
  std::printf("features on bricks: %zu predicted, %zu of %zu lifted, largest error %.4f voxels\n", m, found, k, worst);
  EXPECT_EQ(found, k);
  EXPECT_LT(worst, 0.01f);
}

// Growth (vd_sparse_grow: depth the live model does not explain): the never-fused voxels of the
// listed bricks within the depth's band fused once, ungated, through the field (their own where
// optimised, else the rest position moved by the brick's motion), against the CPU; fused voxels
// untouched.
TEST_F(SparseSolverParityTest, GrowthFusesTheUnfusedVoxelsOfItsBricksLikeTheCpu) {
  ocl::Context* ctx = ctx_;
  const uint32_t used = f_.counts.used;
  const size_t n = size_t(used) * VD_BRICK_VOXELS;
  const cpu::BrickTable ref = f_.Reference(ctx);
  // Every 7th slot, one not a slot (-1), each with its own rigid motion: up to 1 cm and 3 degrees.
  std::vector<int32_t> slots;
  std::vector<VdPose> disp;
  for (uint32_t s = 0; s < used; s += 7) {
    slots.push_back(int32_t(s));
    const float a = 0.05f * std::sin(0.7f * float(s)), c = std::cos(a), sn = std::sin(a);
    VdPose m{};
    m.r0 = VD_F4(c, -sn, 0.f, 0.01f * std::sin(0.3f * float(s)));
    m.r1 = VD_F4(sn, c, 0.f, 0.005f * std::cos(0.2f * float(s)));
    m.r2 = VD_F4(0.f, 0.f, 1.f, -0.004f);
    disp.push_back(m);
  }
  slots.push_back(-1);
  disp.push_back(test::IdentityPose());
  // Some voxels optimised already (their own t_i, moved 2 mm, is used).
  std::vector<vd_float4> field = FromDevice(ctx, f_.pool->def_pos, n);
  for (size_t v = 0; v < n; v += 5) {
    field[v].z += 0.002f;
    field[v].w = 4.f;
  }
  ASSERT_TRUE(ctx->Upload(f_.pool->def_pos, field.data(), n).ok());
  test::FusedBricks::Voxels want = f_.Download(ctx);
  const std::vector<float> weight_before = want.weight;
  std::vector<vd_float4> want_field = field;
  cpu::SparseGrow(ref, slots, disp, want.tsdf.data(), want.weight.data(), want.color.data(), want_field.data(), f_.vol,
                  f_.cam, f_.world_to_cam, f_.depth.data(), f_.rgba.data());
  auto d_slots = ToDevice(ctx, slots);
  auto d_disp = ToDevice(ctx, disp);
  ASSERT_TRUE(ocl::GrowBricks(*ctx, *f_.table, *f_.pool, slots.size(), d_slots, d_disp, f_.vol, f_.cam, f_.world_to_cam,
                              f_.dd, f_.dc)
                  .ok());
  const test::FusedBricks::Voxels got = f_.Download(ctx);
  EXPECT_TRUE(test::AllClose(got.tsdf, want.tsdf, 1e-6f, 1e-5f));
  EXPECT_TRUE(test::AllClose(got.weight, want.weight, 0.f, 0.f));
  EXPECT_EQ(got.color, want.color);
  EXPECT_TRUE(
      test::AllClose(test::Flatten(FromDevice(ctx, f_.pool->def_pos, n)), test::Flatten(want_field), 1e-6f, 1e-6f));
  size_t grown = 0, refused = 0;
  for (size_t v = 0; v < n; ++v) {
    if (weight_before[v] > 0.f) {
      EXPECT_EQ(want.weight[v], weight_before[v]) << "a fused voxel is left alone";
      continue;
    }
    if (want.weight[v] > 0.f) {
      ++grown;
      EXPECT_EQ((v / VD_BRICK_VOXELS) % 7, 0u) << "only the listed bricks grow";
    } else if ((v / VD_BRICK_VOXELS) % 7 == 0) {
      ++refused;  // outside the band
    }
  }
  std::printf("growth: %zu voxels fused, %zu of the listed bricks' unfused voxels outside the band\n", grown, refused);
  EXPECT_GT(grown, 100u);
  EXPECT_GT(refused, grown) << "free space in front is not fused";
  EXPECT_FALSE(ocl::GrowBricks(*ctx, *f_.table, *f_.pool, slots.size() + 1, d_slots, d_disp, f_.vol, f_.cam,
                               f_.world_to_cam, f_.dd, f_.dc)
                   .ok())
      << "more bricks than listed";
}

}  // namespace
}  // namespace vd
