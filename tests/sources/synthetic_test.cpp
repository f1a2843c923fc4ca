#include "vd/capture/synthetic.h"

#include <gtest/gtest.h>

#include <cstring>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <Eigen/Eigenvalues>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "vd/common/camera.h"
#include "vd/common/codecs.h"

namespace vd {
namespace {

constexpr double kPi = 3.14159265358979323846;
std::unique_ptr<SyntheticScene> Make(const std::string& name, bool noise, uint32_t seed = 1) {
  SyntheticOptions options;
  options.noise = noise;
  options.seed = seed;
  auto scene = MakeSyntheticScene(name, options);
  EXPECT_TRUE(scene.ok()) << scene.status().ToString();
  return std::move(scene).value();
}

Eigen::Vector3f BackProject(const RgbdFrame& frame, int x, int y) {
  const float z = frame.depth.at<uint16_t>(y, x) / frame.depth_scale;
  const Intrinsics& k = frame.intrinsics;
  return Eigen::Vector3f((x - k.cx) / k.fx * z, (y - k.cy) / k.fy * z, z);
}

Eigen::Vector3f Vertex(const TriangleMesh& mesh, size_t v) {
  return Eigen::Vector3f(mesh.positions[3 * v], mesh.positions[3 * v + 1], mesh.positions[3 * v + 2]);
}

Eigen::Vector3f FaceNormal(const TriangleMesh& mesh, int t) {
  const Eigen::Vector3f a = Vertex(mesh, size_t(mesh.triangles[3 * size_t(t)]));
  const Eigen::Vector3f b = Vertex(mesh, size_t(mesh.triangles[3 * size_t(t) + 1]));
  const Eigen::Vector3f c = Vertex(mesh, size_t(mesh.triangles[3 * size_t(t) + 2]));
  return (b - a).cross(c - a).normalized();
}

Eigen::Vector3d Centroid(const TriangleMesh& mesh, const std::vector<size_t>& ids) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (size_t v : ids) sum += Vertex(mesh, v).cast<double>();
  return sum / double(ids.size());
}

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / kPi;
}

// Least-squares plane of the mesh vertices: centroid and unit normal.
void FitPlane(const TriangleMesh& mesh, Eigen::Vector3d* centre, Eigen::Vector3d* normal) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (size_t v = 0; v < mesh.num_vertices(); ++v) c += Vertex(mesh, v).cast<double>();
  c /= double(mesh.num_vertices());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (size_t v = 0; v < mesh.num_vertices(); ++v) {
    const Eigen::Vector3d d = Vertex(mesh, v).cast<double>() - c;
    cov += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  *centre = c;
  *normal = eig.eigenvectors().col(0);
}

