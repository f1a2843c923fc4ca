#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "cpu_ref/cpu_ref.h"
#include "ocl/device_ops.h"
#include "ocl/mc_table.h"
#include "sphere_volume.h"
#include "test_scenes.h"

namespace vd {
namespace {

using Grid = test::AnalyticVolume;

// dim^3 voxels from the origin.
VdVolume Cube(int dim, float voxel) { return test::TestVolume(dim, dim, dim, voxel, VD_F4(0, 0, 0, 1)); }

// A colour pattern on the fixture's volume, so the parity test compares vertex colours too.
Grid Coloured(Grid g) {
  for (int z = 0; z < g.vol.dim_z; ++z)
    for (int y = 0; y < g.vol.dim_y; ++y)
      for (int x = 0; x < g.vol.dim_x; ++x)
        g.color[x + size_t(g.vol.dim_x) * (y + size_t(g.vol.dim_y) * z)] =
            vd_pack_rgba(float(x * 4 % 256), float(y * 4 % 256), float(z * 4 % 256), 10.f);
  return g;
}

cpu::McMesh RunOcl(ocl::Context* ctx, const Grid& g) {
  DeviceOps ops(ctx);
  EXPECT_TRUE(ops.Init().ok());
  DeviceVolume dv;
  EXPECT_TRUE(ops.AllocVolume(g.vol, false, &dv).ok());
  EXPECT_TRUE(ctx->Upload(dv.tsdf, g.tsdf.data(), g.tsdf.size()).ok());
  EXPECT_TRUE(ctx->Upload(dv.weight, g.weight.data(), g.weight.size()).ok());
  EXPECT_TRUE(ops.MarkTouched(dv).ok());
  EXPECT_TRUE(ctx->Upload(dv.color, g.color.data(), g.color.size()).ok());
  DeviceMesh m;
  Status s = ops.MarchingCubes(dv, &m);
  EXPECT_TRUE(s.ok()) << s.ToString();
  cpu::McMesh out;
  out.positions_grid = test::FromDevice(ctx, m.positions_grid, m.num_vertices);
  out.normals = test::FromDevice(ctx, m.normals, m.num_vertices);
  out.colors = test::FromDevice(ctx, m.colors, m.num_vertices);
  out.triangles = test::FromDevice(ctx, m.triangles, 3 * m.num_triangles);
  return out;
}

// V - E + F, and whether every edge has exactly two triangles with opposite orientations.
struct Topology {
  long euler = 0;
  bool closed_manifold = true;
  size_t unreferenced = 0;
};
Topology Analyse(const cpu::McMesh& m) {
  std::map<std::pair<int, int>, int> directed;
  std::set<std::pair<int, int>> undirected;
  std::vector<bool> used(m.positions_grid.size(), false);
  for (size_t t = 0; t < m.triangles.size(); t += 3) {
    for (int k = 0; k < 3; ++k) {
      int a = m.triangles[t + k], b = m.triangles[t + (k + 1) % 3];
      used[a] = true;
      directed[{a, b}]++;
      undirected.insert({std::min(a, b), std::max(a, b)});
    }
  }
  Topology topo;
  for (const auto& [e, c] : directed)
    if (c != 1 || !directed.count({e.second, e.first})) topo.closed_manifold = false;
  topo.euler = long(m.positions_grid.size()) - long(undirected.size()) + long(m.triangles.size() / 3);
  topo.unreferenced = size_t(std::count(used.begin(), used.end(), false));
  return topo;
}

TEST(McTableTest, EveryConfigurationFitsAndComplementsAgree) {
  const McTable& t = GetMcTable();
  EXPECT_EQ(t.counts[0], 0);
  EXPECT_EQ(t.counts[255], 0);
  for (int c = 0; c < 256; ++c) EXPECT_LE(t.counts[c], kMcMaxTrianglesPerCell);
  // A single inside corner gives one triangle.
  EXPECT_EQ(t.counts[1], 1);
  EXPECT_EQ(t.counts[128], 1);
}

TEST(MarchingCubesTest, SphereIsAccurateClosedAndGenusZero) {
  const float voxel = 0.01f, r = 0.2f, c = 0.32f;
  Grid g = Coloured(test::MakeSphereVolume(Cube(64, voxel), c, c, c, r));
  const cpu::McMesh m = cpu::MarchingCubes(g.tsdf.data(), g.weight.data(), g.color.data(), g.vol);
  ASSERT_GT(m.triangles.size(), 3000u);
  double worst = 0;
  for (size_t i = 0; i < m.positions_grid.size(); ++i) {
    const auto& p = m.positions_grid[i];
    const double d = std::sqrt(std::pow(p.x * voxel - c, 2) + std::pow(p.y * voxel - c, 2) + std::pow(p.z * voxel - c, 2)) - r;
    worst = std::max(worst, std::fabs(d));
    // Normals point outwards.
    const double dot = m.normals[i].x * (p.x * voxel - c) + m.normals[i].y * (p.y * voxel - c) + m.normals[i].z * (p.z * voxel - c);
    EXPECT_GT(dot, 0.0);
  }
  EXPECT_LT(worst, 0.1 * voxel) << "worst vertex distance " << worst;
  const Topology topo = Analyse(m);
  EXPECT_TRUE(topo.closed_manifold);
  EXPECT_EQ(topo.euler, 2);
  EXPECT_EQ(topo.unreferenced, 0u);
  // Triangles wind counter-clockwise seen from outside: the enclosed signed volume is the
  // sphere's, and all but a few slivers face outwards.
  int outward = 0;
  double volume = 0;
  for (size_t t = 0; t < m.triangles.size(); t += 3) {
    const auto& a = m.positions_grid[m.triangles[t]];
    const auto& b = m.positions_grid[m.triangles[t + 1]];
    const auto& d = m.positions_grid[m.triangles[t + 2]];
    const vd_float4 n = vd_cross3(b - a, d - a);
    outward += vd_dot3(n, a - VD_F4(c / voxel, c / voxel, c / voxel, 1)) > 0;
    volume += vd_dot3(a, vd_cross3(b, d)) / 6.0 * voxel * voxel * voxel;
  }
  EXPECT_GT(outward, 0.995 * (m.triangles.size() / 3));
  EXPECT_NEAR(volume, 4.0 / 3.0 * M_PI * r * r * r, 0.01 * 4.0 / 3.0 * M_PI * r * r * r);
}

TEST(MarchingCubesTest, PlaneIsFlat) {
  const float voxel = 0.01f;
  // A tilted plane through the grid; only the cells it crosses produce triangles.
  const float norm = std::sqrt(1.f + 0.09f + 0.04f);
  auto plane = [&](float x, float y, float z) { return (z - 0.1035f - 0.3f * x - 0.2f * y) / norm; };
  Grid g = Coloured(test::MakeAnalyticVolume(Cube(40, voxel), plane));
  const cpu::McMesh m = cpu::MarchingCubes(g.tsdf.data(), g.weight.data(), g.color.data(), g.vol);
  ASSERT_GT(m.triangles.size(), 1000u);
  double worst = 0;
  for (const auto& p : m.positions_grid)
    worst = std::max(worst, std::fabs(double(plane(p.x * voxel, p.y * voxel, p.z * voxel))));
  EXPECT_LT(worst, 1e-4);
  // An open sheet over the grid: disc topology, Euler characteristic 1.
  EXPECT_EQ(Analyse(m).euler, 1);
}

TEST(MarchingCubesTest, UnobservedCornersProduceNoTriangles) {
  const float voxel = 0.01f, r = 0.2f, c = 0.32f;
  Grid g = Coloured(test::MakeSphereVolume(Cube(64, voxel), c, c, c, r));
  // Forget the half with x > c: the mesh becomes a hemisphere with an open rim, still welded.
  for (int z = 0; z < 64; ++z)
    for (int y = 0; y < 64; ++y)
      for (int x = 33; x < 64; ++x) g.weight[x + 64 * (y + 64 * z)] = 0.f;
  const cpu::McMesh m = cpu::MarchingCubes(g.tsdf.data(), g.weight.data(), g.color.data(), g.vol);
  for (const auto& p : m.positions_grid) EXPECT_LE(p.x, 33.f);
  const Topology topo = Analyse(m);
  EXPECT_EQ(topo.unreferenced, 0u);
  EXPECT_EQ(topo.euler, 1);
}

TEST(MarchingCubesParityTest, DeviceMatchesCpuOnSphereAndTorus) {
  VD_REQUIRE_OCL(ctx);
  const float voxel = 0.01f, c = 0.32f;
  for (int shape = 0; shape < 2; ++shape) {
    Grid g = Coloured(shape == 0 ? test::MakeSphereVolume(Cube(64, voxel), c, c, c, 0.2f)
                                 : test::MakeAnalyticVolume(Cube(64, voxel), [&](float x, float y, float z) {
                                     const float q = std::sqrt((x - c) * (x - c) + (y - c) * (y - c)) - 0.18f;
                                     return std::sqrt(q * q + (z - c) * (z - c)) - 0.07f;
                                   }));
    const cpu::McMesh ref = cpu::MarchingCubes(g.tsdf.data(), g.weight.data(), g.color.data(), g.vol);
    const cpu::McMesh dev = RunOcl(ctx, g);
    ASSERT_EQ(dev.positions_grid.size(), ref.positions_grid.size());
    ASSERT_EQ(dev.triangles.size(), ref.triangles.size());
    EXPECT_EQ(dev.triangles, ref.triangles);
    EXPECT_TRUE(test::AllClose(test::Flatten(dev.positions_grid), test::Flatten(ref.positions_grid), 1e-5f, 1e-6f));
    EXPECT_TRUE(test::AllClose(test::Flatten(dev.normals), test::Flatten(ref.normals), 1e-5f, 1e-5f));
    EXPECT_EQ(dev.colors, ref.colors);
    const Topology topo = Analyse(ref);
    EXPECT_TRUE(topo.closed_manifold);
    EXPECT_EQ(topo.euler, shape == 0 ? 2 : 0);
  }
}

}  // namespace
}  // namespace vd
