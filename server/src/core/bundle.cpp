#include "core/bundle.h"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <unordered_map>

#include "vd/common/flags.h"

namespace vd {
namespace {

// A point's trilinear stencil on the correction grid: 8 nodes (global unknown indices) and weights.
struct Stencil {
  std::array<int, 8> node{};
  std::array<double, 8> weight{};
};

// One free frame's nodes: grid cell corner -> unknown index.
struct NodeKey {
  int x, y, z;
  bool operator==(const NodeKey& o) const { return x == o.x && y == o.y && z == o.z; }
};
struct NodeKeyHash {
  size_t operator()(const NodeKey& k) const {
    return size_t(uint32_t(k.x) * 73856093u ^ uint32_t(k.y) * 19349663u ^ uint32_t(k.z) * 83492791u);
  }
};

}  // namespace

bool IsBundlePoint(const vd_float4& p) {
  return p.w > 0.f && std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

Status BundleParams::Validate() const {
  if (!(keyframes >= 0 && keyframes <= 1024))
    return ParamOutOfBounds("BundleParams", "keyframes", keyframes, "0..1024");
  if (!(cell_voxels >= 1.f && cell_voxels <= 256.f))
    return ParamOutOfBounds("BundleParams", "cell_voxels", cell_voxels, "1..256");
  if (!(smoothness >= 0.f && smoothness <= 1e6f))
    return ParamOutOfBounds("BundleParams", "smoothness", smoothness, "0..1e6");
  if (!(prior > 0.f && prior <= 1e6f)) return ParamOutOfBounds("BundleParams", "prior", prior, "0 < prior <= 1e6");
  if (!(huber_voxels > 0.f)) return ParamOutOfBounds("BundleParams", "huber_voxels", huber_voxels, "> 0");
  if (!(iterations >= 1 && iterations <= 20))
    return ParamOutOfBounds("BundleParams", "iterations", iterations, "1..20");
  return Status::Ok();
}

void BundleParams::Bind(FlagParser* f) {
  f->Section("Keyframe bundle adjustment of the sparse features (docs/NONRIGID.md)");
  f->Add("ba-keyframes", &keyframes,
         "Newest keyframes whose feature points the adjustment corrects, each time a frame becomes a keyframe; "
         "older ones and the first frame stay fixed (0 = off)");
  f->Add("ba-cell-voxels", &cell_voxels, "Spacing of each frame's correction grid, voxels");
  f->Add("ba-smoothness", &smoothness, "Weight of smoothness between neighbouring correction nodes, per matched pair");
  f->Add("ba-prior", &prior, "Weight keeping a correction node without evidence at zero, per matched pair");
  f->Add("ba-huber-voxels", &huber_voxels,
         "Matched features disagreeing by more than this count linearly (wrong matches), voxels");
  f->Add("ba-iterations", &iterations, "Reweighting passes of the adjustment (one factorisation each)");
}

Status SolveBundle(const BundleParams& params, const std::vector<char>& free, const std::vector<BundleLink>& links,
                   std::vector<std::vector<vd_float4>>* points, BundleStats* stats) {
  *stats = BundleStats();
  std::vector<std::vector<vd_float4>>& pts = *points;
  const int num_frames = int(pts.size());
  if (int(free.size()) != num_frames) return InvalidArgument("bundle: one free flag per frame expected");
  for (const BundleLink& l : links) {
    for (auto [f, i] : {std::pair{l.frame_a, l.feature_a}, std::pair{l.frame_b, l.feature_b}}) {
      if (f < 0 || f >= num_frames || i < 0 || i >= int(pts[f].size()))
        return InvalidArgument("bundle: a link names frame " + std::to_string(f) + " feature " + std::to_string(i) +
                               ", which the problem does not have");
      if (!IsBundlePoint(pts[f][i])) return InvalidArgument("bundle: a link names an invalid point");
    }
  }
  // The links that move something.
  std::vector<const BundleLink*> active;
  for (const BundleLink& l : links)
    if ((free[l.frame_a] || free[l.frame_b]) && !(l.frame_a == l.frame_b && l.feature_a == l.feature_b))
      active.push_back(&l);
  stats->links = int(active.size());
  for (int f = 0; f < num_frames; ++f) stats->free_frames += free[f] ? 1 : 0;
  if (active.empty()) return Status::Ok();

  // Nodes of each free frame's correction grid, created on first touch.
  const double h = params.cell_voxels;
  std::vector<std::unordered_map<NodeKey, int, NodeKeyHash>> nodes(num_frames);
  std::vector<NodeKey> node_keys;
  std::vector<int> node_frame;
  auto stencil = [&](int f, const vd_float4& p, bool create, Stencil* s) {
    const double gx = p.x / h, gy = p.y / h, gz = p.z / h;
    const int x0 = int(std::floor(gx)), y0 = int(std::floor(gy)), z0 = int(std::floor(gz));
    const double fx = gx - x0, fy = gy - y0, fz = gz - z0;
    for (int c = 0; c < 8; ++c) {
      const NodeKey k{x0 + (c & 1), y0 + ((c >> 1) & 1), z0 + ((c >> 2) & 1)};
      auto it = nodes[f].find(k);
      if (it == nodes[f].end()) {
        if (!create) {
          s->node[c] = -1;
          s->weight[c] = 0.0;
          continue;
        }
        it = nodes[f].emplace(k, int(node_keys.size())).first;
        node_keys.push_back(k);
        node_frame.push_back(f);
      }
      s->node[c] = it->second;
      s->weight[c] = ((c & 1) ? fx : 1.0 - fx) * (((c >> 1) & 1) ? fy : 1.0 - fy) * (((c >> 2) & 1) ? fz : 1.0 - fz);
    }
  };
  // The corners of every cell holding a valid point of a free frame: unlinked points (features no
  // later frame matched yet, or that matched only frames of the same drift) move with the
  // correction their linked neighbours find, through the smoothness.
  std::vector<char> linked(num_frames, 0);
  for (const BundleLink* l : active) linked[l->frame_a] = linked[l->frame_b] = 1;
  for (int f = 0; f < num_frames; ++f) {
    if (!free[f] || !linked[f]) continue;
    Stencil s;
    for (const vd_float4& p : pts[f])
      if (IsBundlePoint(p)) stencil(f, p, true, &s);
  }
  const int n = int(node_keys.size());
  const int m = int(active.size());
  stats->nodes = n;
  // The links as rows J D + c: J holds +w (side a's stencil) and -w (side b's; a fixed side has
  // none), c the uncorrected disagreement.
  std::vector<Eigen::Triplet<double>> triplets;
  Eigen::MatrixX3d c(m, 3);
  for (int k = 0; k < m; ++k) {
    const BundleLink& l = *active[k];
    const vd_float4& pa = pts[l.frame_a][l.feature_a];
    const vd_float4& pb = pts[l.frame_b][l.feature_b];
    c.row(k) << double(pa.x) - pb.x, double(pa.y) - pb.y, double(pa.z) - pb.z;
    for (int side = 0; side < 2; ++side) {
      const int f = side == 0 ? l.frame_a : l.frame_b;
      if (!free[f]) continue;
      Stencil st;
      stencil(f, pts[f][side == 0 ? l.feature_a : l.feature_b], false, &st);
      for (int corner = 0; corner < 8; ++corner)
        if (st.node[corner] >= 0 && st.weight[corner] != 0.0)
          triplets.emplace_back(k, st.node[corner], side == 0 ? st.weight[corner] : -st.weight[corner]);
    }
  }
  Eigen::SparseMatrix<double> J(m, n);
  J.setFromTriplets(triplets.begin(), triplets.end());
  // Smoothness between a frame's nodes that are grid neighbours, and the prior: the constant part
  // of the normal equations.
  triplets.clear();
  for (int a = 0; a < n; ++a) {
    triplets.emplace_back(a, a, params.prior);
    const NodeKey& k = node_keys[a];
    for (const NodeKey& nb : {NodeKey{k.x + 1, k.y, k.z}, NodeKey{k.x, k.y + 1, k.z}, NodeKey{k.x, k.y, k.z + 1}}) {
      auto it = nodes[node_frame[a]].find(nb);
      if (it == nodes[node_frame[a]].end()) continue;
      const int b = it->second;
      triplets.emplace_back(a, a, params.smoothness);
      triplets.emplace_back(b, b, params.smoothness);
      triplets.emplace_back(a, b, -params.smoothness);
      triplets.emplace_back(b, a, -params.smoothness);
    }
  }
  Eigen::SparseMatrix<double> R(n, n);
  R.setFromTriplets(triplets.begin(), triplets.end());

  const double huber = params.huber_voxels;
  Eigen::MatrixX3d D = Eigen::MatrixX3d::Zero(n, 3);
  Eigen::VectorXd e = c.rowwise().norm();
  auto rms_of = [&](const Eigen::VectorXd& norms) {
    stats->outliers = int((norms.array() > huber).count());
    return std::sqrt(norms.squaredNorm() / double(m));
  };
  stats->rms_before = rms_of(e);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
  for (int it = 0; it < params.iterations; ++it) {
    // Huber weights from the disagreements under the current corrections (IRLS).
    const Eigen::VectorXd w = (e.array() > huber).select(huber / e.array(), 1.0);
    const Eigen::SparseMatrix<double> A = Eigen::SparseMatrix<double>(J.transpose() * w.asDiagonal() * J) + R;
    // The pattern is the same in every pass: ordered and analysed once.
    if (it == 0) solver.analyzePattern(A);
    solver.factorize(A);
    if (solver.info() != Eigen::Success) return Internal("bundle: the normal equations could not be factorised");
    D = solver.solve(-(J.transpose() * (w.asDiagonal() * c)));
    if (solver.info() != Eigen::Success || !D.allFinite()) return Internal("bundle: the solve failed");
    e = (J * D + c).rowwise().norm();
  }
  stats->rms_after = rms_of(e);

  // Every valid point of a free frame moves by its frame's correction.
  for (int f = 0; f < num_frames; ++f) {
    if (!free[f] || nodes[f].empty()) continue;
    for (vd_float4& p : pts[f]) {
      if (!IsBundlePoint(p)) continue;
      Stencil s;
      stencil(f, p, false, &s);
      Eigen::RowVector3d d = Eigen::RowVector3d::Zero();
      for (int c = 0; c < 8; ++c)
        if (s.node[c] >= 0) d += s.weight[c] * D.row(s.node[c]);
      p.x = float(p.x + d.x());
      p.y = float(p.y + d.y());
      p.z = float(p.z + d.z());
    }
  }
  return Status::Ok();
}

}  // namespace vd
