// The coarse levels of the non-rigid solver (shared/hierarchy.h): level active sets, restriction,
// constraint re-expression and prolongation on the device against their CPU references, plus the
// exact cases the formulation promises (a translated field restricts, re-expresses and
// prolongates without loss).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/hierarchy.h"
#include "cpu_ref/cpu_ref.h"
#include "cpu_ref/solver_ref.h"
#include "ocl/hierarchy_ocl.h"
#include "ocl/solver_ocl.h"
#include "sphere_volume.h"
#include "test_scenes.h"

namespace vd {
namespace {

using test::AllClose;
using test::Flatten;
using test::FromDevice;
using test::ToDevice;

struct Fixture {
  VdVolume vol{};
  cpu::McMesh mesh;
  cpu::ActiveSet fine;
};

// A sphere of 11.4 voxels around grid point (20.3, 17.6, 15.2).
Fixture MakeSphere() {
  Fixture f;
  const test::AnalyticVolume sphere = test::MakeSphereVolume(
      test::TestVolume(41, 36, 30, 0.01f, VD_F4(-0.2f, -0.18f, 0.8f, 1.f)), 0.003f, -0.004f, 0.952f, 0.114f);
  f.vol = sphere.vol;
  f.mesh = cpu::MarchingCubes(sphere.tsdf.data(), sphere.weight.data(), sphere.color.data(), f.vol);
  f.fine = cpu::BuildActiveSet(f.mesh.codes.data(), f.vol);
  return f;
}

vd_float4 Rest(VdVolume vol, int i) {
  int x, y, z;
  vd_grid_coords(i, vol, &x, &y, &z);
  return vd_rest_position(vol, x, y, z);
}

// An active set of a dense lattice, as the shared functions take it.
VdActive Dense(VdLattice l, const cpu::ActiveSet& a) {
  return vd_active(l, nullptr, nullptr, a.list.data(), a.compact.data());
}

// Each constraint's cell on a dense grid (the compact index of its first corner, -1: unusable).
std::vector<int32_t> CellsOf(const std::vector<VdCorrespondence>& cons, const std::vector<int32_t>& compact,
                             VdVolume vol) {
  std::vector<int32_t> cells(cons.size());
  for (size_t c = 0; c < cons.size(); ++c) cells[c] = vd_constraint_cell(cons[c], compact.data(), vol);
  return cells;
}

TEST(HierarchyParityTest, LevelsRestrictionConstraintsAndProlongationMatchCpu) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  const Fixture f = MakeSphere();
  ASSERT_GT(f.fine.list.size(), 3000u);
  DeviceVolume dv;
  ASSERT_TRUE(ops.AllocVolume(f.vol, true, &dv).ok());
  DeviceActiveSet fine;
  fine.count = f.fine.list.size();
  fine.list = ToDevice(ctx, f.fine.list);
  fine.compact = ToDevice(ctx, f.fine.compact);
  fine.neighbours = ToDevice(ctx, f.fine.neighbours);
  SolverParams three_levels;
  three_levels.levels = 3;
  HierarchicalSolver h(&ops, three_levels);
  ASSERT_TRUE(h.Prepare(dv, fine).ok());
  ASSERT_EQ(h.num_levels(), 3);

  // Fine state: rest plus a smooth non-rigid displacement.
  std::vector<vd_float4> x_f(fine.count);
  for (size_t k = 0; k < fine.count; ++k) {
    const vd_float4 r = Rest(f.vol, f.fine.list[k]);
    x_f[k] = r + VD_F4(0.01f * std::sin(9.f * r.y), 0.006f * std::cos(7.f * r.x), 0.004f * std::sin(5.f * r.z), 0.f);
  }
  // Fine rotations: turns by up to 160 degrees about (0.6, 0.8, 0), every other one stored as -q
  // (the same rotation), so the mean must align signs.
  std::vector<vd_float4> rot_f(fine.count);
  for (size_t k = 0; k < fine.count; ++k) {
    const float a = 1.4f * float(k + 1) / float(fine.count), sg = k % 2 ? -1.f : 1.f;
    rot_f[k] = VD_F4(sg * 0.6f * std::sin(a), sg * 0.8f * std::sin(a), 0.f, sg * std::cos(a));
  }
  auto d_rot_f = ToDevice(ctx, rot_f);
  auto d_x_f = ToDevice(ctx, x_f);
  // Constraints at the marching-cubes vertices, targets along the normals.
  std::vector<VdCorrespondence> cons;
  for (size_t i = 0; i < f.mesh.positions_grid.size(); ++i) {
    VdCorrespondence c;
    c.canonical = f.mesh.positions_grid[i];
    c.canonical.w = (i % 7 == 0) ? 0.f : 0.3f + 0.1f * float(i % 5);
    c.normal = f.mesh.normals[i];
    c.normal.w = 0.f;
    const vd_float4 g = c.canonical;
    c.target = VD_F4(f.vol.origin.x + 0.01f * g.x, f.vol.origin.y + 0.01f * g.y, f.vol.origin.z + 0.01f * g.z, 0.f) +
               c.normal * 0.005f;
    cons.push_back(c);
  }
  auto d_cons = ToDevice(ctx, cons);
  const int nc = int(cons.size());

