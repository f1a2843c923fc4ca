// The synthetic scenes: a bending tube (and its long-take variant), a waving and sliding cloth, a
// rigid object seen by a moving camera, an object that enters from outside the first view, and one
// that passes through it.
// World = frame 0's camera coordinates (x right, y down, z forward).
#include <cmath>

#include "synthetic_internal.h"

namespace vd {
namespace synthetic_internal {
namespace {

constexpr double kDeg = M_PI / 180.0;
// Target edge length of the ground-truth meshes: the chord error of a 2 mm edge on the tightest
// curvature used (the 40 mm cylinder) is 0.0125 mm, far below the 1 mm depth quantisation.
constexpr double kEdge = 0.002;

// A rectangle corner + u e1 + v e2 with e1 x e2 the outward normal.
Chart PlaneChart(const Eigen::Vector3d& corner, const Eigen::Vector3d& e1, const Eigen::Vector3d& e2,
                 const Texture& texture) {
  Chart chart;
  chart.nu = SamplesFor(e1.norm(), kEdge);
  chart.nv = SamplesFor(e2.norm(), kEdge);
  chart.texture = texture;
  chart.rest = [corner, e1, e2](double u, double v) { return Eigen::Vector3d(corner + u * e1 + v * e2); };
  return chart;
}


// A capsule (cylinder with hemispherical ends) lying across the view that bends into an arc.
// "tube": the end tangents turn by kMaxBend * sin^2(pi tau), up and back. "bend" (a long-take
// case): the arc closes monotonically to 150 degrees, 150 * (3 tau^2 - 2 tau^3), and stays: with
// no return, what the model gets wrong over a take is still there at its end. The ends bend
// towards the camera and up, so the motion shows both in depth and in the image.
class TubeScene : public ParametricScene {
 public:
  // Tube radius and the length of its cylindrical part (caps add one radius at each end): 70 cm
  // by 20 cm, about 410 x 115 px at 0.9 m.
  static constexpr double kRadius = 0.10;
  static constexpr double kLength = 0.50;
  static constexpr double kMaxBend = 55.0 * kDeg;
  static constexpr double kFullBend = 150.0 * kDeg;

  TubeScene(const SyntheticOptions& options, bool monotone)
      : ParametricScene(monotone ? "bend" : "tube", options, false), monotone_(monotone) {
    // Half the meridian length, from the middle of the cylinder to a pole.
    const double half_meridian = 0.5 * kLength + 0.5 * M_PI * kRadius;
    Chart chart;
    chart.nu = static_cast<int>(std::ceil(2.0 * M_PI * kRadius / kEdge));
    chart.nv = SamplesFor(2.0 * half_meridian, kEdge);
    chart.wrap_u = true;
    chart.pole_v0 = chart.pole_v1 = true;
    chart.texture.seed = 11;
    chart.rest = [half_meridian](double u, double v) {
      const double theta = 2.0 * M_PI * u;
      const double s = -half_meridian + 2.0 * half_meridian * v;
      double axial = s, radius = kRadius;
      if (std::fabs(s) > 0.5 * kLength) {
        const double phi = std::min((std::fabs(s) - 0.5 * kLength) / kRadius, 0.5 * M_PI);
        axial = std::copysign(0.5 * kLength + kRadius * std::sin(phi), s);
        radius = kRadius * std::cos(phi);
      }
      // u = theta, v = axial: d/dtheta x d/daxial points outwards.
      return Eigen::Vector3d(axial, radius * std::cos(theta), radius * std::sin(theta));
    };
    AddChart(chart);
    FinishCharts();
    pose_ = Eigen::Translation3d(0.0, 0.0, 0.9) * Eigen::AngleAxisd(8.0 * kDeg, Eigen::Vector3d::UnitZ());
    // In the local frame the bend pulls towards (0, cos b, sin b); with b = -120 deg that is up
    // in the image (-y) and towards the camera (-z).
    const double b = -120.0 * kDeg;
    bend_dir_ = Eigen::Vector3d(0.0, std::cos(b), std::sin(b));
    side_dir_ = Eigen::Vector3d(0.0, -std::sin(b), std::cos(b));
  }

