#include "ocl/mc_table.h"

#include <cassert>
#include <cstdlib>
#include <vector>

#include <Eigen/Geometry>

namespace vd {
namespace {

Eigen::Vector3f Corner(int i) { return Eigen::Vector3f(float(i & 1), float((i >> 1) & 1), float((i >> 2) & 1)); }

// The two corners of edge e (numbering as in marching_cubes.h).
void EdgeCorners(int e, int* c0, int* c1) {
  const int axis = e >> 2, b0 = e & 1, b1 = (e >> 1) & 1;
  int o[3];
  o[axis] = 0;
  o[axis == 0 ? 1 : 0] = b0;
  o[axis == 2 ? 1 : 2] = b1;
  *c0 = o[0] | (o[1] << 1) | (o[2] << 2);
  *c1 = *c0 | (1 << axis);
}

int EdgeBetween(int ca, int cb) {
  for (int e = 0; e < 12; ++e) {
    int c0, c1;
    EdgeCorners(e, &c0, &c1);
    if ((c0 == ca && c1 == cb) || (c0 == cb && c1 == ca)) return e;
  }
  return -1;
}

Eigen::Vector3f EdgeMid(int e) {
  int c0, c1;
  EdgeCorners(e, &c0, &c1);
  return 0.5f * (Corner(c0) + Corner(c1));
}

McTable Build() {
  McTable table;
  table.triangles.fill(-1);
  table.counts.fill(0);
  for (int code = 0; code < 256; ++code) {
    auto inside = [code](int c) { return ((code >> c) & 1) != 0; };
    int next[12];
    for (int& n : next) n = -1;
    for (int axis = 0; axis < 3; ++axis) {
      for (int side = 0; side < 2; ++side) {
        Eigen::Vector3f n = Eigen::Vector3f::Zero();
        n[axis] = side ? 1.f : -1.f;
        // Face corners in cyclic order.
        const int u = (axis + 1) % 3, v = (axis + 2) % 3;
        int ring[4];
        const int uv[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
        for (int k = 0; k < 4; ++k) ring[k] = (side << axis) | (uv[k][0] << u) | (uv[k][1] << v);
        int num_inside = 0;
        for (int c : ring) num_inside += inside(c);
        if (num_inside == 0 || num_inside == 4) continue;
        // Each segment: two crossing edges and a reference point on the inside side.
        struct Seg {
          int a, b;
          Eigen::Vector3f ref;
        };
        std::vector<Seg> segs;
        const bool diagonal = num_inside == 2 && inside(ring[0]) == inside(ring[2]);
        if (diagonal) {
          // Ambiguous face: each inside corner is cut off on its own.
          for (int k = 0; k < 4; ++k) {
            if (!inside(ring[k])) continue;
            segs.push_back({EdgeBetween(ring[k], ring[(k + 3) % 4]), EdgeBetween(ring[k], ring[(k + 1) % 4]),
                            Corner(ring[k])});
          }
        } else {
          std::vector<int> crossings;
          Eigen::Vector3f ref = Eigen::Vector3f::Zero();
          for (int k = 0; k < 4; ++k) {
            if (inside(ring[k]) != inside(ring[(k + 1) % 4])) crossings.push_back(EdgeBetween(ring[k], ring[(k + 1) % 4]));
            if (inside(ring[k])) ref += Corner(ring[k]);
          }
          assert(crossings.size() == 2);
          segs.push_back({crossings[0], crossings[1], ref / float(num_inside)});
        }
        for (Seg s : segs) {
          const Eigen::Vector3f A = EdgeMid(s.a), B = EdgeMid(s.b);
          // Orient so that ((B - A) x (ref - A)) . n < 0: the loop then fans into triangles
          // whose normals point from the inside (negative) to the outside.
          if ((B - A).cross(s.ref - A).dot(n) > 0.f) std::swap(s.a, s.b);
          if (next[s.a] != -1) std::abort();  // Inconsistent orientation: a bug in this generator.
          next[s.a] = s.b;
        }
      }
    }
    int8_t* out = &table.triangles[code * 16];
    int count = 0;
    bool used[12] = {};
    for (int start = 0; start < 12; ++start) {
      if (next[start] == -1 || used[start]) continue;
      std::vector<int> loop;
      for (int e = start; !used[e]; e = next[e]) {
        used[e] = true;
        loop.push_back(e);
        if (next[e] == -1) std::abort();
      }
      for (size_t i = 1; i + 1 < loop.size(); ++i) {
        if (count >= kMcMaxTrianglesPerCell) std::abort();
        out[3 * count + 0] = int8_t(loop[0]);
        out[3 * count + 1] = int8_t(loop[i]);
        out[3 * count + 2] = int8_t(loop[i + 1]);
        ++count;
      }
    }
    table.counts[code] = uint8_t(count);
  }
  return table;
}

}  // namespace

const McTable& GetMcTable() {
  static const McTable table = Build();
  return table;
}

}  // namespace vd
