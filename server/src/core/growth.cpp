#include "core/growth.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "shared/brick_hash.h"
#include "shared/raster.h"
#include "shared/tsdf.h"

namespace vd {
namespace {

// Nearest (chamfer distance) sample with a displacement, for every sample of a w x h grid: two
// passes of the 3x3 chamfer propagation; -1 where none lies within `search`.
std::vector<int> NearestValid(const std::vector<uint8_t>& valid, int w, int h, int search, std::vector<int>* chamfer) {
  const int inf = std::numeric_limits<int>::max() / 4;
  std::vector<int> dist(size_t(w) * h, inf), from(size_t(w) * h, -1);
  for (int i = 0; i < w * h; ++i)
    if (valid[i]) dist[i] = 0, from[i] = i;
  auto relax = [&](int i, int j, int cost) {
    if (dist[j] + cost < dist[i]) dist[i] = dist[j] + cost, from[i] = from[j];
  };
  // Costs 3 (edge) and 4 (diagonal): about 3 per sample step.
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int i = y * w + x;
      if (x > 0) relax(i, i - 1, 3);
      if (y > 0) {
        relax(i, i - w, 3);
        if (x > 0) relax(i, i - w - 1, 4);
        if (x + 1 < w) relax(i, i - w + 1, 4);
      }
    }
  for (int y = h - 1; y >= 0; --y)
    for (int x = w - 1; x >= 0; --x) {
      const int i = y * w + x;
      if (x + 1 < w) relax(i, i + 1, 3);
      if (y + 1 < h) {
        relax(i, i + w, 3);
        if (x + 1 < w) relax(i, i + w + 1, 4);
        if (x > 0) relax(i, i + w - 1, 4);
      }
    }
  for (int i = 0; i < w * h; ++i)
    if (dist[i] > 3 * search) from[i] = -1;
  *chamfer = std::move(dist);
  return from;
}

// Orthonormal frame (columns e1, e2, n) of a triangle; false when degenerate.
bool Frame(const vd_float4 p[3], vd_float4 f[3]) {
  vd_float4 e1 = p[1] - p[0], e2 = p[2] - p[0];
  e1.w = e2.w = 0.f;
  vd_float4 n = vd_cross3(e1, e2);
  const float l1 = std::sqrt(vd_dot3(e1, e1)), ln = std::sqrt(vd_dot3(n, n));
  if (!(l1 > 1e-9f && ln > 1e-12f)) return false;
  f[0] = e1 * (1.f / l1);
  f[2] = n * (1.f / ln);
  f[1] = vd_cross3(f[2], f[0]);
  return true;
}

// The rigid motion of the rendered surface around sample j: Kabsch (Eigen::umeyama, no scale) over
// the vertices of the triangles rendered at the samples of the 5 x 5 window around it, which is
// steadier than one small triangle's; one triangle's (TriangleMotion) with fewer than 6 vertices.
VdPose LocalMotion(int j, int w, int h, const std::vector<int32_t>& tri_of, const int32_t* tris,
                   const vd_float4* deformed, const vd_float4* grid, float voxel_size) {
  std::vector<int32_t> verts;
  const int jx = j % w, jy = j / w;
  for (int y = std::max(0, jy - 2); y <= std::min(h - 1, jy + 2); ++y)
    for (int x = std::max(0, jx - 2); x <= std::min(w - 1, jx + 2); ++x) {
      const int32_t t = tri_of[size_t(y) * w + x];
      if (t < 0) continue;
      for (int a = 0; a < 3; ++a) verts.push_back(tris[3 * size_t(t) + a]);
    }
  std::sort(verts.begin(), verts.end());
  verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
  const int32_t t = tri_of[j];
  if (verts.size() < 6) {
    vd_float4 c[3], d[3];
    for (int a = 0; a < 3; ++a) {
      const int32_t k = tris[3 * size_t(t) + a];
      c[a] = VD_F4(voxel_size * grid[k].x, voxel_size * grid[k].y, voxel_size * grid[k].z, 1.f);
      d[a] = VD_F4(deformed[k].x, deformed[k].y, deformed[k].z, 1.f);
    }
    return TriangleMotion(c, d);
  }
  Eigen::Matrix3Xd src(3, verts.size()), dst(3, verts.size());
  for (size_t q = 0; q < verts.size(); ++q) {
    const int32_t k = verts[q];
    src.col(Eigen::Index(q)) << voxel_size * grid[k].x, voxel_size * grid[k].y, voxel_size * grid[k].z;
    dst.col(Eigen::Index(q)) << deformed[k].x, deformed[k].y, deformed[k].z;
  }
  const Eigen::Matrix4d a = Eigen::umeyama(src, dst, false);
  VdPose m{};
  m.r0 = VD_F4(float(a(0, 0)), float(a(0, 1)), float(a(0, 2)), float(a(0, 3)));
  m.r1 = VD_F4(float(a(1, 0)), float(a(1, 1)), float(a(1, 2)), float(a(1, 3)));
  m.r2 = VD_F4(float(a(2, 0)), float(a(2, 1)), float(a(2, 2)), float(a(2, 3)));
  return m;
}

}  // namespace