 protected:
  void WorldPositions(double tau, std::vector<Eigen::Vector3d>* world) const override {
    const double s = std::sin(M_PI * tau);
    const double angle = monotone_ ? kFullBend * tau * tau * (3.0 - 2.0 * tau) : kMaxBend * s * s;
    const double curvature = angle / kLength;
    world->resize(rest().size());
    for (size_t i = 0; i < rest().size(); ++i) (*world)[i] = pose_ * Bend(rest()[i], curvature);
  }

 private:
  // "bend": closes to kFullBend and stays; "tube": up to kMaxBend and back.
  bool monotone_;
  // Bends the cylindrical part into an arc of the given curvature (cross-sections stay planar
  // and normal to the centreline, which keeps its length); the caps follow the end sections.
  Eigen::Vector3d Bend(const Eigen::Vector3d& p, double curvature) const {
    if (curvature == 0.0) return p;
    const double along = p.x();
    const double clamped = std::clamp(along, -0.5 * kLength, 0.5 * kLength);
    const double beyond = along - clamped;
    const double offset = p.dot(bend_dir_);
    const double side = p.dot(side_dir_);
    const double phi = curvature * clamped;
    const double sin_half = std::sin(0.5 * phi);
    const double centre_axial = std::sin(phi) / curvature;
    const double centre_bend = 2.0 * sin_half * sin_half / curvature;
    const double axial = centre_axial - offset * std::sin(phi) + beyond * std::cos(phi);
    const double bend = centre_bend + offset * std::cos(phi) + beyond * std::sin(phi);
    return axial * Eigen::Vector3d::UnitX() + bend * bend_dir_ + side * side_dir_;
  }

  Eigen::Isometry3d pose_;
  Eigen::Vector3d bend_dir_;
  Eigen::Vector3d side_dir_;
};

// A 40 x 30 cm sheet facing the camera. Two travelling sine waves ripple it along its normal
// (their amplitude ramps from 35% to full over the first 40% of the sequence) while the
// material slides 7 cm and turns 15 degrees within the plane. The waves are a field over the
// plane, not over the material, so the slide and turn are invisible to depth alone.
class ClothScene : public ParametricScene {
 public:
  static constexpr double kWidth = 0.40;
  static constexpr double kHeight = 0.30;
  static constexpr double kEdgeCloth = 0.0015;

  explicit ClothScene(const SyntheticOptions& options) : ParametricScene("cloth", options, false) {
    Chart chart;
    chart.nu = SamplesFor(kWidth, kEdgeCloth);
    chart.nv = SamplesFor(kHeight, kEdgeCloth);
    chart.texture.seed = 22;
    // Material coordinates in the sheet's own plane; the visible side is +z of that frame.
    chart.rest = [](double u, double v) {
      return Eigen::Vector3d(-0.5 * kWidth + kWidth * u, -0.5 * kHeight + kHeight * v, 0.0);
    };
    AddChart(chart);
    FinishCharts();
    // The sheet's x axis points right and its y axis up, so its normal (x cross y) faces the
    // camera; it is tilted a little so it is not exactly fronto-parallel.
    const Eigen::Matrix3d tilt =
        (Eigen::AngleAxisd(15.0 * kDeg, Eigen::Vector3d::UnitX()) * Eigen::AngleAxisd(-10.0 * kDeg, Eigen::Vector3d::UnitY()))
            .toRotationMatrix();
    axis_x_ = tilt * Eigen::Vector3d::UnitX();
    axis_y_ = tilt * -Eigen::Vector3d::UnitY();
    normal_ = axis_x_.cross(axis_y_);
    origin_ = Eigen::Vector3d(0.0, 0.0, 0.85);
  }

