#pragma once
// Deterministic synthetic deforming scenes with ground truth: textured surfaces with a fixed
// topology whose every material point has a known position in every frame.
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "vd/common/frame.h"
#include "vd/common/mesh.h"
#include "vd/common/status.h"

namespace vd {

struct SyntheticOptions {
  int width = 640;
  int height = 480;
  // Kinect-like noise: axial sigma growing with depth squared, 1 mm quantisation steps of the
  // disparity, invalid pixels at grazing angles.
  bool noise = true;
  // Seed for the noise; the same seed gives the same frames.
  uint32_t seed = 1;
  // Frames in one pass of the scene's motion.
  int num_frames = 60;
  Status Validate() const;
};

// A point on the ground-truth surface, identified by triangle and barycentric coordinates; it is
// the same material point in every frame because the topology is fixed.
struct SurfacePoint {
  int triangle = -1;
  float b0 = 0.f, b1 = 0.f, b2 = 0.f;
};

class SyntheticScene {
 public:
  virtual ~SyntheticScene() = default;
  // "tube" (bending tube), "cloth" (waving, sliding and turning in its own plane),
  // "rigid" (rigid object, moving camera).
  virtual std::string name() const = 0;
  virtual int num_frames() const = 0;
  virtual double fps() const = 0;
  virtual const Intrinsics& intrinsics() const = 0;
  // Ground-truth surface of frame k in frame k's camera coordinates (metres), fixed topology.
  virtual TriangleMesh GroundTruthMesh(int k) const = 0;
  // Camera-to-world pose of frame k, world = frame 0's camera coordinates.
  virtual Eigen::Isometry3d CameraPose(int k) const = 0;
  // Rendered RGB-D frame k (depth in millimetres, depth_scale 1000, colour BGR).
  virtual RgbdFrame Render(int k) const = 0;
  // True when the surface itself is rigid (only the camera moves).
  virtual bool rigid() const = 0;
};

StatusOr<std::unique_ptr<SyntheticScene>> MakeSyntheticScene(const std::string& name, const SyntheticOptions& options);
std::vector<std::string> SyntheticSceneNames();
// The names joined by ", " (help texts and errors).
std::string SyntheticSceneList();

// Ground-truth metrics. `mesh_k` is frame k's ground truth (camera coordinates).
// Closest point on the mesh to p (brute force over a BVH-free grid is fine for tests).
struct ClosestPoint {
  SurfacePoint where;
  Eigen::Vector3f position;
  float distance = 0.f;
};
class MeshDistance {
 public:
  explicit MeshDistance(const TriangleMesh& mesh);
  ClosestPoint Closest(const Eigen::Vector3f& p) const;
  // Position of a surface point on the mesh (same topology as the one it was found on).
  static Eigen::Vector3f Evaluate(const TriangleMesh& mesh, const SurfacePoint& s);

 private:
  struct Impl;
  std::shared_ptr<const Impl> impl_;
};

// Writes frames [0, n) as a VolumeDeform-layout folder: frame-%06d.color.png, frame-%06d.depth.png,
// intrinsics.txt, and ground truth frame-%06d.gt.ply (frame camera coordinates) and
// frame-%06d.pose.txt (camera-to-world).
Status WriteSyntheticDataset(const SyntheticScene& scene, const std::string& dir, int n);

}  // namespace vd