TEST(SyntheticTest, OptionsAndNames) {
  EXPECT_EQ(SyntheticSceneNames(), (std::vector<std::string>{"tube", "cloth", "rigid", "bend", "enter", "pass"}));
  SyntheticOptions options;
  EXPECT_TRUE(options.Validate().ok());
  options.width = 0;
  EXPECT_NE(options.Validate().message().find("width"), std::string::npos);
  options = SyntheticOptions();
  options.num_frames = 0;
  EXPECT_NE(options.Validate().message().find("num_frames"), std::string::npos);
  EXPECT_FALSE(MakeSyntheticScene("tube", options).ok());

  auto unknown = MakeSyntheticScene("teapot", SyntheticOptions());
  ASSERT_FALSE(unknown.ok());
  EXPECT_EQ(unknown.status().code(), StatusCode::kNotFound);
  for (const char* name : {"teapot", "tube", "cloth", "rigid"})
    EXPECT_NE(unknown.status().message().find(name), std::string::npos) << unknown.status().message();

  for (const std::string& name : SyntheticSceneNames()) {
    auto scene = Make(name, true);
    EXPECT_EQ(scene->name(), name);
    EXPECT_EQ(scene->num_frames(), 60);
    EXPECT_DOUBLE_EQ(scene->fps(), 30.0);
    const Intrinsics& k = scene->intrinsics();
    EXPECT_EQ(k.width, 640);
    EXPECT_EQ(k.height, 480);
    EXPECT_FLOAT_EQ(k.fx, 525.f);
    EXPECT_FLOAT_EQ(k.fy, 525.f);
    EXPECT_FLOAT_EQ(k.cx, 319.5f);
    EXPECT_FLOAT_EQ(k.cy, 239.5f);
    EXPECT_EQ(scene->rigid(), name == "rigid");
    if (name != "rigid") {
      for (int f : {0, 30, 59}) EXPECT_TRUE(scene->CameraPose(f).isApprox(Eigen::Isometry3d::Identity()));
    }
    const RgbdFrame frame = scene->Render(7);
    EXPECT_TRUE(frame.Validate().ok()) << frame.Validate().ToString();
    EXPECT_EQ(frame.seq, 7);
    EXPECT_EQ(frame.utime, std::llround(7 * 1e6 / 30.0));
    EXPECT_FLOAT_EQ(frame.depth_scale, 1000.f);
    // Frames outside the sequence are clamped to its ends.
    EXPECT_EQ(cv::norm(scene->Render(-3).depth, scene->Render(0).depth, cv::NORM_INF), 0.0);
    EXPECT_EQ(scene->GroundTruthMesh(1000).positions, scene->GroundTruthMesh(59).positions);
  }

  // Other image sizes keep the field of view.
  SyntheticOptions small;
  small.width = 320;
  small.height = 240;
  small.num_frames = 10;
  auto scene = MakeSyntheticScene("cloth", small);
  ASSERT_TRUE(scene.ok());
  EXPECT_FLOAT_EQ((*scene)->intrinsics().fx, 262.5f);
  EXPECT_FLOAT_EQ((*scene)->intrinsics().cx, 159.5f);
  EXPECT_EQ((*scene)->num_frames(), 10);
  const RgbdFrame frame = (*scene)->Render(9);
  EXPECT_TRUE(frame.Validate().ok());
  EXPECT_GT(cv::countNonZero(frame.depth), 0.1 * 320 * 240);
}

TEST(SyntheticTest, SameSeedSameFramesOtherSeedOtherNoise) {
  for (const std::string& name : {std::string("cloth"), std::string("rigid")}) {
    auto a = Make(name, true, 5);
    auto b = Make(name, true, 5);
    auto c = Make(name, true, 6);
    const RgbdFrame fa = a->Render(12), fb = b->Render(12), fc = c->Render(12);
    EXPECT_EQ(cv::norm(fa.depth, fb.depth, cv::NORM_INF), 0.0) << name;
    EXPECT_EQ(cv::norm(fa.color, fb.color, cv::NORM_INF), 0.0) << name;
    EXPECT_GT(cv::countNonZero(fa.depth != fc.depth), 10000) << name;
    // Noise differs between frames too (frame index is part of the key).
    auto clean = Make(name, false);
    EXPECT_GT(cv::countNonZero(fa.depth != clean->Render(12).depth), 10000) << name;
    EXPECT_EQ(cv::norm(fa.color, clean->Render(12).color, cv::NORM_INF), 0.0) << name;
  }
}

TEST(SyntheticTest, TopologyFixedAcrossFrames) {
  for (const std::string& name : SyntheticSceneNames()) {
    auto scene = Make(name, false);
    const TriangleMesh m0 = scene->GroundTruthMesh(0);
    ASSERT_TRUE(m0.Validate().ok()) << m0.Validate().ToString();
    EXPECT_GT(m0.num_triangles(), 50000u) << name;
    EXPECT_EQ(m0.normals.size(), m0.positions.size());
    for (int f : {17, 59}) {
      const TriangleMesh mk = scene->GroundTruthMesh(f);
      EXPECT_EQ(mk.triangles, m0.triangles) << name;
      EXPECT_EQ(mk.colors, m0.colors) << name;
      EXPECT_EQ(mk.num_vertices(), m0.num_vertices()) << name;
    }
    // Edges of about 1-2 mm (longer only where the cloth stretches over its waves).
    double sum = 0.0, longest = 0.0;
    for (size_t t = 0; t < m0.num_triangles(); ++t) {
      const Eigen::Vector3f a = Vertex(m0, size_t(m0.triangles[3 * t]));
      const Eigen::Vector3f b = Vertex(m0, size_t(m0.triangles[3 * t + 1]));
      sum += (a - b).norm();
      longest = std::max(longest, double((a - b).norm()));
    }
    EXPECT_LT(sum / m0.num_triangles(), 0.0025) << name;
    EXPECT_LT(longest, 0.004) << name;
    // Object fits a ~1 m volume at 0.5-1.3 m from the camera ("pass", a strip longer than the view,
    // is 1.8 m long).
    float lo[3], hi[3];
    m0.Bounds(lo, hi);
    for (int a = 0; a < 3; ++a) EXPECT_LT(hi[a] - lo[a], name == "pass" && a == 0 ? 1.85f : 1.0f) << name;
    EXPECT_GT(lo[2], 0.5f) << name;
    EXPECT_LT(hi[2], 1.3f) << name;
  }
}

