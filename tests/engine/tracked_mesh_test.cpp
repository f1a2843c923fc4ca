// The fixed-topology tracked mesh (issue 14, --track-mesh): the same vertices and faces in every
// frame, each vertex the deformation field S applied to its canonical position, seen from the
// frame's camera; and how close it follows the tube's true material points.
#include <gtest/gtest.h>

#include <cmath>

#include "scene_eval.h"
#include "shared/deformation.h"

namespace vd {
namespace {

TEST(TrackedMeshTest, SameVerticesAndFacesEveryFrameAtSOfTheCanonicalPositions) {
  if (!test::HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  SyntheticOptions so;
  so.num_frames = 30;
  auto scene = MakeSyntheticScene("tube", so);
  ASSERT_TRUE(scene.ok());
  EngineParams p;
  p.voxel_size = 0.006f;
  auto engine = Engine::Create(p, "");
  ASSERT_TRUE(engine.ok());
  ASSERT_TRUE((*engine)->TrackMesh().ok());
  TriangleMesh first_canonical, first_tracked;
  double last_truth_mm = 0;
  const int frames = 30;
  for (int k = 0; k < frames; ++k) {
    auto r = (*engine)->Process((*scene)->Render(k));
    ASSERT_TRUE(r.ok() && r->tracking_ok) << k;
    const TriangleMesh& t = r->tracked_mesh;
    if (k == 0) {
      first_canonical = r->canonical_mesh;
      first_tracked = t;
      ASSERT_GT(t.num_vertices(), 1000u);
      // Frame 0: the canonical mesh itself (the field is the identity), in camera 0 = world.
      EXPECT_EQ(t.triangles, first_canonical.triangles);
      for (size_t i = 0; i < t.positions.size(); ++i) ASSERT_NEAR(t.positions[i], first_canonical.positions[i], 1e-5f);
      continue;
    }
    // Constant topology, though the canonical mesh itself grows and changes.
    ASSERT_EQ(t.num_vertices(), first_tracked.num_vertices()) << k;
    ASSERT_EQ(t.triangles, first_tracked.triangles) << k;
    EXPECT_EQ(t.colors, first_tracked.colors) << k;
    // Each vertex: S(canonical position) moved into this frame's camera.
    std::vector<vd_float4> def_pos;
    ASSERT_TRUE((*engine)->DownloadDeformation(&def_pos).ok());
    const VdVolume vol = (*engine)->volume();
    const Eigen::Matrix4d cam_from_world = r->pose.inverse();
    double worst = 0;
    for (size_t i = 0; i < t.num_vertices(); i += 7) {
      const float* c = &first_canonical.positions[3 * i];
      const vd_float4 g = VD_F4((c[0] - vol.origin.x) / vol.voxel_size, (c[1] - vol.origin.y) / vol.voxel_size,
                                (c[2] - vol.origin.z) / vol.voxel_size, 1.f);
      const vd_float4 s = vd_deform_point(g, def_pos.data(), vol);
      const Eigen::Vector3d expect = (cam_from_world * Eigen::Vector4d(s.x, s.y, s.z, 1.0)).head<3>();
      worst = std::max(worst, (expect - test::V(t, i).cast<double>()).norm());
    }
    EXPECT_LT(worst, 1e-5) << "frame " << k;
    if (k == frames - 1) {
      // Against the truth: each tracked vertex's material point (its closest point on frame 0's
      // true surface) where it really is now (ground truth is in this frame's camera).
      const MeshDistance gt0((*scene)->GroundTruthMesh(0));
      const TriangleMesh gt = (*scene)->GroundTruthMesh(k);
      double sum = 0;
      for (size_t i = 0; i < t.num_vertices(); ++i) {
        const ClosestPoint cp = gt0.Closest(test::V(first_canonical, i));
        const Eigen::Vector3d truth = MeshDistance::Evaluate(gt, cp.where).cast<double>();
        sum += (truth - test::V(t, i).cast<double>()).norm();
      }
      last_truth_mm = 1000 * sum / double(t.num_vertices());
    }
  }
  std::printf("tracked mesh: %zu vertices; mean distance to the true positions at frame %d: %.2f mm\n",
              first_tracked.num_vertices(), frames - 1, last_truth_mm);
  EXPECT_LT(last_truth_mm, 3.0);
}

TEST(TrackedMeshTest, AGivenMeshIsTrackedAndABrokenOneRefused) {
  if (!test::HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  auto engine = Engine::Create(EngineParams(), "");
  ASSERT_TRUE(engine.ok());
  TriangleMesh bad;
  bad.positions = {0.f, 0.f, 0.9f, 0.01f, 0.f, 0.9f, 0.f, 0.01f, 0.9f};
  bad.triangles = {0, 1, 3};
  EXPECT_EQ((*engine)->TrackMesh(bad).code(), StatusCode::kInvalidArgument);
  bad.triangles = {0, 1, 2};
  bad.positions[4] = std::nanf("");
  EXPECT_EQ((*engine)->TrackMesh(bad).code(), StatusCode::kInvalidArgument);
  TriangleMesh empty_faces;
  empty_faces.positions = {0.f, 0.f, 0.9f};
  EXPECT_EQ((*engine)->TrackMesh(empty_faces).code(), StatusCode::kInvalidArgument);

  // One triangle on the tube's near side, in canonical (frame 0 camera) coordinates.
  SyntheticOptions so;
  so.num_frames = 10;
  auto scene = MakeSyntheticScene("tube", so);
  ASSERT_TRUE(scene.ok());
  TriangleMesh tri;
  tri.positions = {-0.01f, 0.f, 0.8f, 0.01f, 0.f, 0.8f, 0.f, 0.01f, 0.8f};
  tri.triangles = {0, 1, 2};
  ASSERT_TRUE((*engine)->TrackMesh(tri).ok());
  for (int k = 0; k < 3; ++k) {
    auto r = (*engine)->Process((*scene)->Render(k));
    ASSERT_TRUE(r.ok());
    ASSERT_EQ(r->tracked_mesh.num_vertices(), 3u) << k;
    EXPECT_EQ(r->tracked_mesh.triangles, tri.triangles);
    if (k == 0) {
      for (size_t i = 0; i < 9; ++i) EXPECT_NEAR(r->tracked_mesh.positions[i], tri.positions[i], 1e-5f);
    }
  }
}

}  // namespace
}  // namespace vd
