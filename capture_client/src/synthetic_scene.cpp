// The chart-based parametric scene: ground-truth meshes, camera poses and rendering with the
// Kinect-like noise model.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <sstream>

#include "raster.h"
#include "synthetic_internal.h"

namespace vd {

Status SyntheticOptions::Validate() const {
  auto bad = [](const char* field, long long value, const char* bound) {
    std::ostringstream os;
    os << "SyntheticOptions." << field << " = " << value << " violates " << bound;
    return InvalidArgument(os.str());
  };
  if (width < 32 || width > 4096) return bad("width", width, "32 <= width <= 4096");
  if (height < 24 || height > 4096) return bad("height", height, "24 <= height <= 4096");
  if (num_frames < 1 || num_frames > 1000000) return bad("num_frames", num_frames, "1 <= num_frames <= 1000000");
  return Status::Ok();
}

namespace synthetic_internal {
namespace {

// The scenes are laid out for a 525 px focal length at 640x480 (Kinect-like); other image sizes
// scale it so the field of view stays the same.
constexpr double kFocal = 525.0;
constexpr double kReferenceWidth = 640.0;
constexpr double kReferenceHeight = 480.0;

// Background colour: dark neutral grey, BGR.
const cv::Vec3b kBackground(40, 40, 45);

// Axial noise of Nguyen et al. 2012 (Kinect v1), metres, for camera depth z in metres.
inline double AxialSigma(double z) { return 0.0012 + 0.0019 * (z - 0.4) * (z - 0.4); }
// Beyond ~78 degrees between the surface normal and the view ray the sensor returns nothing.
const double kGrazingCos = std::cos(78.0 * M_PI / 180.0);
// Neighbour depth jumps larger than this mark a depth edge (silhouettes, self-occlusions).
constexpr double kEdgeJump = 0.02;
// Chance that a depth-edge pixel is dropped, as structured-light sensors do along silhouettes.
constexpr double kEdgeDropProbability = 0.5;

}  // namespace

int SamplesFor(double length, double edge) {
  return std::max(2, static_cast<int>(std::ceil(length / edge)) + 1);
}

ParametricScene::ParametricScene(std::string name, const SyntheticOptions& options, bool rigid)
    : name_(std::move(name)), options_(options), rigid_(rigid) {
  intrinsics_.width = options.width;
  intrinsics_.height = options.height;
  intrinsics_.fx = static_cast<float>(kFocal * options.width / kReferenceWidth);
  intrinsics_.fy = static_cast<float>(kFocal * options.height / kReferenceHeight);
  intrinsics_.cx = 0.5f * options.width - 0.5f;
  intrinsics_.cy = 0.5f * options.height - 0.5f;
}

void ParametricScene::AddChart(const Chart& chart) {
  assert(chart.rest);
  assert(chart.nu >= (chart.wrap_u ? 3 : 2));
  assert(chart.nv >= (chart.pole_v0 && chart.pole_v1 ? 3 : 2));
  const int nu = chart.nu, nv = chart.nv;
  const int32_t base = static_cast<int32_t>(rest_.size());
  // Row j starts at row_start[j]; pole rows hold one vertex.
  std::vector<int32_t> row_start(nv);
  int32_t next = base;
  for (int j = 0; j < nv; ++j) {
    const double v = double(j) / double(nv - 1);
    row_start[j] = next;
    const bool pole = (j == 0 && chart.pole_v0) || (j == nv - 1 && chart.pole_v1);
    if (pole) {
      rest_.push_back(chart.rest(0.0, v));
      ++next;
      continue;
    }
    for (int i = 0; i < nu; ++i) {
      const double u = chart.wrap_u ? double(i) / double(nu) : double(i) / double(nu - 1);
      rest_.push_back(chart.rest(u, v));
      ++next;
    }
  }
  vertex_texture_.resize(rest_.size(), chart.texture);
  auto vertex = [&](int i, int j) {
    const bool pole = (j == 0 && chart.pole_v0) || (j == nv - 1 && chart.pole_v1);
    return pole ? row_start[j] : row_start[j] + i;
  };
  auto add = [&](int32_t a, int32_t b, int32_t c) {
    triangles_.insert(triangles_.end(), {a, b, c});
    triangle_texture_.push_back(chart.texture);
  };
  const int cells_u = chart.wrap_u ? nu : nu - 1;
  for (int j = 0; j + 1 < nv; ++j) {
    const bool pole_below = j == 0 && chart.pole_v0;
    const bool pole_above = j + 1 == nv - 1 && chart.pole_v1;
    for (int i = 0; i < cells_u; ++i) {
      const int i1 = chart.wrap_u ? (i + 1) % nu : i + 1;
      // Quad (i,j) (i1,j) (i1,j+1) (i,j+1) is counter-clockwise in (u, v).
      if (!pole_below) add(vertex(i, j), vertex(i1, j), vertex(i1, j + 1));
      if (!pole_above) add(vertex(i, j), vertex(i1, j + 1), vertex(i, j + 1));
    }
  }
}

void ParametricScene::FinishCharts() {
  colors_.resize(3 * rest_.size());
  for (size_t i = 0; i < rest_.size(); ++i) {
    const Eigen::Vector3f bgr = SolidTexture(rest_[i], vertex_texture_[i]);
    // The mesh stores r, g, b.
    for (int c = 0; c < 3; ++c) colors_[3 * i + c] = static_cast<uint8_t>(std::lround(bgr[2 - c]));
  }
}

double ParametricScene::Phase(int k) const {
  const int n = options_.num_frames;
  if (n <= 1) return 0.0;
  return double(std::clamp(k, 0, n - 1)) / double(n - 1);
}

Eigen::Isometry3d ParametricScene::CameraPose(int k) const { return CameraPoseAt(Phase(k)); }

std::vector<float> ParametricScene::CameraPositions(int k) const {
  const double tau = Phase(k);
  std::vector<Eigen::Vector3d> world;
  WorldPositions(tau, &world);
  assert(world.size() == rest_.size());
  const Eigen::Isometry3d camera_from_world = CameraPoseAt(tau).inverse();
  std::vector<float> out(3 * world.size());
  for (size_t i = 0; i < world.size(); ++i) {
    const Eigen::Vector3d p = camera_from_world * world[i];
    for (int a = 0; a < 3; ++a) out[3 * i + a] = static_cast<float>(p[a]);
  }
  return out;
}

TriangleMesh ParametricScene::GroundTruthMesh(int k) const {
  TriangleMesh mesh;
  mesh.positions = CameraPositions(k);
  mesh.colors = colors_;
  mesh.triangles = triangles_;
  // Area-weighted vertex normals.
  std::vector<double> acc(mesh.positions.size(), 0.0);
  const float* p = mesh.positions.data();
  for (size_t t = 0; t + 2 < triangles_.size(); t += 3) {
    const int32_t a = triangles_[t], b = triangles_[t + 1], c = triangles_[t + 2];
    const Eigen::Vector3d pa(p[3 * a], p[3 * a + 1], p[3 * a + 2]);
    const Eigen::Vector3d pb(p[3 * b], p[3 * b + 1], p[3 * b + 2]);
    const Eigen::Vector3d pc(p[3 * c], p[3 * c + 1], p[3 * c + 2]);
    const Eigen::Vector3d n = (pb - pa).cross(pc - pa);
    for (int32_t v : {a, b, c})
      for (int i = 0; i < 3; ++i) acc[3 * v + i] += n[i];
  }
  mesh.normals.resize(acc.size());
  for (size_t v = 0; v < acc.size(); v += 3) {
    const double len = std::sqrt(acc[v] * acc[v] + acc[v + 1] * acc[v + 1] + acc[v + 2] * acc[v + 2]);
    for (int i = 0; i < 3; ++i) mesh.normals[v + i] = len > 0 ? static_cast<float>(acc[v + i] / len) : 0.f;
  }
  return mesh;
}

RgbdFrame ParametricScene::Render(int k) const {
  const int n = options_.num_frames;
  const int kk = std::clamp(k, 0, n - 1);
  const std::vector<float> pos = CameraPositions(kk);
  const RasterImage raster = Rasterize(pos, triangles_, intrinsics_);
  const int w = intrinsics_.width, h = intrinsics_.height;

  RgbdFrame frame;
  frame.utime = std::llround(kk * 1e6 / fps());
  frame.seq = kk;
  frame.source_id = "synthetic:" + name_;
  frame.intrinsics = intrinsics_;
  frame.depth_scale = 1000.f;
  frame.depth = cv::Mat(h, w, CV_16UC1, cv::Scalar(0));
  frame.color = cv::Mat(h, w, CV_8UC3, cv::Scalar(kBackground[0], kBackground[1], kBackground[2]));

  const double fx = intrinsics_.fx, fy = intrinsics_.fy, cx = intrinsics_.cx, cy = intrinsics_.cy;
  const bool noise = options_.noise;
  const uint64_t seed = options_.seed;
#pragma omp parallel for schedule(dynamic, 8)
  for (int y = 0; y < h; ++y) {
    uint16_t* depth_row = frame.depth.ptr<uint16_t>(y);
    cv::Vec3b* color_row = frame.color.ptr<cv::Vec3b>(y);
    for (int x = 0; x < w; ++x) {
      const size_t idx = size_t(y) * size_t(w) + size_t(x);
      const int32_t t = raster.triangle[idx];
      if (t < 0) continue;
      const int32_t* tri = &triangles_[3 * size_t(t)];
      const float* b = &raster.bary[3 * idx];
      const Eigen::Vector3d material = b[0] * rest_[tri[0]] + b[1] * rest_[tri[1]] + b[2] * rest_[tri[2]];
      const Eigen::Vector3f bgr = SolidTexture(material, triangle_texture_[size_t(t)]);
      color_row[x] = cv::Vec3b(static_cast<uint8_t>(std::lround(bgr[0])), static_cast<uint8_t>(std::lround(bgr[1])),
                               static_cast<uint8_t>(std::lround(bgr[2])));

      double z = raster.depth[idx];
      if (noise) {
        const Eigen::Vector3d p0(pos[3 * tri[0]], pos[3 * tri[0] + 1], pos[3 * tri[0] + 2]);
        const Eigen::Vector3d p1(pos[3 * tri[1]], pos[3 * tri[1] + 1], pos[3 * tri[1] + 2]);
        const Eigen::Vector3d p2(pos[3 * tri[2]], pos[3 * tri[2] + 1], pos[3 * tri[2] + 2]);
        const Eigen::Vector3d normal = (p1 - p0).cross(p2 - p0);
        const Eigen::Vector3d ray((x - cx) / fx, (y - cy) / fy, 1.0);
        const double denom = normal.norm() * ray.norm();
        if (!(denom > 0.0) || std::fabs(normal.dot(ray)) < kGrazingCos * denom) continue;
        bool edge = false;
        const int nx[4] = {x - 1, x + 1, x, x};
        const int ny[4] = {y, y, y - 1, y + 1};
        for (int q = 0; q < 4 && !edge; ++q) {
          if (nx[q] < 0 || ny[q] < 0 || nx[q] >= w || ny[q] >= h) continue;
          const float zn = raster.depth[size_t(ny[q]) * size_t(w) + size_t(nx[q])];
          edge = zn <= 0.f || std::fabs(zn - z) > kEdgeJump;
        }
        const uint64_t key = HashKey(seed, static_cast<uint64_t>(kk), 4 * idx);
        if (edge && UniformFromKey(HashKey(key, 1, 0)) < kEdgeDropProbability) continue;
        const double u1 = std::max(UniformFromKey(HashKey(key, 2, 0)), 1e-300);
        const double u2 = UniformFromKey(HashKey(key, 3, 0));
        const double gauss = std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
        z += AxialSigma(z) * gauss;
      }
      const long long mm = std::llround(z * 1000.0);
      if (mm >= 1 && mm <= 65535) depth_row[x] = static_cast<uint16_t>(mm);
    }
  }
  return frame;
}

}  // namespace synthetic_internal
}  // namespace vd