// Noise-free depth back-projects onto the ground-truth surface within the 1 mm quantisation,
// the colour is textured, and the visible triangles face the camera.
TEST(SyntheticTest, NoiseFreeRenderLiesOnGroundTruth) {
  for (const std::string& name : SyntheticSceneNames()) {
    auto scene = Make(name, false);
    for (int f : {0, 31}) {
      const RgbdFrame frame = scene->Render(f);
      const TriangleMesh mesh = scene->GroundTruthMesh(f);
      const MeshDistance dist(mesh);
      double sum = 0.0, worst = 0.0;
      int count = 0, facing = 0, background_colour = 0;
      for (int y = 0; y < frame.depth.rows; y += 2) {
        for (int x = 0; x < frame.depth.cols; x += 2) {
          if (frame.depth.at<uint16_t>(y, x) == 0) continue;
          const Eigen::Vector3f p = BackProject(frame, x, y);
          const ClosestPoint c = dist.Closest(p);
          sum += c.distance;
          worst = std::max(worst, double(c.distance));
          ++count;
          if (FaceNormal(mesh, c.where.triangle).dot(p) < 0.f) ++facing;
          if (frame.color.at<cv::Vec3b>(y, x) == cv::Vec3b(40, 40, 45)) ++background_colour;
        }
      }
      // Object covers a good part of the image (sampled every 2nd pixel).
      EXPECT_GT(count, 0.10 * 640 * 480 / 4) << name << " frame " << f;
      std::cout << name << " frame " << f << ": noise-free depth to surface mean " << sum / count * 1e3
                << " mm, max " << worst * 1e3 << " mm over " << count << " pixels\n";
      EXPECT_LT(sum / count, 0.0003) << name << " frame " << f;
      EXPECT_LT(worst, 0.0008) << name << " frame " << f;
      EXPECT_GT(facing, 0.995 * count) << name << " frame " << f;
      EXPECT_LT(background_colour, 0.001 * count) << name << " frame " << f;
      // Background is empty depth with the background colour.
      EXPECT_EQ(frame.depth.at<uint16_t>(0, 0), 0);
    }
  }
}

// Noisy depth minus noise-free depth follows sigma(z) = 1.2 mm + 1.9 mm * (z - 0.4)^2, and the
// invalidated pixels are grazing or at depth edges only.
TEST(SyntheticTest, NoiseFollowsTheModel) {
  for (const std::string& name : SyntheticSceneNames()) {
    auto noisy = Make(name, true, 3);
    auto clean = Make(name, false);
    const RgbdFrame fn = noisy->Render(20), fc = clean->Render(20);
    const TriangleMesh mesh = clean->GroundTruthMesh(20);
    const MeshDistance dist(mesh);
    double sum = 0.0, sum2 = 0.0, surface = 0.0;
    int both = 0, clean_only = 0, noisy_only = 0, grazing_kept = 0;
    for (int y = 0; y < 480; ++y) {
      for (int x = 0; x < 640; ++x) {
        const int zn = fn.depth.at<uint16_t>(y, x), zc = fc.depth.at<uint16_t>(y, x);
        if (zn && !zc) ++noisy_only;
        if (!zn && zc) ++clean_only;
        if (!zn || !zc) continue;
        const double z = zc * 1e-3;
        const double sigma_mm = 1e3 * (0.0012 + 0.0019 * (z - 0.4) * (z - 0.4));
        const double r = (zn - zc) / sigma_mm;
        sum += r;
        sum2 += r * r;
        ++both;
        if ((x + y) % 7 == 0) {
          const Eigen::Vector3f p = BackProject(fc, x, y);
          const ClosestPoint c = dist.Closest(p);
          const float cosine = std::fabs(FaceNormal(mesh, c.where.triangle).dot(p.normalized()));
          if (cosine < std::cos(81.0 * kPi / 180.0)) ++grazing_kept;
          surface += dist.Closest(BackProject(fn, x, y)).distance;
        }
      }
    }
    const double mean = sum / both, stddev = std::sqrt(sum2 / both - mean * mean);
    // Quantising both images to 1 mm adds 1/6 mm^2 of variance to sigma^2 of ~2.5 mm^2.
    EXPECT_NEAR(mean, 0.0, 0.03) << name;
    EXPECT_GT(stddev, 0.95) << name;
    EXPECT_LT(stddev, 1.12) << name;
    EXPECT_EQ(noisy_only, 0) << name;
    EXPECT_GT(clean_only, 100) << name;
    EXPECT_LT(clean_only, 0.12 * both) << name;
    // Pixels on a box edge may find the other face as the closest triangle.
    EXPECT_LE(grazing_kept, 2) << name;
    const double mean_surface = surface / std::max(1, both / 7);
    EXPECT_GT(mean_surface, 0.0006) << name;
    EXPECT_LT(mean_surface, 0.0025) << name;
    std::cout << name << ": noise residual/sigma mean " << mean << " std " << stddev << ", dropped "
              << clean_only << " of " << both + clean_only << ", mean distance to surface "
              << mean_surface * 1e3 << " mm\n";
  }
}