VdPose TriangleMotion(const vd_float4 c[3], const vd_float4 d[3]) {
  VdPose m{};
  vd_float4 fc[3], fd[3];
  float r[3][3] = {{1.f, 0.f, 0.f}, {0.f, 1.f, 0.f}, {0.f, 0.f, 1.f}};
  if (Frame(c, fc) && Frame(d, fd)) {
    // R = Fd Fc^T: R fc_k = fd_k.
    const float* a[3] = {&fd[0].x, &fd[1].x, &fd[2].x};
    const float* b[3] = {&fc[0].x, &fc[1].x, &fc[2].x};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) r[i][j] = a[0][i] * b[0][j] + a[1][i] * b[1][j] + a[2][i] * b[2][j];
  }
  // t = d0 - R c0.
  const float t[3] = {d[0].x - (r[0][0] * c[0].x + r[0][1] * c[0].y + r[0][2] * c[0].z),
                      d[0].y - (r[1][0] * c[0].x + r[1][1] * c[0].y + r[1][2] * c[0].z),
                      d[0].z - (r[2][0] * c[0].x + r[2][1] * c[0].y + r[2][2] * c[0].z)};
  m.r0 = VD_F4(r[0][0], r[0][1], r[0][2], t[0]);
  m.r1 = VD_F4(r[1][0], r[1][1], r[1][2], t[1]);
  m.r2 = VD_F4(r[2][0], r[2][1], r[2][2], t[2]);
  return m;
}