  const VdLattice fl = vd_lattice_dense(f.vol);
  const DeviceLattice dfl = DeviceLattice::Dense(f.vol);
  const std::vector<int32_t> cells = CellsOf(cons, f.fine.compact, f.vol);
  auto d_cells = ToDevice(ctx, cells);
  for (int l = 1; l <= 2; ++l) {
    const int s = 1 << l;
    const DeviceLattice dcl = h.level_lattice(l);
    const VdLattice cv = dcl.lat;
    EXPECT_EQ(cv.spacing, f.vol.voxel_size * s);
    const cpu::ActiveSet ref = cpu::BuildLevel(fl, nullptr, f.fine.list, s, cv, dcl.Entries(0));
    const DeviceActiveSet& got = h.level_active(l);
    ASSERT_EQ(got.count, ref.list.size()) << "level " << l;
    EXPECT_EQ(FromDevice(ctx, got.list, got.count), ref.list);
    EXPECT_EQ(FromDevice(ctx, got.compact, ref.compact.size()), ref.compact);
    EXPECT_EQ(FromDevice(ctx, got.neighbours, 6 * got.count), ref.neighbours);
    // A coarse level is much smaller than the fine one but covers every fine point's cell.
    EXPECT_LT(got.count, f.fine.list.size() / 2);

    auto d_x0 = ctx->Alloc<vd_float4>(got.count);
    auto d_rot_c = ctx->Alloc<vd_float4>(got.count);
    ASSERT_TRUE(d_x0.ok() && d_rot_c.ok());
    ASSERT_TRUE(ocl::RestrictState(*ctx, dfl, fine, dcl, got, s, d_x_f, d_rot_f, *d_x0, *d_rot_c).ok());
    std::vector<vd_float4> x0_ref(got.count), rot_ref(got.count);
    cpu::LevelRestrict(Dense(cv, ref), int(got.count), s, Dense(fl, f.fine), x_f.data(), rot_f.data(), x0_ref.data(),
                       rot_ref.data());
    const auto x0 = FromDevice(ctx, *d_x0, got.count);
    EXPECT_TRUE(AllClose(Flatten(x0), Flatten(x0_ref), 1e-6f, 1e-6f));
    const auto rot_c = FromDevice(ctx, *d_rot_c, got.count);
    EXPECT_TRUE(AllClose(Flatten(rot_c), Flatten(rot_ref), 1e-6f, 0.f));
    // Every coarse point has fine points around it: a unit quaternion about the fine rotations'
    // axis turning the same way (q or -q), never the identity fallback.
    for (size_t K = 0; K < got.count; ++K) {
      const vd_float4 q = rot_ref[K];
      EXPECT_NEAR(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w, 1.f, 1e-5f) << K;
      EXPECT_NEAR(q.x * 0.8f, q.y * 0.6f, 1e-5f) << K;  // the same axis (0.6, 0.8, 0)
      EXPECT_GT(q.w < 0.f ? -q.y : q.y, 0.f) << K;  // a turn the positive way, as every fine one
    }

    auto d_cc = ctx->Alloc<VdCorrespondence>(nc);
    ASSERT_TRUE(d_cc.ok());
    ASSERT_TRUE(
        ocl::RestrictConstraints(*ctx, dfl, fine, dcl, got, s, size_t(nc), d_cons, d_cells, d_x_f, *d_x0, *d_cc).ok());
    std::vector<VdCorrespondence> cc_ref(nc);
    cpu::LevelConstraints(cons.data(), cells.data(), nc, Dense(fl, f.fine), x_f.data(), s, Dense(cv, ref),
                          x0_ref.data(), cc_ref.data());
    const auto cc = FromDevice(ctx, *d_cc, nc);
    int kept = 0;
    for (int c = 0; c < nc; ++c) {
      ASSERT_EQ(cc[c].canonical.w, cc_ref[c].canonical.w) << c;
      kept += cc[c].canonical.w > 0.f;
      EXPECT_NEAR(cc[c].canonical.x, cc_ref[c].canonical.x, 1e-6f);
      EXPECT_NEAR(cc[c].target.x, cc_ref[c].target.x, 1e-6f);
      EXPECT_NEAR(cc[c].target.y, cc_ref[c].target.y, 1e-6f);
      EXPECT_NEAR(cc[c].target.z, cc_ref[c].target.z, 1e-6f);
    }
    // Every constraint the fine level accepts has all its coarse corners: only the pruned ones drop.
    EXPECT_EQ(kept, nc - (nc + 6) / 7);

    // Prolongation of arbitrary coarse increments.
    std::vector<vd_float4> x_c(got.count);
    for (size_t k = 0; k < got.count; ++k) x_c[k] = x0_ref[k] + VD_F4(0.001f * float(k % 11), -0.0005f * float(k % 5), 0.002f, 0.f);
    auto d_x_c = ToDevice(ctx, x_c);
    auto d_out = ToDevice(ctx, x_f);
    ASSERT_TRUE(ocl::ProlongateIncrement(*ctx, dfl, fine, dcl, got, s, d_x_c, *d_x0, d_out).ok());
    std::vector<vd_float4> out_ref = x_f;
    cpu::LevelProlongate(Dense(fl, f.fine), int(fine.count), s, Dense(cv, ref), x_c.data(), x0_ref.data(),
                         out_ref.data());
    EXPECT_TRUE(AllClose(Flatten(FromDevice(ctx, d_out, fine.count)), Flatten(out_ref), 1e-6f, 1e-6f));
  }
}

// A field translated by d everywhere: the coarse starts are rest + d, the constraints' targets do
// not move (trilinear interpolation reproduces positions exactly), a constant coarse increment
// reaches every fine point unchanged.
TEST(HierarchyParityTest, TranslatedFieldIsExact) {
  const Fixture f = MakeSphere();
  const vd_float4 d = VD_F4(0.013f, -0.007f, 0.021f, 0.f);
  std::vector<vd_float4> x_f(f.fine.list.size());
  for (size_t k = 0; k < x_f.size(); ++k) x_f[k] = Rest(f.vol, f.fine.list[k]) + d;
  const int s = 4;
  const VdLattice fl = vd_lattice_dense(f.vol), cv = vd_lattice_level(fl, s);
  const cpu::ActiveSet lvl = cpu::BuildLevel(fl, nullptr, f.fine.list, s, cv, size_t(vd_lattice_brick_points(cv)));
  std::vector<vd_float4> x0(lvl.list.size()), rot_c(lvl.list.size());
  // One rotation everywhere (half of the points store it as -q): every coarse point gets it.
  const vd_float4 q = VD_F4(0.36f, 0.48f, 0.f, 0.8f);
  std::vector<vd_float4> rot_f(f.fine.list.size());
  for (size_t k = 0; k < rot_f.size(); ++k) rot_f[k] = k % 2 ? -q : q;
  cpu::LevelRestrict(Dense(cv, lvl), int(lvl.list.size()), s, Dense(fl, f.fine), x_f.data(), rot_f.data(), x0.data(),
                     rot_c.data());
  for (const vd_float4& r : rot_c) {
    const float sg = r.w < 0.f ? -1.f : 1.f;
    ASSERT_NEAR(sg * r.x, q.x, 1e-6f);
    ASSERT_NEAR(sg * r.y, q.y, 1e-6f);
    ASSERT_NEAR(sg * r.w, q.w, 1e-6f);
  }
  for (size_t k = 0; k < x0.size(); ++k) {
    const vd_float4 want = vd_active_rest(Dense(cv, lvl), int(k)) + d;
    ASSERT_NEAR(x0[k].x, want.x, 1e-6f);
    ASSERT_NEAR(x0[k].y, want.y, 1e-6f);
    ASSERT_NEAR(x0[k].z, want.z, 1e-6f);
  }
  std::vector<VdCorrespondence> cons;
  for (size_t i = 0; i < f.mesh.positions_grid.size(); ++i) {
    VdCorrespondence c;
    c.canonical = f.mesh.positions_grid[i];
    c.canonical.w = 1.f;
    c.normal = f.mesh.normals[i];
    c.target = VD_F4(0.1f, 0.2f, 0.9f, 0.f);
    cons.push_back(c);
  }
  std::vector<VdCorrespondence> cc(cons.size());
  const std::vector<int32_t> cells = CellsOf(cons, f.fine.compact, f.vol);
  cpu::LevelConstraints(cons.data(), cells.data(), int(cons.size()), Dense(fl, f.fine), x_f.data(), s, Dense(cv, lvl),
                        x0.data(), cc.data());
  for (size_t c = 0; c < cc.size(); ++c) {
    ASSERT_GT(cc[c].canonical.w, 0.f);
    ASSERT_NEAR(cc[c].target.x, 0.1f, 2e-6f);
    ASSERT_NEAR(cc[c].target.y, 0.2f, 2e-6f);
    ASSERT_NEAR(cc[c].target.z, 0.9f, 2e-6f);
    ASSERT_NEAR(cc[c].canonical.x * s, cons[c].canonical.x, 1e-4f);
  }
  std::vector<vd_float4> x_c = x0;
  for (auto& p : x_c) p = p + VD_F4(0.002f, 0.003f, -0.001f, 0.f);
  std::vector<vd_float4> out = x_f;
  cpu::LevelProlongate(Dense(fl, f.fine), int(f.fine.list.size()), s, Dense(cv, lvl), x_c.data(), x0.data(),
                       out.data());
  for (size_t k = 0; k < out.size(); ++k) {
    ASSERT_NEAR(out[k].x - x_f[k].x, 0.002f, 1e-6f);
    ASSERT_NEAR(out[k].y - x_f[k].y, 0.003f, 1e-6f);
    ASSERT_NEAR(out[k].z - x_f[k].z, -0.001f, 1e-6f);
  }
}

// Constraints sorted by the compact index of their cell's first corner (the fine solver's
// counting sort, order within a cell aside), and the cells' ranges (m + 1 entries).
void SortByCell(const std::vector<VdCorrespondence>& raw, const std::vector<int32_t>& compact, VdLattice lat, size_t m,
                std::vector<VdCorrespondence>* sorted, std::vector<vd_uint>* cell_start) {
  VdVolume vol{};
  vol.origin = lat.origin;
  vol.dim_x = lat.dim_x;
  vol.dim_y = lat.dim_y;
  vol.dim_z = lat.dim_z;
  vol.voxel_size = lat.spacing;
  std::vector<std::vector<VdCorrespondence>> by_cell(m);
  for (const auto& c : raw) {
    const int kc = vd_constraint_cell(c, compact.data(), vol);
    if (kc >= 0) by_cell[kc].push_back(c);
  }
  sorted->clear();
  cell_start->assign(m + 1, 0u);
  for (size_t k = 0; k < m; ++k) {
    (*cell_start)[k + 1] = (*cell_start)[k] + vd_uint(by_cell[k].size());
    sorted->insert(sorted->end(), by_cell[k].begin(), by_cell[k].end());
  }
}

struct CoarseSystem {
  std::vector<float> blocks;
  std::vector<int> nbr;
  std::vector<vd_float4> rhs;
  std::vector<VdMat3> inv;
};

CoarseSystem Assemble(const cpu::ActiveSet& lvl, VdLattice cv, const std::vector<float>& moments, VdSolverWeights w,
                      const vd_float4* x0) {
  const int n = int(lvl.list.size());
  CoarseSystem sys;
  sys.blocks.resize(size_t(VD_BTB_FLOATS) * n);
  sys.nbr.resize(size_t(VD_BTB_BLOCKS) * n);
  sys.rhs.resize(n);
  sys.inv.resize(n);
  const std::vector<float> ones(6 * size_t(n), 1.f);
  cpu::BtbAssemble(Dense(cv, lvl), lvl.neighbours.data(), ones.data(), moments.data(), w, x0, n, sys.blocks.data(),
                   sys.nbr.data(), sys.rhs.data(), sys.inv.data());
  return sys;
}

// A deformed fine state over the sphere's active set and constraints sorted by fine cell.
struct FineProblem {
  std::vector<vd_float4> x_f, rot_f;
  std::vector<VdCorrespondence> cons;
  std::vector<vd_uint> cell_start;
};

FineProblem MakeFineProblem(const Fixture& f) {
  const size_t m = f.fine.list.size();
  FineProblem p;
  std::vector<vd_float4>& x_f = p.x_f;
  x_f.resize(m);
  p.rot_f.assign(m, VD_F4(0.f, 0.f, 0.f, 1.f));
  for (size_t k = 0; k < m; ++k) {
    const vd_float4 r = Rest(f.vol, f.fine.list[k]);
    x_f[k] = r + VD_F4(0.01f * std::sin(9.f * r.y), 0.006f * std::cos(7.f * r.x), 0.004f * std::sin(5.f * r.z), 0.f);
  }
  // Three constraints per marching-cubes vertex (two nudged within its cell), weights 0.3-0.7,
  // every seventh unusable (weight 0), targets off the surface along the normal.
  std::vector<VdCorrespondence> raw;
  for (size_t i = 0; i < f.mesh.positions_grid.size(); ++i)
    for (int r = 0; r < 3; ++r) {
      VdCorrespondence c;
      const vd_float4 g = f.mesh.positions_grid[i];
      const float cx = std::floor(g.x), cy = std::floor(g.y), cz = std::floor(g.z), sh = 0.37f * float(r);
      c.canonical =
          VD_F4(cx + std::fmod(g.x - cx + sh, 1.f), cy + std::fmod(g.y - cy + 0.5f * sh, 1.f),
                cz + std::fmod(g.z - cz + 0.25f * sh, 1.f), raw.size() % 7 == 0 ? 0.f : 0.3f + 0.1f * float(i % 5));
      c.normal = f.mesh.normals[i];
      c.normal.w = 0.f;
      c.target = VD_F4(f.vol.origin.x + 0.01f * g.x, f.vol.origin.y + 0.01f * g.y, f.vol.origin.z + 0.01f * g.z, 0.f) +
                 c.normal * (0.004f + 0.002f * std::sin(float(i)));
      raw.push_back(c);
    }
  const VdLattice fl = vd_lattice_dense(f.vol);
  SortByCell(raw, f.fine.compact, fl, m, &p.cons, &p.cell_start);
  return p;
}

// A coarse level's system gathered from the fine constraints in place (vd_level_moments, then the
// x0 part of the right-hand side from the blocks) on the device against the CPU, and against the
// system built the long way: every constraint re-expressed on the level (vd_level_constraint),
// sorted by coarse cell, its moments taken and assembled. The two are the same sums.
TEST(HierarchyParityTest, CoarseSystemFromFineConstraintsMatchesCpuAndTheReexpressedConstraints) {
  VD_REQUIRE_OCL(ctx);
  const Fixture f = MakeSphere();
  const size_t m = f.fine.list.size();
  const FineProblem p = MakeFineProblem(f);
  const std::vector<vd_float4>& x_f = p.x_f;
  const std::vector<vd_float4>& rot_f = p.rot_f;
  const std::vector<VdCorrespondence>& cons = p.cons;
  const std::vector<vd_uint>& cell_start = p.cell_start;
  const VdLattice fl = vd_lattice_dense(f.vol);
  DeviceActiveSet fine;
  fine.count = m;
  fine.list = ToDevice(ctx, f.fine.list);
  fine.compact = ToDevice(ctx, f.fine.compact);
  const DeviceLattice dfl = DeviceLattice::Dense(f.vol);
  ASSERT_GT(cons.size(), 3000u);
  VdSolverWeights w{};
  w.w_dense = 1.3f;
  w.w_reg = 2.f;
  w.damping = 2e-4f;

  auto d_cons = ToDevice(ctx, cons);
  auto d_start = ToDevice(ctx, cell_start);
  auto d_x_f = ToDevice(ctx, x_f);
  for (int s : {2, 4}) {
    const DeviceLattice dcl = dfl.Level(s);
    const VdLattice cv = dcl.lat;
    const cpu::ActiveSet lvl = cpu::BuildLevel(fl, nullptr, f.fine.list, s, cv, dcl.Entries(0));
    const int n = int(lvl.list.size());
    std::vector<vd_float4> x0(n), rot0(n);
    cpu::LevelRestrict(Dense(cv, lvl), n, s, Dense(fl, f.fine), x_f.data(), rot_f.data(), x0.data(), rot0.data());
    DeviceActiveSet coarse;
    coarse.count = size_t(n);
    coarse.list = ToDevice(ctx, lvl.list);
    coarse.compact = ToDevice(ctx, lvl.compact);
    coarse.neighbours = ToDevice(ctx, lvl.neighbours);

    // Device against CPU: the moments, then the shifted right-hand side.
    auto d_moments = ctx->Alloc<float>(size_t(VD_CELL_MOMENT_FLOATS) * n);
    ASSERT_TRUE(d_moments.ok());
    ASSERT_TRUE(ocl::LevelMoments(*ctx, dfl, fine, dcl, coarse, s, d_cons, d_start, d_x_f, *d_moments).ok());
    std::vector<float> moments(size_t(VD_CELL_MOMENT_FLOATS) * n, -1.f);
    cpu::LevelMoments(Dense(cv, lvl), s, Dense(fl, f.fine), cons.data(), cell_start.data(), x_f.data(), n,
                      moments.data());
    EXPECT_TRUE(AllClose(FromDevice(ctx, *d_moments, moments.size()), moments, 1e-6f, 1e-5f)) << "s = " << s;
    // The assembly with the x0 shift, on the device against the CPU.
    const CoarseSystem got = Assemble(lvl, cv, moments, w, x0.data());
    {
      auto d_ew = ToDevice(ctx, std::vector<float>(6 * size_t(n), 1.f));
      auto d_x0 = ToDevice(ctx, x0);
      auto d_blocks = ctx->Alloc<float>(size_t(VD_BTB_FLOATS) * n);
      auto d_nbr = ctx->Alloc<int32_t>(size_t(VD_BTB_BLOCKS) * n);
      auto d_rhs = ctx->Alloc<vd_float4>(n);
      auto d_inv = ctx->Alloc<VdMat3>(n);
      ASSERT_TRUE(d_blocks.ok() && d_nbr.ok() && d_rhs.ok() && d_inv.ok());
      ASSERT_TRUE(
          ocl::AssembleBtb(*ctx, dcl, coarse, d_ew, *d_moments, w, d_x0, *d_blocks, *d_nbr, *d_rhs, *d_inv).ok());
      EXPECT_EQ(FromDevice(ctx, *d_nbr, got.nbr.size()), got.nbr);
      EXPECT_TRUE(AllClose(FromDevice(ctx, *d_blocks, got.blocks.size()), got.blocks, 1e-6f, 1e-5f)) << "s = " << s;
      EXPECT_TRUE(AllClose(Flatten(FromDevice(ctx, *d_rhs, n)), Flatten(got.rhs), 1e-6f, 1e-5f)) << "s = " << s;
    }

    // The long way: re-expressed, sorted by coarse cell, moments, assembled.
    std::vector<VdCorrespondence> cc(cons.size()), cc_sorted;
    const std::vector<int32_t> cells = CellsOf(cons, f.fine.compact, f.vol);
    cpu::LevelConstraints(cons.data(), cells.data(), int(cons.size()), Dense(fl, f.fine), x_f.data(), s, Dense(cv, lvl),
                          x0.data(), cc.data());
    std::vector<vd_uint> cc_start;
    SortByCell(cc, lvl.compact, cv, n, &cc_sorted, &cc_start);
    ASSERT_EQ(cc_sorted.size(), cons.size()) << "every fine constraint has its coarse corners";
    std::vector<float> want_moments(size_t(VD_CELL_MOMENT_FLOATS) * n, -1.f);
    cpu::CellMoments(Dense(cv, lvl), cc_sorted.data(), cc_start.data(), n, want_moments.data());
    const CoarseSystem want = Assemble(lvl, cv, want_moments, w, nullptr);
    EXPECT_EQ(got.nbr, want.nbr);
    double largest_block = 0, worst_block = 0, largest_rhs = 0, worst_rhs = 0, worst_inv = 0;
    for (size_t i = 0; i < want.blocks.size(); ++i) {
      largest_block = std::max(largest_block, double(std::abs(want.blocks[i])));
      worst_block = std::max(worst_block, double(std::abs(got.blocks[i] - want.blocks[i])));
    }
    for (int k = 0; k < n; ++k) {
      const float g[3] = {got.rhs[k].x, got.rhs[k].y, got.rhs[k].z},
                  h[3] = {want.rhs[k].x, want.rhs[k].y, want.rhs[k].z};
      for (int a = 0; a < 3; ++a) {
        largest_rhs = std::max(largest_rhs, double(std::abs(h[a])));
        worst_rhs = std::max(worst_rhs, double(std::abs(g[a] - h[a])));
      }
      float scale = 0.f;
      for (int a = 0; a < 9; ++a) scale = std::max(scale, std::abs(want.inv[k].m[a]));
      for (int a = 0; a < 9; ++a)
        worst_inv = std::max(worst_inv, double(std::abs(got.inv[k].m[a] - want.inv[k].m[a]) / scale));
    }
    std::printf(
        "s = %d: %d points, %zu constraints; worst block error %.3g of %.3g, rhs %.3g of %.3g, relative "
        "inverse diagonal %.3g\n",
        s, n, cons.size(), worst_block, largest_block, worst_rhs, largest_rhs, worst_inv);
    EXPECT_GT(largest_rhs, 0.0);
    EXPECT_LT(worst_block, 1e-5 * largest_block) << "s = " << s;
    EXPECT_LT(worst_rhs, 1e-4 * largest_rhs) << "s = " << s;
    EXPECT_LT(worst_inv, 1e-4) << "s = " << s;
  }
}

// The dense colour term's rows (VD_CORR_COARSE_ONLY) are the coarse levels' alone: the fine cell
// moments, rows, targets and energy leave them out, while the coarse moments (on the device and the
// CPU) and the restricted constraints take them as any other row.
TEST(HierarchyParityTest, CoarseOnlyRowsEnterTheCoarseLevelsAlone) {
  VD_REQUIRE_OCL(ctx);
  const Fixture f = MakeSphere();
  const int m = int(f.fine.list.size());
  const FineProblem p = MakeFineProblem(f);
  const VdLattice fl = vd_lattice_dense(f.vol);
  // Every third row marked; the same rows with no weight; the same rows plain.
  std::vector<VdCorrespondence> marked = p.cons, weightless = p.cons;
  int n_marked = 0;
  for (size_t c = 0; c < marked.size(); c += 3) {
    if (!(marked[c].canonical.w > 0.f)) continue;
    marked[c].normal.w = VD_CORR_COARSE_ONLY;
    weightless[c].canonical.w = 0.f;
    ++n_marked;
  }
  ASSERT_GT(n_marked, 1000);

  // Fine: the moments are those without the marked rows (the count slot still counts them).
  std::vector<float> got(size_t(VD_CELL_MOMENT_FLOATS) * m), want(got.size()), plain(got.size());
  cpu::CellMoments(Dense(fl, f.fine), marked.data(), p.cell_start.data(), m, got.data());
  cpu::CellMoments(Dense(fl, f.fine), weightless.data(), p.cell_start.data(), m, want.data());
  cpu::CellMoments(Dense(fl, f.fine), p.cons.data(), p.cell_start.data(), m, plain.data());
  double differs = 0;
  for (int k = 0; k < m; ++k) {
    for (int i = 0; i < VD_CELL_COUNT_SLOT; ++i) {
      const size_t at = size_t(VD_CELL_MOMENT_FLOATS) * k + i;
      ASSERT_EQ(got[at], want[at]) << "cell " << k << " float " << i;
      differs = std::max(differs, double(std::abs(plain[at] - want[at])));
    }
  }
  EXPECT_GT(differs, 1e-3) << "the marked rows carry weight when plain";
  const std::vector<int32_t> cells = CellsOf(marked, f.fine.compact, f.vol);
  const VdActive fa = Dense(fl, f.fine);
  for (size_t c = 0; c < marked.size(); ++c) {
    if (vd_fine_row(marked[c])) continue;
    ASSERT_EQ(vd_constraint_apply(marked[c], cells[c], fa, p.x_f.data()), 0.f) << c;
    ASSERT_EQ(vd_constraint_target(marked[c]), 0.f) << c;
    ASSERT_EQ(vd_constraint_energy(marked[c], cells[c], fa, p.x_f.data()), 0.f) << c;
  }

  // Coarse: the moments of the marked rows are those of the plain ones, on the device and the CPU.
  DeviceActiveSet fine;
  fine.count = size_t(m);
  fine.list = ToDevice(ctx, f.fine.list);
  fine.compact = ToDevice(ctx, f.fine.compact);
  const DeviceLattice dfl = DeviceLattice::Dense(f.vol);
  auto d_marked = ToDevice(ctx, marked);
  auto d_start = ToDevice(ctx, p.cell_start);
  auto d_x_f = ToDevice(ctx, p.x_f);
  const int s = 2;
  const DeviceLattice dcl = dfl.Level(s);
  const cpu::ActiveSet lvl = cpu::BuildLevel(fl, nullptr, f.fine.list, s, dcl.lat, dcl.Entries(0));
  const int n = int(lvl.list.size());
  DeviceActiveSet coarse;
  coarse.count = size_t(n);
  coarse.list = ToDevice(ctx, lvl.list);
  coarse.compact = ToDevice(ctx, lvl.compact);
  coarse.neighbours = ToDevice(ctx, lvl.neighbours);
  std::vector<float> c_marked(size_t(VD_CELL_MOMENT_FLOATS) * n), c_plain(c_marked.size());
  cpu::LevelMoments(Dense(dcl.lat, lvl), s, fa, marked.data(), p.cell_start.data(), p.x_f.data(), n, c_marked.data());
  cpu::LevelMoments(Dense(dcl.lat, lvl), s, fa, p.cons.data(), p.cell_start.data(), p.x_f.data(), n, c_plain.data());
  EXPECT_EQ(c_marked, c_plain);
  auto d_moments = ctx->Alloc<float>(c_marked.size());
  ASSERT_TRUE(d_moments.ok());
  ASSERT_TRUE(ocl::LevelMoments(*ctx, dfl, fine, dcl, coarse, s, d_marked, d_start, d_x_f, *d_moments).ok());
  EXPECT_TRUE(AllClose(FromDevice(ctx, *d_moments, c_marked.size()), c_plain, 1e-6f, 1e-5f));
  // Restricted to a coarse level (without the cached moments), a row is that level's like any other.
  std::vector<vd_float4> x0(n), rot0(n);
  cpu::LevelRestrict(Dense(dcl.lat, lvl), n, s, fa, p.x_f.data(), p.rot_f.data(), x0.data(), rot0.data());
  std::vector<VdCorrespondence> cc(marked.size());
  cpu::LevelConstraints(marked.data(), cells.data(), int(marked.size()), fa, p.x_f.data(), s, Dense(dcl.lat, lvl),
                        x0.data(), cc.data());
  for (const VdCorrespondence& c : cc) ASSERT_TRUE(vd_fine_row(c));
}

// A level's moments from the level below it (vd_level_moments_up): on the device against the CPU,
// and against the same level's moments taken from the fine constraints (vd_level_moments), which
// are the same sums; twice up (spacing 2 -> 4 -> 8) as a four-level hierarchy runs it.
TEST(HierarchyParityTest, MomentsFromTheLevelBelowMatchTheFineConstraints) {
  VD_REQUIRE_OCL(ctx);
  const Fixture f = MakeSphere();
  const FineProblem p = MakeFineProblem(f);
  const VdLattice fl = vd_lattice_dense(f.vol);
  const DeviceLattice dfl = DeviceLattice::Dense(f.vol);
  std::vector<cpu::ActiveSet> levels;
  std::vector<std::vector<float>> direct;
  for (int s : {2, 4, 8}) {
    const VdLattice cv = dfl.Level(s).lat;
    levels.push_back(cpu::BuildLevel(fl, nullptr, f.fine.list, s, cv, dfl.Level(s).Entries(0)));
    const int n = int(levels.back().list.size());
    direct.emplace_back(size_t(VD_CELL_MOMENT_FLOATS) * n, -1.f);
    cpu::LevelMoments(Dense(cv, levels.back()), s, Dense(fl, f.fine), p.cons.data(), p.cell_start.data(), p.x_f.data(),
                      n, direct.back().data());
  }
  std::vector<float> below = direct[0];
  for (int l = 1; l < 3; ++l) {
    const int s = 2 << l;
    const DeviceLattice dcl = dfl.Level(s), dbl = dfl.Level(s / 2);
    const cpu::ActiveSet& up = levels[l];
    const cpu::ActiveSet& low = levels[l - 1];
    const int n = int(up.list.size());
    ASSERT_GT(n, 20) << "s = " << s;
    std::vector<float> got(size_t(VD_CELL_MOMENT_FLOATS) * n, -1.f);
    cpu::LevelMomentsUp(Dense(dcl.lat, up), Dense(dbl.lat, low), below.data(), n, got.data());

    DeviceActiveSet d_low, d_up;
    d_low.count = low.list.size();
    d_low.list = ToDevice(ctx, low.list);
    d_low.compact = ToDevice(ctx, low.compact);
    d_up.count = size_t(n);
    d_up.list = ToDevice(ctx, up.list);
    d_up.compact = ToDevice(ctx, up.compact);
    auto d_below = ToDevice(ctx, below);
    auto d_got = ctx->Alloc<float>(got.size());
    ASSERT_TRUE(d_got.ok());
    ASSERT_TRUE(ocl::LevelMomentsUp(*ctx, dbl, d_low, dcl, d_up, d_below, *d_got).ok());
    EXPECT_TRUE(AllClose(FromDevice(ctx, *d_got, got.size()), got, 1e-6f, 1e-5f)) << "s = " << s;

    // Against the fine constraints, relative to the largest value of each part (B^T B moments,
    // right-hand sides); the counts exactly.
    const std::vector<float>& want = direct[l];
    double largest[2] = {0, 0}, worst[2] = {0, 0};
    int cells = 0;
    for (int k = 0; k < n; ++k) {
      const float* a = got.data() + size_t(VD_CELL_MOMENT_FLOATS) * k;
      const float* b = want.data() + size_t(VD_CELL_MOMENT_FLOATS) * k;
      ASSERT_EQ(a[VD_CELL_COUNT_SLOT], b[VD_CELL_COUNT_SLOT]) << "s = " << s << ", point " << k;
      cells += b[VD_CELL_COUNT_SLOT] > 0.f;
      for (int i = 0; i < VD_CELL_COUNT_SLOT; ++i) {
        const int part = i < VD_CELL_RHS_SLOT ? 0 : 1;
        largest[part] = std::max(largest[part], double(std::abs(b[i])));
        worst[part] = std::max(worst[part], double(std::abs(a[i] - b[i])));
      }
    }
    std::printf(
        "s = %d from s = %d: %d points, %d cells with constraints; worst moment %.3g of %.3g, rhs %.3g of %.3g\n", s,
        s / 2, n, cells, worst[0], largest[0], worst[1], largest[1]);
    EXPECT_GT(cells, 10);
    EXPECT_GT(largest[1], 0.0);
    EXPECT_LT(worst[0], 1e-5 * largest[0]) << "s = " << s;
    EXPECT_LT(worst[1], 1e-5 * largest[1]) << "s = " << s;
    below = got;
  }
}

// A coarse level's increment reaches every point of a finer coarse level (the start of its solve,
// HierarchicalSolver): a linear increment over the spacing-4 level, prolongated to the spacing-2
// level, is that linear field at each of its points, including points on a face of the spacing-4
// cell holding them whose far corners no fine point marked.
TEST(HierarchyParityTest, ALinearIncrementProlongatesToEveryPointOfTheFinerLevel) {
  const Fixture f = MakeSphere();
  const VdLattice fl = vd_lattice_dense(f.vol), l1 = vd_lattice_level(fl, 2), l2 = vd_lattice_level(fl, 4);
  const cpu::ActiveSet a1 = cpu::BuildLevel(fl, nullptr, f.fine.list, 2, l1, size_t(vd_lattice_brick_points(l1)));
  const cpu::ActiveSet a2 = cpu::BuildLevel(fl, nullptr, f.fine.list, 4, l2, size_t(vd_lattice_brick_points(l2)));
  auto increment = [](vd_float4 p) {
    return VD_F4(0.01f + 0.2f * p.x - 0.1f * p.z, -0.02f + 0.15f * p.y, 0.005f + 0.1f * p.x + 0.05f * p.y, 0.f);
  };
  const int n2 = int(a2.list.size()), n1 = int(a1.list.size());
  std::vector<vd_float4> x0_c(n2), x_c(n2);
  for (int k = 0; k < n2; ++k) {
    x0_c[k] = vd_active_rest(Dense(l2, a2), k);
    x_c[k] = x0_c[k] + increment(x0_c[k]);
  }
  std::vector<vd_float4> u(n1, VD_F4(0.f, 0.f, 0.f, 0.f));
  cpu::LevelProlongate(Dense(l1, a1), n1, 2, Dense(l2, a2), x_c.data(), x0_c.data(), u.data());
  int on_face = 0;
  for (int k = 0; k < n1; ++k) {
    const vd_float4 p = vd_active_rest(Dense(l1, a1), k), want = increment(p);
    ASSERT_NEAR(u[k].x, want.x, 1e-6f) << "point " << k;
    ASSERT_NEAR(u[k].y, want.y, 1e-6f) << "point " << k;
    ASSERT_NEAR(u[k].z, want.z, 1e-6f) << "point " << k;
    int slot, x, y, z;
    vd_lattice_point(l1, a1.list[k], &slot, &x, &y, &z);
    on_face += (x % 2 == 0 && vd_lattice_compact(l2, nullptr, a2.compact.data(), 0, x / 2 + 1, y / 2, z / 2) < 0);
  }
  std::printf("%d points of spacing 2, %d on a face whose far corners are not in spacing 4\n", n1, on_face);
  EXPECT_GT(on_face, 0) << "the sphere has points on such faces";
}

}  // namespace
}  // namespace vd
