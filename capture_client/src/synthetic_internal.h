#pragma once
// Private pieces of the synthetic scenes: the procedural texture, the chart-based parametric
// surface that every scene is built from, and small motion profiles.
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "vd/capture/synthetic.h"

namespace vd::synthetic_internal {

struct Texture {
  // Selects the random pattern; parts with different seeds look different.
  uint32_t seed = 0;
  // Greys instead of saturated colours, so a floor stands apart from the objects on it.
  bool muted = false;
};

// Colour, B G R in 0..255, of the material point whose rest position (metres) is p. A solid
// texture: seamless on closed surfaces and a function of the material point only, so it moves
// with the surface. Layers of several scales (cells 45 mm, 18 mm, 7 mm, grain 5 mm) give SIFT
// blobs and corners from coarse to fine.
Eigen::Vector3f SolidTexture(const Eigen::Vector3d& p, const Texture& texture);

// Deterministic per-pixel random numbers: counter based, so the result does not depend on the
// order or thread in which pixels are visited.
uint64_t HashKey(uint64_t a, uint64_t b, uint64_t c);
// Uniform in [0, 1) from a key.
double UniformFromKey(uint64_t key);

// Smooth 0 -> 1 ramp over [0, 1] with zero slope at both ends.
inline double SmoothStep(double x) {
  x = x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x);
  return x * x * (3.0 - 2.0 * x);
}
// 0 -> 1 over the phase with a cosine profile (zero velocity at the start and the end).
inline double CosineProgress(double tau) { return 0.5 * (1.0 - std::cos(M_PI * tau)); }

// A patch of material points on a regular grid over (u, v) in [0, 1]^2, u across columns and
// v along rows. rest(u, v) must make d/du x d/dv point out of the object, so triangles are
// counter-clockwise seen from outside.
struct Chart {
  // Samples along u (distinct columns when wrap_u) and along v.
  int nu = 2;
  int nv = 2;
  // The last column joins the first (closed around u, e.g. a tube).
  bool wrap_u = false;
  // Row v = 0 / v = 1 is a single pole vertex (a sphere or capsule end, a disc centre).
  bool pole_v0 = false;
  bool pole_v1 = false;
  // Each chart may carry its own texture so neighbouring parts are told apart.
  Texture texture;
  std::function<Eigen::Vector3d(double u, double v)> rest;
};

// A scene made of charts whose material points move by an analytic function of the phase
// tau = k / (num_frames - 1) in [0, 1]. Frames outside [0, num_frames) are clamped.
class ParametricScene : public SyntheticScene {
 public:
  ParametricScene(std::string name, const SyntheticOptions& options, bool rigid);

  std::string name() const override { return name_; }
  int num_frames() const override { return options_.num_frames; }
  double fps() const override { return 30.0; }
  const Intrinsics& intrinsics() const override { return intrinsics_; }
  TriangleMesh GroundTruthMesh(int k) const override;
  Eigen::Isometry3d CameraPose(int k) const override;
  RgbdFrame Render(int k) const override;
  bool rigid() const override { return rigid_; }

  // Number of material points and triangles (for logs and tests).
  size_t num_material_points() const { return rest_.size(); }

 protected:
  // Called from the derived constructors, then FinishCharts once all charts are in.
  void AddChart(const Chart& chart);
  void FinishCharts();
  // World positions of every material point (rest_ order) at phase tau.
  virtual void WorldPositions(double tau, std::vector<Eigen::Vector3d>* world) const = 0;
  // Camera-to-world pose at phase tau; identity unless the camera moves.
  virtual Eigen::Isometry3d CameraPoseAt(double tau) const { return Eigen::Isometry3d::Identity(); }
  const std::vector<Eigen::Vector3d>& rest() const { return rest_; }

 private:
  double Phase(int k) const;
  // Frame k's material points in frame k's camera coordinates, x y z floats.
  std::vector<float> CameraPositions(int k) const;

  std::string name_;
  SyntheticOptions options_;
  bool rigid_ = false;
  Intrinsics intrinsics_;
  // Rest position of each material point (the texture's domain).
  std::vector<Eigen::Vector3d> rest_;
  // Texture of each material point's chart.
  std::vector<Texture> vertex_texture_;
  std::vector<int32_t> triangles_;
  // Chart texture of each triangle, for per-pixel texturing.
  std::vector<Texture> triangle_texture_;
  std::vector<uint8_t> colors_;
};

// Grid density of a chart so that its edges are about `edge` metres long.
int SamplesFor(double length, double edge);

}  // namespace vd::synthetic_internal
