// Exact closest point on a triangle mesh, accelerated by an axis-aligned bounding-box tree.
#include <algorithm>
#include <cmath>
#include <limits>

#include "vd/capture/synthetic.h"

namespace vd {
namespace {

// Leaves this small keep the number of exact point-triangle tests per query low.
constexpr int kLeafSize = 4;

struct Node {
  Eigen::Vector3f lo;
  Eigen::Vector3f hi;
  // Leaf: [first, first + count) of the triangle order; interior: count = 0, children are the
  // next node and `right`.
  int32_t first = 0;
  int32_t count = 0;
  int32_t right = -1;
};

struct TriangleHit {
  Eigen::Vector3f point;
  float b0 = 1.f, b1 = 0.f, b2 = 0.f;
};

// Closest point on segment a-b; t is the weight of b.
inline Eigen::Vector3f ClosestOnSegment(const Eigen::Vector3f& p, const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                                        float* t) {
  const Eigen::Vector3f ab = b - a;
  const float len2 = ab.squaredNorm();
  *t = len2 > 0.f ? std::clamp((p - a).dot(ab) / len2, 0.f, 1.f) : 0.f;
  return a + *t * ab;
}

// Closest point of triangle (a, b, c) to p by the Voronoi regions of its vertices, edges and
// face; degenerate triangles fall back to the nearest of their edges.
TriangleHit ClosestOnTriangle(const Eigen::Vector3f& p, const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                              const Eigen::Vector3f& c) {
  TriangleHit r;
  const Eigen::Vector3f ab = b - a, ac = c - a, ap = p - a;
  const float d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.f && d2 <= 0.f) {
    r.point = a;
    return r;
  }
  const Eigen::Vector3f bp = p - b;
  const float d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.f && d4 <= d3) {
    r.point = b;
    r.b0 = 0.f;
    r.b1 = 1.f;
    return r;
  }
  const float vc = d1 * d4 - d3 * d2;
  if (vc <= 0.f && d1 >= 0.f && d3 <= 0.f && d1 - d3 > 0.f) {
    const float v = d1 / (d1 - d3);
    r.point = a + v * ab;
    r.b0 = 1.f - v;
    r.b1 = v;
    return r;
  }
  const Eigen::Vector3f cp = p - c;
  const float d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.f && d5 <= d6) {
    r.point = c;
    r.b0 = 0.f;
    r.b2 = 1.f;
    return r;
  }
  const float vb = d5 * d2 - d1 * d6;
  if (vb <= 0.f && d2 >= 0.f && d6 <= 0.f && d2 - d6 > 0.f) {
    const float w = d2 / (d2 - d6);
    r.point = a + w * ac;
    r.b0 = 1.f - w;
    r.b2 = w;
    return r;
  }
  const float va = d3 * d6 - d5 * d4;
  if (va <= 0.f && (d4 - d3) >= 0.f && (d5 - d6) >= 0.f && (d4 - d3) + (d5 - d6) > 0.f) {
    const float w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    r.point = b + w * (c - b);
    r.b0 = 0.f;
    r.b1 = 1.f - w;
    r.b2 = w;
    return r;
  }
  const float denom = va + vb + vc;
  if (denom > 0.f && std::isfinite(denom)) {
    const float v = vb / denom, w = vc / denom;
    r.point = a + v * ab + w * ac;
    r.b0 = 1.f - v - w;
    r.b1 = v;
    r.b2 = w;
    return r;
  }
  // Degenerate (collinear or coincident vertices): the nearest point of the three edges.
  float t = 0.f, best = std::numeric_limits<float>::infinity();
  const Eigen::Vector3f e0 = ClosestOnSegment(p, a, b, &t);
  if ((e0 - p).squaredNorm() < best) {
    best = (e0 - p).squaredNorm();
    r = TriangleHit{e0, 1.f - t, t, 0.f};
  }
  const Eigen::Vector3f e1 = ClosestOnSegment(p, b, c, &t);
  if ((e1 - p).squaredNorm() < best) {
    best = (e1 - p).squaredNorm();
    r = TriangleHit{e1, 0.f, 1.f - t, t};
  }
  const Eigen::Vector3f e2 = ClosestOnSegment(p, c, a, &t);
  if ((e2 - p).squaredNorm() < best) r = TriangleHit{e2, t, 0.f, 1.f - t};
  return r;
}