TEST(SyntheticTest, ClothSlidesTangentially) {
  auto scene = Make("cloth", false);
  const TriangleMesh first = scene->GroundTruthMesh(0), last = scene->GroundTruthMesh(59);
  Eigen::Vector3d c0, n0, c1, n1;
  FitPlane(first, &c0, &n0);
  FitPlane(last, &c1, &n1);
  EXPECT_LT(std::min(AngleDeg(n0, n1), AngleDeg(n0, -n1)), 5.0);
  EXPECT_LT(std::fabs((c1 - c0).dot(n0)), 0.01);
  double tangential = 0.0, normal = 0.0;
  for (size_t v = 0; v < first.num_vertices(); ++v) {
    const Eigen::Vector3d d = (Vertex(last, v) - Vertex(first, v)).cast<double>();
    tangential += (d - d.dot(n0) * n0).norm();
    normal += std::fabs(d.dot(n0));
  }
  tangential /= double(first.num_vertices());
  normal /= double(first.num_vertices());
  std::cout << "cloth: mean in-plane displacement " << tangential * 100 << " cm, along the normal "
            << normal * 100 << " cm\n";
  EXPECT_GT(tangential, 0.05);
  EXPECT_LT(tangential, 0.12);
  EXPECT_LT(normal, 0.04);
  // The sheet waves: frame 30's vertices leave the frame-0 plane by centimetres.
  const TriangleMesh mid = scene->GroundTruthMesh(30);
  double peak = 0.0;
  for (size_t v = 0; v < mid.num_vertices(); ++v)
    peak = std::max(peak, std::fabs((Vertex(mid, v).cast<double>() - c0).dot(n0)));
  EXPECT_GT(peak, 0.02);
  EXPECT_LT(peak, 0.05);
}

TEST(SyntheticTest, TubeBendsUpAndBack) {
  auto scene = Make("tube", false);
  const TriangleMesh rest = scene->GroundTruthMesh(0);
  Eigen::Vector3d centre, unused;
  FitPlane(rest, &centre, &unused);
  // Main axis of the straight tube.
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (size_t v = 0; v < rest.num_vertices(); ++v) {
    const Eigen::Vector3d d = Vertex(rest, v).cast<double>() - centre;
    cov += d * d.transpose();
  }
  const Eigen::Vector3d axis = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(2);
  // Rings in the end caps (beyond the 25 cm half-length of the cylinder) move rigidly with the
  // end sections, so the line through two ring centres is the end tangent.
  std::vector<size_t> ring[4];
  const double bands[4][2] = {{-0.295, -0.285}, {-0.275, -0.265}, {0.265, 0.275}, {0.285, 0.295}};
  for (size_t v = 0; v < rest.num_vertices(); ++v) {
    const double s = (Vertex(rest, v).cast<double>() - centre).dot(axis);
    for (int r = 0; r < 4; ++r)
      if (s > bands[r][0] && s < bands[r][1]) ring[r].push_back(v);
  }
  for (int r = 0; r < 4; ++r) ASSERT_GT(ring[r].size(), 500u);
  auto bend = [&](int f) {
    const TriangleMesh m = scene->GroundTruthMesh(f);
    const Eigen::Vector3d t0 = Centroid(m, ring[1]) - Centroid(m, ring[0]);
    const Eigen::Vector3d t1 = Centroid(m, ring[3]) - Centroid(m, ring[2]);
    return AngleDeg(t0, t1);
  };
  EXPECT_LT(bend(0), 0.1);
  double previous = 0.0;
  for (int f = 5; f <= 30; f += 5) {
    const double angle = bend(f);
    EXPECT_GT(angle, previous + 1.0) << "frame " << f;
    previous = angle;
  }
  const double peak = std::max(bend(29), bend(30));
  std::cout << "tube: end-tangent angle at frames 10/20/30/45/59: " << bend(10) << " " << bend(20) << " " << peak
            << " " << bend(45) << " " << bend(59) << " deg\n";
  EXPECT_GT(peak, 50.0);
  EXPECT_LT(peak, 60.0);
  EXPECT_LT(bend(59), 0.5);
  // The ends move by centimetres.
  const TriangleMesh mid = scene->GroundTruthMesh(30);
  EXPECT_LT((Centroid(mid, ring[0]) - Centroid(rest, ring[0])).norm(), 0.15);
  EXPECT_GT((Centroid(mid, ring[0]) - Centroid(rest, ring[0])).norm(), 0.05);
}