 protected:
  void WorldPositions(double tau, std::vector<Eigen::Vector3d>* world) const override {
    const double progress = CosineProgress(tau);
    const double turn = 15.0 * kDeg * progress;
    const Eigen::Vector2d slide = Eigen::Vector2d(0.06, 0.035) * progress;
    const double amplitude = 0.35 + 0.65 * SmoothStep(tau / 0.4);
    const Eigen::Rotation2Dd rot(turn);
    // Wave 1: 22 cm wavelength, 2 cm high, 1.5 wavelengths of travel; wave 2: 14 cm, 1 cm, 1.
    const Eigen::Vector2d k1 = 2.0 * M_PI / 0.22 * Eigen::Vector2d(std::cos(20.0 * kDeg), std::sin(20.0 * kDeg));
    const Eigen::Vector2d k2 = 2.0 * M_PI / 0.14 * Eigen::Vector2d(std::cos(110.0 * kDeg), std::sin(110.0 * kDeg));
    const double phase1 = 2.0 * M_PI * 1.5 * tau;
    const double phase2 = 2.0 * M_PI * 1.0 * tau - 1.0;
    world->resize(rest().size());
    for (size_t i = 0; i < rest().size(); ++i) {
      const Eigen::Vector2d q = rot * rest()[i].head<2>() + slide;
      const double height = amplitude * (0.02 * std::sin(k1.dot(q) - phase1) + 0.01 * std::sin(k2.dot(q) - phase2));
      (*world)[i] = origin_ + q.x() * axis_x_ + q.y() * axis_y_ + height * normal_;
    }
  }

 private:
  Eigen::Vector3d axis_x_, axis_y_, normal_, origin_;
};

// A rigid arrangement on a 70 x 50 cm textured grey floor: a box, a sphere resting on the floor and a
// capped upright cylinder. The camera orbits 12 degrees about the floor's vertical axis through
// the scene centre and rises 3 cm, both with a cosine profile (about 13 cm of travel).
class RigidScene : public ParametricScene {
 public:
  explicit RigidScene(const SyntheticOptions& options) : ParametricScene("rigid", options, true) {
    // Object frame: x right, z up from the floor, floor at z = 0.
    AddPlane(Eigen::Vector3d(-0.35, -0.25, 0.0), Eigen::Vector3d(0.70, 0.0, 0.0), Eigen::Vector3d(0.0, 0.50, 0.0),
             Texture{101, true});
    AddBox(Eigen::Vector2d(-0.10, 0.03), 20.0 * kDeg, Eigen::Vector3d(0.16, 0.12, 0.10), 202);
    AddSphere(Eigen::Vector3d(0.12, -0.07, 0.065), 0.065, Texture{303, false});
    AddCylinder(Eigen::Vector2d(0.11, 0.13), 0.04, 0.12, Texture{404, false});
    FinishCharts();
    // The floor's up direction leans 50 degrees towards the camera, so the camera looks down at
    // about 40 degrees from the floor normal.
    const double elevation = 50.0 * kDeg;
    up_ = Eigen::Vector3d(0.0, -std::cos(elevation), -std::sin(elevation));
    const Eigen::Vector3d x = Eigen::Vector3d::UnitX();
    Eigen::Matrix3d r;
    r.col(0) = x;
    r.col(1) = up_.cross(x);
    r.col(2) = up_;
    centre_ = Eigen::Vector3d(0.0, -0.02, 0.92);
    const Eigen::Isometry3d world_from_object = Eigen::Translation3d(centre_) * Eigen::Isometry3d(r);
    world_.resize(rest().size());
    for (size_t i = 0; i < rest().size(); ++i) world_[i] = world_from_object * rest()[i];
  }

 protected:
  void WorldPositions(double, std::vector<Eigen::Vector3d>* world) const override { *world = world_; }

  Eigen::Isometry3d CameraPoseAt(double tau) const override {
    const double progress = CosineProgress(tau);
    const Eigen::Matrix3d rot = Eigen::AngleAxisd(12.0 * kDeg * progress, up_).toRotationMatrix();
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = rot;
    pose.translation() = centre_ - rot * centre_ + 0.03 * progress * up_;
    return pose;
  }

