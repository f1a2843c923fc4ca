#include "vd/viewer/render.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace vd {
namespace {

// Grey used when a mesh has no colour (or in kShade mode): light enough that shading reads well.
constexpr uint8_t kGrey = 200;
// Zoom beyond these bounds only produces empty or single-pixel images.
constexpr float kMinZoom = 1e-3f;
constexpr float kMaxZoom = 1e3f;

// Twice the signed area of (a, b, p): positive when p lies left of a->b.
inline double Edge(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double px, double py) {
  return (b.x() - a.x()) * (py - a.y()) - (b.y() - a.y()) * (px - a.x());
}

}  // namespace

const char* ColorModeName(ColorMode mode) {
  switch (mode) {
    case ColorMode::kCanonical:
      return "canonical";
    case ColorMode::kVertex:
      return "vertex";
    case ColorMode::kShade:
      return "shade";
  }
  return "unknown";
}

StatusOr<ColorMode> ParseColorMode(const std::string& name) {
  for (ColorMode m : {ColorMode::kCanonical, ColorMode::kVertex, ColorMode::kShade})
    if (name == ColorModeName(m)) return m;
  return InvalidArgument("colour mode '" + name + "' is not canonical, vertex or shade");
}

ColorMode NextColorMode(ColorMode mode) {
  switch (mode) {
    case ColorMode::kCanonical:
      return ColorMode::kVertex;
    case ColorMode::kVertex:
      return ColorMode::kShade;
    case ColorMode::kShade:
      return ColorMode::kCanonical;
  }
  return ColorMode::kCanonical;
}

Status RenderOptions::Validate() const {
  auto bad = [](const char* field, const std::string& value, const char* bound) {
    return InvalidArgument(std::string("RenderOptions.") + field + " = " + value + " violates " + bound);
  };
  if (width < 16 || width > 8192) return bad("width", std::to_string(width), "16 <= width <= 8192");
  if (height < 16 || height > 8192) return bad("height", std::to_string(height), "16 <= height <= 8192");
  if (!std::isfinite(margin) || margin < 0.f || margin >= 0.45f)
    return bad("margin", std::to_string(margin), "0 <= margin < 0.45");
  if (!std::isfinite(ambient) || ambient < 0.f || ambient > 1.f)
    return bad("ambient", std::to_string(ambient), "0 <= ambient <= 1");
  return Status::Ok();
}