TEST(SyntheticTest, RigidSceneIsStaticInTheWorldWhileTheCameraMoves) {
  auto scene = Make("rigid", false);
  const TriangleMesh m0 = scene->GroundTruthMesh(0);
  EXPECT_TRUE(scene->CameraPose(0).isApprox(Eigen::Isometry3d::Identity()));
  for (int f : {10, 30, 59}) {
    const TriangleMesh mk = scene->GroundTruthMesh(f);
    const Eigen::Isometry3f pose = scene->CameraPose(f).cast<float>();
    double worst = 0.0;
    for (size_t v = 0; v < m0.num_vertices(); ++v)
      worst = std::max(worst, double((pose * Vertex(mk, v) - Vertex(m0, v)).norm()));
    EXPECT_LT(worst, 2e-6) << "frame " << f;
  }
  const Eigen::Isometry3d last = scene->CameraPose(59);
  const double travel = last.translation().norm();
  const double turn = Eigen::AngleAxisd(last.linear()).angle() * 180.0 / kPi;
  std::cout << "rigid: camera travels " << travel * 100 << " cm and turns " << turn << " deg\n";
  EXPECT_GT(travel, 0.10);
  EXPECT_LT(travel, 0.20);
  EXPECT_GT(turn, 8.0);
  EXPECT_LT(turn, 20.0);
  // Smooth path: no step between consecutive frames larger than 4 mm or 0.5 degrees.
  for (int f = 1; f < 60; ++f) {
    const Eigen::Isometry3d step = scene->CameraPose(f - 1).inverse() * scene->CameraPose(f);
    EXPECT_LT(step.translation().norm(), 0.004);
    EXPECT_LT(Eigen::AngleAxisd(step.linear()).angle() * 180.0 / kPi, 0.5);
  }
  EXPECT_GT(cv::countNonZero(scene->Render(0).depth != scene->Render(59).depth), 50000);
}

TEST(SyntheticTest, TextureHasManySiftFeaturesOnTheObject) {
  auto sift = cv::SIFT::create();
  for (const std::string& name : SyntheticSceneNames()) {
    auto scene = Make(name, true);
    const RgbdFrame frame = scene->Render(0);
    cv::Mat grey;
    cv::cvtColor(frame.color, grey, cv::COLOR_BGR2GRAY);
    std::vector<cv::KeyPoint> keypoints;
    sift->detect(grey, keypoints);
    int on_object = 0;
    for (const cv::KeyPoint& k : keypoints) {
      const int x = std::clamp(int(std::lround(k.pt.x)), 0, 639), y = std::clamp(int(std::lround(k.pt.y)), 0, 479);
      if (frame.depth.at<uint16_t>(y, x) > 0) ++on_object;
    }
    std::cout << name << ": " << on_object << " SIFT keypoints on the object (" << keypoints.size() << " in all)\n";
    EXPECT_GT(on_object, 150) << name;
  }
}