 private:
  void AddPlane(const Eigen::Vector3d& corner, const Eigen::Vector3d& e1, const Eigen::Vector3d& e2, const Texture& texture) {
    AddChart(PlaneChart(corner, e1, e2, texture));
  }

  // Five faces (no bottom) of a box standing on the floor, turned by `yaw` about z.
  void AddBox(const Eigen::Vector2d& centre, double yaw, const Eigen::Vector3d& size, uint32_t seed) {
    const Eigen::Matrix3d r = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Vector3d c(centre.x(), centre.y(), 0.0);
    const double hx = 0.5 * size.x(), hy = 0.5 * size.y(), hz = size.z();
    auto face = [&](const Eigen::Vector3d& corner, const Eigen::Vector3d& e1, const Eigen::Vector3d& e2, uint32_t s) {
      AddPlane(c + r * corner, r * e1, r * e2, Texture{s, false});
    };
    face({-hx, -hy, hz}, {2 * hx, 0, 0}, {0, 2 * hy, 0}, seed);
    face({hx, -hy, 0}, {0, 2 * hy, 0}, {0, 0, hz}, seed + 1);
    face({-hx, hy, 0}, {0, -2 * hy, 0}, {0, 0, hz}, seed + 2);
    face({hx, hy, 0}, {-2 * hx, 0, 0}, {0, 0, hz}, seed + 3);
    face({-hx, -hy, 0}, {2 * hx, 0, 0}, {0, 0, hz}, seed + 4);
  }

  void AddSphere(const Eigen::Vector3d& centre, double radius, const Texture& texture) {
    Chart chart;
    chart.nu = static_cast<int>(std::ceil(2.0 * M_PI * radius / kEdge));
    chart.nv = SamplesFor(M_PI * radius, kEdge);
    chart.wrap_u = true;
    chart.pole_v0 = chart.pole_v1 = true;
    chart.texture = texture;
    // u = longitude, v = polar angle from the bottom pole: d/du x d/dv points outwards.
    chart.rest = [centre, radius](double u, double v) {
      const double theta = 2.0 * M_PI * u, phi = M_PI * v;
      return Eigen::Vector3d(centre + radius * Eigen::Vector3d(std::sin(phi) * std::cos(theta),
                                                               std::sin(phi) * std::sin(theta), -std::cos(phi)));
    };
    AddChart(chart);
  }

  // An upright cylinder standing on the floor with a flat top; its bottom is hidden.
  void AddCylinder(const Eigen::Vector2d& centre, double radius, double height, const Texture& texture) {
    const int around = static_cast<int>(std::ceil(2.0 * M_PI * radius / kEdge));
    Chart side;
    side.nu = around;
    side.nv = SamplesFor(height, kEdge);
    side.wrap_u = true;
    side.texture = texture;
    side.rest = [centre, radius, height](double u, double v) {
      const double theta = 2.0 * M_PI * u;
      return Eigen::Vector3d(centre.x() + radius * std::cos(theta), centre.y() + radius * std::sin(theta), v * height);
    };
    AddChart(side);
    Chart top;
    top.nu = around;
    top.nv = SamplesFor(radius, kEdge);
    top.wrap_u = true;
    top.pole_v1 = true;
    top.texture = Texture{texture.seed + 1, texture.muted};
    // From the rim (v = 0) to the centre (v = 1): d/du x d/dv points up.
    top.rest = [centre, radius, height](double u, double v) {
      const double theta = 2.0 * M_PI * u, rho = radius * (1.0 - v);
      return Eigen::Vector3d(centre.x() + rho * std::cos(theta), centre.y() + rho * std::sin(theta), height);
    };
    AddChart(top);
  }