StatusOr<RenderResult> RenderMesh(const TriangleMesh& mesh, const std::vector<uint8_t>& rgb,
                                  const RenderOptions& options, const ViewParams& view) {
  VD_RETURN_IF_ERROR(options.Validate());
  VD_RETURN_IF_ERROR(mesh.Validate());
  if (!rgb.empty() && rgb.size() != mesh.positions.size())
    return InvalidArgument("RenderMesh: " + std::to_string(rgb.size() / 3) + " colours for " +
                           std::to_string(mesh.num_vertices()) + " vertices");
  if (!std::isfinite(view.yaw) || !std::isfinite(view.pitch) || !std::isfinite(view.zoom) || view.zoom < kMinZoom ||
      view.zoom > kMaxZoom)
    return InvalidArgument("ViewParams: yaw and pitch must be finite and zoom within [0.001, 1000], got zoom = " +
                           std::to_string(view.zoom));

  const int w = options.width;
  const int h = options.height;
  RenderResult result;
  result.image = cv::Mat(h, w, CV_8UC3, cv::Scalar(options.background[0], options.background[1], options.background[2]));
  result.depth = cv::Mat::zeros(h, w, CV_32FC1);
  result.intrinsics = Intrinsics{1.f, 1.f, w / 2.f, h / 2.f, w, h};
  if (mesh.empty()) return result;

  // Orbit about the bounding-box centre; the unrotated view is exactly the live camera's.
  float mn[3], mx[3];
  mesh.Bounds(mn, mx);
  const Eigen::Vector3d centre(0.5 * (mn[0] + mx[0]), 0.5 * (mn[1] + mx[1]), 0.5 * (mn[2] + mx[2]));
  const double radius = std::max(
      1e-6, 0.5 * Eigen::Vector3d(mx[0] - mn[0], mx[1] - mn[1], mx[2] - mn[2]).norm());
  const Eigen::Matrix3d rotation = (Eigen::AngleAxisd(view.pitch, Eigen::Vector3d::UnitX()) *
                                    Eigen::AngleAxisd(view.yaw, Eigen::Vector3d::UnitY()))
                                       .toRotationMatrix();
  const size_t n = mesh.num_vertices();
  std::vector<Eigen::Vector3d> p(n);
  double z_min = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d v(mesh.positions[3 * i], mesh.positions[3 * i + 1], mesh.positions[3 * i + 2]);
    p[i] = rotation * (v - centre) + centre;
    z_min = std::min(z_min, p[i].z());
  }
  // A mesh reaching behind the camera (a canonical mesh in odd coordinates, an orbit that swings
  // it round) is seen from further back instead: the bounding sphere then lies in front.
  const double near = std::max(1e-4, 1e-2 * radius);
  if (z_min < near) {
    const double offset = 2.0 * radius - centre.z();
    for (auto& v : p) v.z() += offset;
    result.eye_offset_z = static_cast<float>(offset);
  }

  // Intrinsics: the focal length that fits the projected vertices' bounding box into the image
  // minus the margins, the principal point that centres it.
  double a_min = std::numeric_limits<double>::infinity(), a_max = -a_min, b_min = a_min, b_max = -a_min;
  for (const auto& v : p) {
    const double a = v.x() / v.z(), b = v.y() / v.z();
    a_min = std::min(a_min, a);
    a_max = std::max(a_max, a);
    b_min = std::min(b_min, b);
    b_max = std::max(b_max, b);
  }
  const double usable = 1.0 - 2.0 * options.margin;
  const double span_a = std::max(a_max - a_min, 1e-9), span_b = std::max(b_max - b_min, 1e-9);
  const double f = std::min(w * usable / span_a, h * usable / span_b) * view.zoom;
  const double cx = 0.5 * w - f * 0.5 * (a_min + a_max);
  const double cy = 0.5 * h - f * 0.5 * (b_min + b_max);
  result.intrinsics = Intrinsics{static_cast<float>(f), static_cast<float>(f), static_cast<float>(cx),
                                 static_cast<float>(cy), w, h};

  // Smooth shading: area-weighted vertex normals (Draco meshes arrive without normals).
  std::vector<Eigen::Vector3d> normal(n, Eigen::Vector3d::Zero());
  const size_t num_tri = mesh.num_triangles();
  for (size_t t = 0; t < num_tri; ++t) {
    const int32_t* idx = &mesh.triangles[3 * t];
    const Eigen::Vector3d face = (p[idx[1]] - p[idx[0]]).cross(p[idx[2]] - p[idx[0]]);
    for (int k = 0; k < 3; ++k) normal[idx[k]] += face;
  }
  for (auto& nv : normal) {
    const double len = nv.norm();
    nv = len > 0 ? Eigen::Vector3d(nv / len) : Eigen::Vector3d(0, 0, -1);
  }

  std::vector<Eigen::Vector2d> s(n);
  for (size_t i = 0; i < n; ++i) s[i] = Eigen::Vector2d(f * p[i].x() / p[i].z() + cx, f * p[i].y() / p[i].z() + cy);

  // Pass 1, visibility: the z-buffer holds 1/z (linear in screen space; 0 means empty) and the
  // triangle seen at each pixel. Shading waits for pass 2 so hidden surfaces cost no shading.
  std::vector<float> inv_depth(static_cast<size_t>(w) * h, 0.f);
  std::vector<int32_t> visible(static_cast<size_t>(w) * h, -1);
  for (size_t t = 0; t < num_tri; ++t) {
    const int32_t i0 = mesh.triangles[3 * t], i1 = mesh.triangles[3 * t + 1], i2 = mesh.triangles[3 * t + 2];
    const double area = Edge(s[i0], s[i1], s[i2].x(), s[i2].y());
    if (!(std::abs(area) > 1e-12)) continue;
    // Clamp in floating point before converting, so far-off vertices cannot overflow an int.
    const double u_lo = std::min({s[i0].x(), s[i1].x(), s[i2].x()});
    const double u_hi = std::max({s[i0].x(), s[i1].x(), s[i2].x()});
    const double v_lo = std::min({s[i0].y(), s[i1].y(), s[i2].y()});
    const double v_hi = std::max({s[i0].y(), s[i1].y(), s[i2].y()});
    const int x0 = static_cast<int>(std::clamp(std::floor(u_lo - 0.5), 0.0, static_cast<double>(w)));
    const int x1 = static_cast<int>(std::clamp(std::ceil(u_hi - 0.5), -1.0, static_cast<double>(w - 1)));
    const int y0 = static_cast<int>(std::clamp(std::floor(v_lo - 0.5), 0.0, static_cast<double>(h)));
    const int y1 = static_cast<int>(std::clamp(std::ceil(v_hi - 0.5), -1.0, static_cast<double>(h - 1)));
    if (x0 > x1 || y0 > y1) continue;
    const double inv_area = 1.0 / area;
    const double iz0 = 1.0 / p[i0].z(), iz1 = 1.0 / p[i1].z(), iz2 = 1.0 / p[i2].z();
    // Barycentric weights are affine in the pixel position: step them along the row.
    const double dw0 = -(s[i2].y() - s[i1].y()) * inv_area, dw1 = -(s[i0].y() - s[i2].y()) * inv_area;
    for (int y = y0; y <= y1; ++y) {
      const double py = y + 0.5, px0 = x0 + 0.5;
      double w0 = Edge(s[i1], s[i2], px0, py) * inv_area;
      double w1 = Edge(s[i2], s[i0], px0, py) * inv_area;
      float* depth_row = &inv_depth[static_cast<size_t>(y) * w];
      int32_t* visible_row = &visible[static_cast<size_t>(y) * w];
      for (int x = x0; x <= x1; ++x, w0 += dw0, w1 += dw1) {
        const double w2 = 1.0 - w0 - w1;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const float inv_z = static_cast<float>(w0 * iz0 + w1 * iz1 + w2 * iz2);
        if (inv_z <= depth_row[x]) continue;
        depth_row[x] = inv_z;
        visible_row[x] = static_cast<int32_t>(t);
      }
    }
  }

  // Pass 2, shading of the visible surface only.
  const double ambient = options.ambient;
  for (int y = 0; y < h; ++y) {
    auto* row = result.image.ptr<cv::Vec3b>(y);
    float* depth_row = result.depth.ptr<float>(y);
    const double py = y + 0.5;
    for (int x = 0; x < w; ++x) {
      const int32_t t = visible[static_cast<size_t>(y) * w + x];
      if (t < 0) continue;
      const int32_t i0 = mesh.triangles[3 * t], i1 = mesh.triangles[3 * t + 1], i2 = mesh.triangles[3 * t + 2];
      const double px = x + 0.5;
      const double inv_area = 1.0 / Edge(s[i0], s[i1], s[i2].x(), s[i2].y());
      // Clamped: stepping in pass 1 can accept a pixel a rounding error outside an edge.
      const double w0 = std::max(0.0, Edge(s[i1], s[i2], px, py) * inv_area);
      const double w1 = std::max(0.0, Edge(s[i2], s[i0], px, py) * inv_area);
      const double w2 = std::max(0.0, 1.0 - w0 - w1);
      const double iz0 = w0 / p[i0].z(), iz1 = w1 / p[i1].z(), iz2 = w2 / p[i2].z();
      const double inv_z = iz0 + iz1 + iz2;
      if (!(inv_z > 0)) continue;
      // Perspective-correct weights for the vertex attributes.
      const double b0 = iz0 / inv_z, b1 = iz1 / inv_z, b2 = iz2 / inv_z;
      const Eigen::Vector3d nrm = (b0 * normal[i0] + b1 * normal[i1] + b2 * normal[i2]).normalized();
      const Eigen::Vector3d ray = Eigen::Vector3d((px - cx) / f, (py - cy) / f, 1.0).normalized();
      // Headlight: the light sits at the eye, so brightness is |cos| between normal and ray
      // (two-sided: marching-cubes surfaces seen from behind at their borders stay lit).
      const double lambert = std::isfinite(nrm.x()) ? std::abs(nrm.dot(ray)) : 1.0;
      const double shade = ambient + (1.0 - ambient) * lambert;
      double rgb_px[3] = {kGrey, kGrey, kGrey};
      if (!rgb.empty())
        for (int c = 0; c < 3; ++c) rgb_px[c] = b0 * rgb[3 * i0 + c] + b1 * rgb[3 * i1 + c] + b2 * rgb[3 * i2 + c];
      for (int c = 0; c < 3; ++c)
        row[x][2 - c] = static_cast<uint8_t>(std::clamp(rgb_px[c] * shade + 0.5, 0.0, 255.0));
      depth_row[x] = static_cast<float>(1.0 / inv_z);
    }
  }
  result.covered_pixels = cv::countNonZero(result.depth);
  return result;
}