TEST(SyntheticTest, MeshDistanceMatchesBruteForce) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<float> coord(-0.2f, 0.2f), small(-0.02f, 0.02f);
  TriangleMesh mesh;
  for (int t = 0; t < 3000; ++t) {
    const Eigen::Vector3f c(coord(rng), coord(rng), coord(rng));
    for (int v = 0; v < 3; ++v) {
      Eigen::Vector3f p = c + Eigen::Vector3f(small(rng), small(rng), small(rng));
      // A few degenerate triangles: collinear and coincident vertices.
      if (t % 500 == 1 && v == 2) p = Vertex(mesh, mesh.num_vertices() - 1) * 2.f - Vertex(mesh, mesh.num_vertices() - 2);
      if (t % 500 == 2 && v > 0) p = Vertex(mesh, mesh.num_vertices() - 1);
      mesh.positions.insert(mesh.positions.end(), {p.x(), p.y(), p.z()});
      mesh.triangles.push_back(int32_t(mesh.num_vertices() - 1));
    }
  }
  const MeshDistance dist(mesh);
  std::uniform_real_distribution<float> query(-0.4f, 0.4f);
  for (int q = 0; q < 400; ++q) {
    const Eigen::Vector3f p(query(rng), query(rng), query(rng));
    // Brute force: dense barycentric sampling cannot be exact, so compare against the minimum
    // of an independent projection-based computation per triangle.
    float best = std::numeric_limits<float>::infinity();
    for (size_t t = 0; t < mesh.num_triangles(); ++t) {
      const Eigen::Vector3f a = Vertex(mesh, size_t(mesh.triangles[3 * t]));
      const Eigen::Vector3f b = Vertex(mesh, size_t(mesh.triangles[3 * t + 1]));
      const Eigen::Vector3f c = Vertex(mesh, size_t(mesh.triangles[3 * t + 2]));
      auto segment = [&](const Eigen::Vector3f& s0, const Eigen::Vector3f& s1) {
        const Eigen::Vector3f d = s1 - s0;
        const float len2 = d.squaredNorm();
        const float u = len2 > 0 ? std::clamp((p - s0).dot(d) / len2, 0.f, 1.f) : 0.f;
        return (s0 + u * d - p).norm();
      };
      float d = std::min({segment(a, b), segment(b, c), segment(c, a)});
      const Eigen::Vector3f n = (b - a).cross(c - a);
      if (n.squaredNorm() > 1e-14f) {
        const Eigen::Vector3f nn = n.normalized();
        const Eigen::Vector3f proj = p - (p - a).dot(nn) * nn;
        const bool inside = (b - a).cross(proj - a).dot(n) >= 0 && (c - b).cross(proj - b).dot(n) >= 0 &&
                            (a - c).cross(proj - c).dot(n) >= 0;
        if (inside) d = std::min(d, std::fabs((p - a).dot(nn)));
      }
      best = std::min(best, d);
    }
    const ClosestPoint c = dist.Closest(p);
    ASSERT_NEAR(c.distance, best, 1e-5f) << "query " << q;
    EXPECT_NEAR((c.position - p).norm(), c.distance, 1e-5f);
    EXPECT_LT((MeshDistance::Evaluate(mesh, c.where) - c.position).norm(), 1e-5f);
    EXPECT_NEAR(c.where.b0 + c.where.b1 + c.where.b2, 1.f, 1e-5f);
    EXPECT_GE(std::min({c.where.b0, c.where.b1, c.where.b2}), -1e-6f);
  }
  // Bad input: empty mesh, out-of-range surface points and indices never crash.
  const MeshDistance empty{TriangleMesh()};
  EXPECT_EQ(empty.Closest(Eigen::Vector3f::Zero()).where.triangle, -1);
  EXPECT_TRUE(std::isinf(empty.Closest(Eigen::Vector3f::Zero()).distance));
  EXPECT_TRUE(MeshDistance::Evaluate(mesh, SurfacePoint{-1, 1, 0, 0}).hasNaN());
  EXPECT_TRUE(MeshDistance::Evaluate(mesh, SurfacePoint{3000, 1, 0, 0}).hasNaN());
  TriangleMesh broken = mesh;
  broken.triangles[0] = 1 << 30;
  const MeshDistance skip(broken);
  EXPECT_TRUE(std::isfinite(skip.Closest(Eigen::Vector3f::Zero()).distance));
  EXPECT_TRUE(MeshDistance::Evaluate(broken, SurfacePoint{0, 1, 0, 0}).hasNaN());
}

