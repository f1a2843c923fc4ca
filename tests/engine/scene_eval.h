#pragma once
// Runs a synthetic scene through the engine (sensor noise, 4 mm voxels, 60 frames, default
// parameters) and measures it against ground truth:
//   surface error = mean distance from live-mesh vertices to the true surface of that frame;
//   drift = mean distance between each live vertex and the true position, in that frame, of the
//   material point its canonical vertex lies on;
//   non-rigid displacement = mean distance between each live vertex and its canonical vertex moved
//   by the estimated camera pose only.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "core/engine.h"
#include "ocl/ocl.h"
#include "vd/capture/synthetic.h"

namespace vd::test {

struct SceneErrors {
  double worst_surface_mm = 0, mean_surface_mm = 0, last_drift_mm = 0, last_nonrigid_mm = 0;
};

inline Eigen::Vector3f V(const TriangleMesh& m, size_t i) {
  return Eigen::Vector3f(m.positions[3 * i], m.positions[3 * i + 1], m.positions[3 * i + 2]);
}

inline SceneErrors RunScene(const std::string& name, bool rigid_only) {
  SceneErrors out;
  SyntheticOptions so;
  so.noise = true;
  so.num_frames = 60;
  auto scene = MakeSyntheticScene(name, so);
  EXPECT_TRUE(scene.ok());
  EngineParams p;
  p.rigid_only = rigid_only;
  auto engine = Engine::Create(p, "");
  EXPECT_TRUE(engine.ok()) << engine.status().ToString();
  if (!scene.ok() || !engine.ok()) return out;
  const MeshDistance gt0((*scene)->GroundTruthMesh(0));
  double sum_surface = 0;
  for (int k = 0; k < 60; ++k) {
    auto r = (*engine)->Process((*scene)->Render(k));
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    if (!r.ok()) return out;
    const TriangleMesh gt = (*scene)->GroundTruthMesh(k);
    const MeshDistance dist(gt);
    double s = 0;
    for (size_t i = 0; i < r->live_mesh.num_vertices(); ++i) s += dist.Closest(V(r->live_mesh, i)).distance;
    const double surface_mm = 1000 * s / std::max<size_t>(1, r->live_mesh.num_vertices());
    out.worst_surface_mm = std::max(out.worst_surface_mm, surface_mm);
    sum_surface += surface_mm;
    if (k == 59) {
      // Drift: canonical vertex -> material point on frame 0's true surface -> its true position now.
      double d = 0, nr = 0;
      const Eigen::Matrix4f cam_from_world = r->pose.inverse().cast<float>();
      for (size_t i = 0; i < r->live_mesh.num_vertices(); ++i) {
        const ClosestPoint c = gt0.Closest(V(r->canonical_mesh, i));
        const Eigen::Vector3f truth_k = MeshDistance::Evaluate(gt, c.where);
        d += (truth_k - V(r->live_mesh, i)).norm();
        // Non-rigid displacement: live vertex vs its canonical vertex moved rigidly by the pose.
        const Eigen::Vector3f rigid = (cam_from_world * V(r->canonical_mesh, i).homogeneous()).head<3>();
        nr += (rigid - V(r->live_mesh, i)).norm();
      }
      out.last_drift_mm = 1000 * d / std::max<size_t>(1, r->live_mesh.num_vertices());
      out.last_nonrigid_mm = 1000 * nr / std::max<size_t>(1, r->live_mesh.num_vertices());
    }
  }
  out.mean_surface_mm = sum_surface / 60;
  std::printf("%s (%s): surface error mean %.2f mm, worst frame %.2f mm; last frame drift %.2f mm, mean non-rigid "
              "displacement %.2f mm\n",
              name.c_str(), rigid_only ? "rigid-only" : "non-rigid", out.mean_surface_mm, out.worst_surface_mm,
              out.last_drift_mm, out.last_nonrigid_mm);
  return out;
}

inline bool HaveDevice() {
  auto d = ocl::ListDevices();
  return d.ok() && !d->empty();
}

}  // namespace vd::test