std::vector<GrowthBrick> PlanGrowth(const cv::Mat& depth, float inv_scale, float min_depth, float max_depth,
                                    const VdCamera& cam, const VdPose& cam_to_world, const uint32_t* ids,
                                    const int32_t* tris, size_t num_triangles, const vd_float4* deformed,
                                    const vd_float4* grid, float voxel_size, float truncation,
                                    const GrowthParams& params) {
  const int s = std::max(1, params.stride);
  const int w = (cam.width + s - 1) / s, h = (cam.height + s - 1) / s;
  const VdPose world_to_cam = vd_pose_inverse(cam_to_world);
  // Per sample: the displacement of the surface rendered there (valid) and whether its depth is
  // explained by it.
  std::vector<uint8_t> has_disp(size_t(w) * h, 0), unexplained(size_t(w) * h, 0);
  std::vector<int32_t> tri_of(size_t(w) * h, -1);
  std::vector<vd_float4> observed(size_t(w) * h);
  const float band = params.explained_truncations * truncation;
  int unexplained_count = 0;
  for (int sy = 0; sy < h; ++sy)
    for (int sx = 0; sx < w; ++sx) {
      const int u = sx * s, v = sy * s, i = sy * w + sx;
      const size_t pix = size_t(v) * cam.width + u;
      const uint32_t t = ids[pix];
      float rendered_z = -1.f;
      if (t != VD_RASTER_EMPTY && size_t(t) < num_triangles) {
        tri_of[i] = int32_t(t);
        has_disp[i] = 1;
        const vd_float4 d = deformed[tris[3 * size_t(t)]];
        rendered_z = vd_pose_apply(world_to_cam, VD_F4(d.x, d.y, d.z, 1.f)).z;
      }
      const float z = float(depth.at<uint16_t>(v, u)) * inv_scale;
      if (!(z >= min_depth && z <= max_depth)) continue;
      if (rendered_z > 0.f && std::fabs(rendered_z - z) <= band) continue;
      const vd_float4 pc = VD_F4((float(u) - cam.cx) / cam.fx * z, (float(v) - cam.cy) / cam.fy * z, z, 1.f);
      observed[i] = vd_pose_apply(cam_to_world, pc);
      unexplained[i] = 1;
      ++unexplained_count;
    }
  // The samples that grow are some of the unexplained ones: too few, and the frame grows nothing
  // (most frames; the distance transform below is the plan's larger cost).
  if (unexplained_count < params.min_frame_samples) return {};
  std::vector<int> chamfer;
  const std::vector<int> nearest = NearestValid(has_disp, w, h, params.search, &chamfer);
  const vd_float4 eye = VD_F4(cam_to_world.r0.w, cam_to_world.r1.w, cam_to_world.r2.w, 1.f);
  VdPose identity{};
  identity.r0 = VD_F4(1.f, 0.f, 0.f, 0.f);
  identity.r1 = VD_F4(0.f, 1.f, 0.f, 0.f);
  identity.r2 = VD_F4(0.f, 0.f, 1.f, 0.f);
  // The motion at each sample some unexplained one takes it from, computed once.
  std::unordered_map<int, VdPose> motions;
  std::unordered_map<uint32_t, GrowthBrick> bricks;
  const float brick = VD_BRICK * voxel_size;
  int grown = 0;
  for (int i = 0; i < w * h; ++i) {
    // Depth right beside the rendered surface is its edge seen a little differently: the active
    // set's one-ring and the gated fusion take it in.
    if (!unexplained[i] || chamfer[i] < 3 * params.min_gap) continue;
    ++grown;
    VdPose m = identity;
    if (nearest[i] >= 0) {
      auto it = motions.find(nearest[i]);
      if (it == motions.end())
        it = motions.emplace(nearest[i], LocalMotion(nearest[i], w, h, tri_of, tris, deformed, grid, voxel_size)).first;
      m = it->second;
    }
    const VdPose m_inv = vd_pose_inverse(m);
    const vd_float4 f = observed[i];
    vd_float4 ray = VD_F4(f.x - eye.x, f.y - eye.y, f.z - eye.z, 0.f);
    ray = ray * (1.f / std::max(1e-6f, std::sqrt(vd_dot3(ray, ray))));
    // The truncation band around the canonical point, along the viewing ray taken back with it.
    const vd_float4 g = vd_pose_apply(m_inv, f), ray_c = vd_pose_rotate(m_inv, ray);
    for (float o : {-truncation, 0.f, truncation}) {
      const float gx = g.x + o * ray_c.x, gy = g.y + o * ray_c.y, gz = g.z + o * ray_c.z;
      const int bx = int(std::floor(gx / brick)), by = int(std::floor(gy / brick)), bz = int(std::floor(gz / brick));
      if (!vd_brick_coords_valid(bx, by, bz)) continue;
      GrowthBrick& b = bricks[vd_brick_pack(bx, by, bz)];
      if (b.samples == 0) b.key = vd_brick_pack(bx, by, bz), b.motion = m;
      ++b.samples;
    }
  }
  std::vector<GrowthBrick> out;
  if (grown < params.min_frame_samples) return out;
  for (auto& [key, b] : bricks) {
    if (b.samples < params.min_samples) continue;
    out.push_back(b);
  }
  std::sort(out.begin(), out.end(), [](const GrowthBrick& a, const GrowthBrick& b) {
    return a.samples != b.samples ? a.samples > b.samples : a.key < b.key;
  });
  if (out.size() > size_t(std::max(0, params.max_bricks))) out.resize(size_t(std::max(0, params.max_bricks)));
  return out;
}

}  // namespace vd