inline float BoxDistance2(const Node& n, const Eigen::Vector3f& p) {
  const Eigen::Vector3f d = (n.lo - p).cwiseMax(p - n.hi).cwiseMax(0.f);
  return d.squaredNorm();
}


// A usable triangle in tree order, vertices interleaved so a leaf is a few cache lines.
struct PackedTriangle {
  Eigen::Vector3f a, b, c;
  // Index in the input mesh.
  int32_t id = -1;
};

}  // namespace

struct MeshDistance::Impl {
  std::vector<PackedTriangle> triangles;
  std::vector<Node> nodes;

  int32_t Build(std::vector<int32_t>& order, std::vector<Eigen::Vector3f>& centroids, int32_t first, int32_t count,
                const std::vector<Eigen::Vector3f>& lo, const std::vector<Eigen::Vector3f>& hi) {
    const int32_t index = static_cast<int32_t>(nodes.size());
    nodes.emplace_back();
    Eigen::Vector3f box_lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity());
    Eigen::Vector3f box_hi = -box_lo;
    Eigen::Vector3f c_lo = box_lo, c_hi = box_hi;
    for (int32_t i = first; i < first + count; ++i) {
      const int32_t t = order[size_t(i)];
      box_lo = box_lo.cwiseMin(lo[size_t(t)]);
      box_hi = box_hi.cwiseMax(hi[size_t(t)]);
      c_lo = c_lo.cwiseMin(centroids[size_t(t)]);
      c_hi = c_hi.cwiseMax(centroids[size_t(t)]);
    }
    nodes[size_t(index)].lo = box_lo;
    nodes[size_t(index)].hi = box_hi;
    int axis = 0;
    (c_hi - c_lo).maxCoeff(&axis);
    if (count <= kLeafSize || !(c_hi[axis] > c_lo[axis])) {
      nodes[size_t(index)].first = first;
      nodes[size_t(index)].count = count;
      return index;
    }
    const int32_t half = count / 2;
    std::nth_element(order.begin() + first, order.begin() + first + half, order.begin() + first + count,
                     [&](int32_t x, int32_t y) { return centroids[size_t(x)][axis] < centroids[size_t(y)][axis]; });
    Build(order, centroids, first, half, lo, hi);
    const int32_t right = Build(order, centroids, first + half, count - half, lo, hi);
    nodes[size_t(index)].right = right;
    return index;
  }
};

MeshDistance::MeshDistance(const TriangleMesh& mesh) {
  auto impl = std::make_shared<Impl>();
  const int64_t num_vertices = static_cast<int64_t>(mesh.positions.size() / 3);
  std::vector<int32_t> usable;
  std::vector<Eigen::Vector3f> va, vb, vc;
  for (size_t t = 0; t + 2 < mesh.triangles.size(); t += 3) {
    const int32_t i0 = mesh.triangles[t], i1 = mesh.triangles[t + 1], i2 = mesh.triangles[t + 2];
    if (i0 < 0 || i1 < 0 || i2 < 0 || i0 >= num_vertices || i1 >= num_vertices || i2 >= num_vertices) continue;
    const Eigen::Vector3f p0 = Eigen::Map<const Eigen::Vector3f>(&mesh.positions[3 * size_t(i0)]);
    const Eigen::Vector3f p1 = Eigen::Map<const Eigen::Vector3f>(&mesh.positions[3 * size_t(i1)]);
    const Eigen::Vector3f p2 = Eigen::Map<const Eigen::Vector3f>(&mesh.positions[3 * size_t(i2)]);
    if (!(p0.allFinite() && p1.allFinite() && p2.allFinite())) continue;
    usable.push_back(static_cast<int32_t>(t / 3));
    va.push_back(p0);
    vb.push_back(p1);
    vc.push_back(p2);
  }
  const int32_t n = static_cast<int32_t>(usable.size());
  const size_t count = usable.size();
  std::vector<Eigen::Vector3f> lo(count), hi(count), centroids(count);
  std::vector<int32_t> order(count);
  for (int32_t i = 0; i < n; ++i) {
    lo[size_t(i)] = va[size_t(i)].cwiseMin(vb[size_t(i)]).cwiseMin(vc[size_t(i)]);
    hi[size_t(i)] = va[size_t(i)].cwiseMax(vb[size_t(i)]).cwiseMax(vc[size_t(i)]);
    centroids[size_t(i)] = (va[size_t(i)] + vb[size_t(i)] + vc[size_t(i)]) / 3.f;
    order[size_t(i)] = i;
  }
  if (n > 0) {
    impl->nodes.reserve(size_t(2 * n / kLeafSize + 16));
    impl->Build(order, centroids, 0, n, lo, hi);
  }
  impl->triangles.resize(count);
  for (size_t i = 0; i < count; ++i) {
    const size_t src = size_t(order[i]);
    impl->triangles[i] = PackedTriangle{va[src], vb[src], vc[src], usable[src]};
  }
  impl_ = std::move(impl);
}

