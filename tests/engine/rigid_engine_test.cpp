// Rigid tracking and fusion of the OpenCL engine against synthetic ground truth.
#include <gtest/gtest.h>

#include <cmath>

#include "core/engine.h"
#include "ocl/ocl.h"
#include "vd/capture/synthetic.h"

namespace vd {
namespace {

bool HaveDevice() {
  auto d = ocl::ListDevices();
  return d.ok() && !d->empty();
}

double RotationErrorDeg(const Eigen::Matrix4d& a, const Eigen::Matrix4d& b) {
  const Eigen::Matrix3d d = a.topLeftCorner<3, 3>().transpose() * b.topLeftCorner<3, 3>();
  return Eigen::AngleAxisd(d).angle() * 180.0 / M_PI;
}

TEST(RigidEngineTest, IcpRecoversTheCameraMotionAndFusionMatchesTheSurface) {
  if (!HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  SyntheticOptions so;
  so.noise = true;
  so.num_frames = 60;
  auto scene = MakeSyntheticScene("rigid", so);
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  EngineParams p;
  p.voxel_size = 0.006f;
  auto engine = Engine::Create(p, "");
  ASSERT_TRUE(engine.ok()) << engine.status().ToString();
  const Eigen::Matrix4d pose0 = (*scene)->CameraPose(0).matrix();
  double worst_rot = 0, worst_trans = 0;
  FrameResult last;
  // Every 3rd frame: larger steps than the sensor's, so tracking is exercised, in a few seconds.
  for (int k = 0; k < (*scene)->num_frames(); k += 3) {
    RgbdFrame frame = (*scene)->Render(k);
    auto r = (*engine)->Process(frame);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    ASSERT_TRUE(r->tracking_ok) << "frame " << k << ": " << r->tracking_message;
    // Ground truth relative to frame 0 (our world).
    const Eigen::Matrix4d truth = pose0.inverse() * (*scene)->CameraPose(k).matrix();
    worst_rot = std::max(worst_rot, RotationErrorDeg(truth, r->pose));
    worst_trans = std::max(worst_trans, (truth.topRightCorner<3, 1>() - r->pose.topRightCorner<3, 1>()).norm());
    last = std::move(r).value();
  }
  std::printf("worst rotation error %.4f deg, worst translation error %.3f mm\n", worst_rot, worst_trans * 1000);
  EXPECT_LT(worst_rot, 0.2);
  EXPECT_LT(worst_trans, 0.002);

  // The live mesh of the last frame against that frame's true surface.
  const int k_last = ((*scene)->num_frames() - 1) / 3 * 3;
  MeshDistance truth((*scene)->GroundTruthMesh(k_last));
  const TriangleMesh& m = last.live_mesh;
  ASSERT_GT(m.num_vertices(), 1000u);
  double sum = 0;
  int n = 0;
  for (size_t i = 0; i < m.num_vertices(); ++i) {
    const Eigen::Vector3f p(m.positions[3 * i], m.positions[3 * i + 1], m.positions[3 * i + 2]);
    const float d = truth.Closest(p).distance;
    // Vertices beyond the ground-truth object (e.g. a floor the object stands on) are not scored.
    if (d > 0.02f) continue;
    sum += d;
    ++n;
  }
  ASSERT_GT(n, int(m.num_vertices() / 2));
  const double mean_mm = 1000 * sum / n;
  std::printf("mean surface error %.3f mm over %d vertices\n", mean_mm, n);
  EXPECT_LT(mean_mm, 1.5);
}

}  // namespace
}  // namespace vd