// The drift metric: a material point found on frame 0 is evaluated on frame k's mesh.
TEST(SyntheticTest, SurfacePointsFollowTheMaterial) {
  auto scene = Make("tube", false);
  const TriangleMesh m0 = scene->GroundTruthMesh(0), m30 = scene->GroundTruthMesh(30);
  const MeshDistance d0(m0);
  std::vector<Eigen::Vector3f> queries;
  for (size_t v = 0; v < m0.num_vertices(); v += 997) queries.push_back(Vertex(m0, v));
  for (size_t i = 0; i < queries.size(); ++i) {
    const ClosestPoint c = d0.Closest(queries[i]);
    EXPECT_LT(c.distance, 1e-6f);
    const size_t v = i * 997;
    EXPECT_LT((MeshDistance::Evaluate(m30, c.where) - Vertex(m30, v)).norm(), 1e-5f);
  }
}

// Closest-point queries near the surface: each query is a surface vertex moved by an offset, so
// the distance found can never exceed the offset's length. (Speed belongs in benchmarks.)
TEST(SyntheticTest, MeshDistanceNeverExceedsTheOffsetFromTheSurface) {
  auto scene = Make("tube", false);
  const TriangleMesh mesh = scene->GroundTruthMesh(30);
  const MeshDistance dist(mesh);
  std::mt19937 rng(7);
  std::normal_distribution<float> offset(0.f, 0.01f);
  double sum = 0.0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const size_t v = size_t(rng() % mesh.num_vertices());
    const Eigen::Vector3f o(offset(rng), offset(rng), offset(rng));
    const float d = dist.Closest(Vertex(mesh, v) + o).distance;
    ASSERT_LE(d, o.norm() + 1e-6f);
    sum += d;
  }
  // Offsets of ~1.7 cm (3-D, 1 cm per axis) that often point along the surface: well below that.
  EXPECT_GT(sum / n, 0.002);
  EXPECT_LT(sum / n, 0.012);
}

TEST(SyntheticTest, WritesDataset) {
  auto scene = Make("cloth", true);
  const std::string dir = testing::TempDir() + "/vd_synthetic_dataset";
  std::filesystem::remove_all(dir);
  EXPECT_FALSE(WriteSyntheticDataset(*scene, dir, 0).ok());
  EXPECT_FALSE(WriteSyntheticDataset(*scene, dir, 61).ok());
  ASSERT_TRUE(WriteSyntheticDataset(*scene, dir, 3).ok());
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) files += entry.is_regular_file();
  EXPECT_EQ(files, 1 + 3 * 4);

  auto k = LoadIntrinsicsFile(dir + "/intrinsics.txt");
  ASSERT_TRUE(k.ok()) << k.status().ToString();
  EXPECT_FLOAT_EQ(k->fx, 525.f);
  EXPECT_FLOAT_EQ(k->cy, 239.5f);

  for (int f = 0; f < 3; ++f) {
    char prefix[64];
    std::snprintf(prefix, sizeof(prefix), "/frame-%06d.", f);
    const RgbdFrame frame = scene->Render(f);
    const cv::Mat depth = cv::imread(dir + prefix + "depth.png", cv::IMREAD_UNCHANGED);
    const cv::Mat color = cv::imread(dir + prefix + "color.png", cv::IMREAD_UNCHANGED);
    ASSERT_EQ(depth.type(), CV_16UC1);
    ASSERT_EQ(color.type(), CV_8UC3);
    EXPECT_EQ(cv::norm(depth, frame.depth, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(color, frame.color, cv::NORM_INF), 0.0);

    auto ply = ReadPly(dir + prefix + "gt.ply");
    ASSERT_TRUE(ply.ok()) << ply.status().ToString();
    const TriangleMesh mesh = scene->GroundTruthMesh(f);
    EXPECT_EQ(ply->positions, mesh.positions);
    EXPECT_EQ(ply->normals, mesh.normals);
    EXPECT_EQ(ply->colors, mesh.colors);
    EXPECT_EQ(ply->triangles, mesh.triangles);

    std::ifstream pose_file(dir + prefix + "pose.txt");
    Eigen::Matrix4d pose;
    for (int i = 0; i < 16; ++i) pose_file >> pose(i / 4, i % 4);
    ASSERT_TRUE(bool(pose_file));
    EXPECT_TRUE(pose.isApprox(scene->CameraPose(f).matrix()));
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace vd