ClosestPoint MeshDistance::Closest(const Eigen::Vector3f& p) const {
  ClosestPoint result;
  result.position = Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN());
  result.distance = std::numeric_limits<float>::infinity();
  const Impl& m = *impl_;
  if (m.nodes.empty() || !p.allFinite()) return result;
  float best2 = std::numeric_limits<float>::infinity();
  // Node and its box distance. Depth is at most ~log2(n / kLeafSize) + 2 for a median split and
  // each level leaves at most one entry behind, so 128 covers any mesh that fits in memory.
  struct Entry {
    int32_t node;
    float d2;
  };
  Entry stack[128];
  int top = 0;
  stack[top++] = Entry{0, BoxDistance2(m.nodes[0], p)};
  while (top > 0) {
    const Entry entry = stack[--top];
    if (entry.d2 >= best2) continue;
    const Node& node = m.nodes[size_t(entry.node)];
    if (node.count > 0) {
      for (int32_t i = node.first; i < node.first + node.count; ++i) {
        const PackedTriangle& tri = m.triangles[size_t(i)];
        const TriangleHit hit = ClosestOnTriangle(p, tri.a, tri.b, tri.c);
        const float d2 = (hit.point - p).squaredNorm();
        if (d2 < best2) {
          best2 = d2;
          result.position = hit.point;
          result.where = SurfacePoint{tri.id, hit.b0, hit.b1, hit.b2};
        }
      }
      continue;
    }
    const int32_t left = entry.node + 1;
    const int32_t right = node.right;
    const float dl = BoxDistance2(m.nodes[size_t(left)], p);
    const float dr = BoxDistance2(m.nodes[size_t(right)], p);
    // Nearer child on top of the stack, so it is searched first and tightens the bound.
    if (dl < dr) {
      if (dr < best2) stack[top++] = Entry{right, dr};
      if (dl < best2) stack[top++] = Entry{left, dl};
    } else {
      if (dl < best2) stack[top++] = Entry{left, dl};
      if (dr < best2) stack[top++] = Entry{right, dr};
    }
  }
  result.distance = std::sqrt(best2);
  return result;
}

Eigen::Vector3f MeshDistance::Evaluate(const TriangleMesh& mesh, const SurfacePoint& s) {
  const Eigen::Vector3f nan = Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN());
  if (s.triangle < 0 || size_t(s.triangle) >= mesh.num_triangles()) return nan;
  const int64_t num_vertices = static_cast<int64_t>(mesh.num_vertices());
  Eigen::Vector3f out = Eigen::Vector3f::Zero();
  const float w[3] = {s.b0, s.b1, s.b2};
  for (int i = 0; i < 3; ++i) {
    const int32_t v = mesh.triangles[3 * size_t(s.triangle) + size_t(i)];
    if (v < 0 || v >= num_vertices) return nan;
    out += w[i] * Eigen::Map<const Eigen::Vector3f>(&mesh.positions[3 * size_t(v)]);
  }
  return out;
}

}  // namespace vd