std::vector<uint8_t> CanonicalColors(const TriangleMesh& canonical) {
  float mn[3], mx[3];
  canonical.Bounds(mn, mx);
  std::vector<uint8_t> rgb(canonical.positions.size());
  for (size_t i = 0; i < rgb.size(); ++i) {
    const int a = static_cast<int>(i % 3);
    const float extent = mx[a] - mn[a];
    const float t = extent > 0.f ? (canonical.positions[i] - mn[a]) / extent : 0.5f;
    rgb[i] = static_cast<uint8_t>(std::clamp(t * 255.f + 0.5f, 0.f, 255.f));
  }
  return rgb;
}

VertexColors SelectVertexColors(const TriangleMesh& live, int64_t live_seq, const TriangleMesh* canonical,
                                int64_t canonical_seq, ColorMode mode) {
  VertexColors out;
  if (mode == ColorMode::kCanonical && canonical != nullptr && canonical_seq == live_seq &&
      canonical->num_vertices() == live.num_vertices()) {
    out.rgb = CanonicalColors(*canonical);
    out.used = ColorMode::kCanonical;
    return out;
  }
  if (mode != ColorMode::kShade && !live.colors.empty() && live.colors.size() == live.positions.size()) {
    out.rgb = live.colors;
    out.used = ColorMode::kVertex;
    return out;
  }
  out.used = ColorMode::kShade;
  return out;
}

}  // namespace vd