  Eigen::Vector3d up_;
  Eigen::Vector3d centre_;
  std::vector<Eigen::Vector3d> world_;
};

// A 30 cm high textured strip 1 m in front of a still camera, facing it, from x = `left` to
// `left + length` m (the image spans +-0.61 m at this depth), sliding `slide` m to the right along
// itself over the first `ramp` of the take (a smooth step) and then resting. Only the features see
// the slide (the depth of a plane moving within itself does not change), as in the cloth scene.
class SlidingStripScene : public ParametricScene {
 public:
  SlidingStripScene(const char* name, const SyntheticOptions& options, double left, double length, double slide,
                    double ramp, uint32_t seed)
      : ParametricScene(name, options, false), slide_(slide), ramp_(ramp) {
    // Facing the camera: e1 right, e2 up (-y), e1 x e2 = -z.
    AddChart(PlaneChart(Eigen::Vector3d(left, 0.15, 1.0), Eigen::Vector3d(length, 0.0, 0.0),
                        Eigen::Vector3d(0.0, -0.30, 0.0), Texture{seed, false}));
    FinishCharts();
  }

 protected:
  void WorldPositions(double tau, std::vector<Eigen::Vector3d>* world) const override {
    const Eigen::Vector3d shift(slide_ * SmoothStep(std::min(1.0, tau / ramp_)), 0.0, 0.0);
    world->resize(rest().size());
    for (size_t i = 0; i < rest().size(); ++i) (*world)[i] = rest()[i] + shift;
  }

 private:
  double slide_;  // metres the strip moves to the right
  double ramp_;   // the share of the take the slide takes
};

// "enter" (a scene that grows beyond its first view, issue 17): a 95 cm strip (x = -0.95 to 0.0 m)
// of which the first frame sees only the right part, in the left half of the image. Over the first
// 60 % of the take it slides 45 cm to the right and rests, all of it in view: its left end, never
// seen by the first frame, enters from the image's left edge. In the canonical (first-frame) space
// that end lies up to 24 cm past the space around the first frame's points, which a volume fixed at
// the first frame cannot hold.
std::unique_ptr<SyntheticScene> MakeEnterScene(const SyntheticOptions& options) {
  return std::make_unique<SlidingStripScene>("enter", options, -0.95, 0.95, 0.45, 0.6, 505u);
}

// "pass" (a surface that passes through the view, issue 17's eviction under a deforming model): a
// 1.8 m strip, longer than the view. The first frame sees its right part (x = -0.61 to 0.60 m);
// over the whole take it slides 60 cm to the right, so its left end enters from the image's left
// edge while its right end leaves past the right edge: at the end the camera sees the strip's
// canonical x = -1.21 to 0.01 m, and the 59 cm the first frame saw right of that has been out of
// view for up to half the take. A model whose memory follows the surface must let that part go
// when its pool is full.
std::unique_ptr<SyntheticScene> MakePassScene(const SyntheticOptions& options) {
  return std::make_unique<SlidingStripScene>("pass", options, -1.20, 1.80, 0.60, 1.0, 606u);
}

}  // namespace
}  // namespace synthetic_internal

std::vector<std::string> SyntheticSceneNames() { return {"tube", "cloth", "rigid", "bend", "enter", "pass"}; }

std::string SyntheticSceneList() {
  std::string list;
  for (const std::string& n : SyntheticSceneNames()) list += (list.empty() ? "" : ", ") + n;
  return list;
}

StatusOr<std::unique_ptr<SyntheticScene>> MakeSyntheticScene(const std::string& name, const SyntheticOptions& options) {
  VD_RETURN_IF_ERROR(options.Validate());
  using namespace synthetic_internal;
  if (name == "tube") return std::unique_ptr<SyntheticScene>(new TubeScene(options, false));
  if (name == "bend") return std::unique_ptr<SyntheticScene>(new TubeScene(options, true));
  if (name == "cloth") return std::unique_ptr<SyntheticScene>(new ClothScene(options));
  if (name == "rigid") return std::unique_ptr<SyntheticScene>(new RigidScene(options));
  if (name == "enter") return MakeEnterScene(options);
  if (name == "pass") return MakePassScene(options);
  return NotFound("unknown synthetic scene '" + name + "' (valid: " + SyntheticSceneList() + ")");
}

}  // namespace vd
