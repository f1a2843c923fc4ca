#include "vd/viewer/render.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "shared/raster_math.h"

namespace vd {
namespace {

// Grey used when a mesh has no colour (or in kShade mode): light enough that shading reads well.
constexpr uint8_t kGrey = 200;
// Zoom beyond these bounds only produces empty or single-pixel images.
constexpr float kMinZoom = 1e-3f;
constexpr float kMaxZoom = 1e3f;

// The mesh seen from the (orbited) live camera: camera-space vertices, the fitted focal length and
// principal point, and how far the eye moved back.
struct View {
  std::vector<Eigen::Vector3d> p;
  double f = 1.0, cx = 0.0, cy = 0.0;
  double eye_offset_z = 0.0;
};

View OrbitAndFit(const TriangleMesh& mesh, const RenderOptions& options, const ViewParams& params) {
  // Orbit about the bounding-box centre; the unrotated view is exactly the live camera's.
  float mn[3], mx[3];
  mesh.Bounds(mn, mx);
  const Eigen::Vector3d centre(0.5 * (mn[0] + mx[0]), 0.5 * (mn[1] + mx[1]), 0.5 * (mn[2] + mx[2]));
  const double radius = std::max(1e-6, 0.5 * Eigen::Vector3d(mx[0] - mn[0], mx[1] - mn[1], mx[2] - mn[2]).norm());
  const Eigen::Matrix3d rotation = (Eigen::AngleAxisd(params.pitch, Eigen::Vector3d::UnitX()) *
                                    Eigen::AngleAxisd(params.yaw, Eigen::Vector3d::UnitY()))
                                       .toRotationMatrix();
  View view;
  view.p.resize(mesh.num_vertices());
  double z_min = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < view.p.size(); ++i) {
    const Eigen::Vector3d v(mesh.positions[3 * i], mesh.positions[3 * i + 1], mesh.positions[3 * i + 2]);
    view.p[i] = rotation * (v - centre) + centre;
    z_min = std::min(z_min, view.p[i].z());
  }
  // A mesh reaching behind the camera (a canonical mesh in odd coordinates, an orbit that swings
  // it round) is seen from further back instead: the bounding sphere then lies in front.
  if (z_min < std::max(1e-4, 1e-2 * radius)) {
    view.eye_offset_z = 2.0 * radius - centre.z();
    for (auto& v : view.p) v.z() += view.eye_offset_z;
  }
  // The focal length that fits the projected vertices' bounding box into the image minus the
  // margins, the principal point that centres it.
  double a_min = std::numeric_limits<double>::infinity(), a_max = -a_min, b_min = a_min, b_max = -a_min;
  for (const auto& v : view.p) {
    a_min = std::min(a_min, v.x() / v.z());
    a_max = std::max(a_max, v.x() / v.z());
    b_min = std::min(b_min, v.y() / v.z());
    b_max = std::max(b_max, v.y() / v.z());
  }
  const double usable = 1.0 - 2.0 * options.margin;
  const double span_a = std::max(a_max - a_min, 1e-9), span_b = std::max(b_max - b_min, 1e-9);
  view.f = std::min(options.width * usable / span_a, options.height * usable / span_b) * params.zoom;
  view.cx = 0.5 * options.width - view.f * 0.5 * (a_min + a_max);
  view.cy = 0.5 * options.height - view.f * 0.5 * (b_min + b_max);
  return view;
}

// Smooth shading: area-weighted vertex normals (Draco meshes arrive without normals).
std::vector<Eigen::Vector3d> VertexNormals(const std::vector<Eigen::Vector3d>& p, const std::vector<int32_t>& tris) {
  std::vector<Eigen::Vector3d> normal(p.size(), Eigen::Vector3d::Zero());
  for (size_t t = 0; t < tris.size(); t += 3) {
    const Eigen::Vector3d face = (p[tris[t + 1]] - p[tris[t]]).cross(p[tris[t + 2]] - p[tris[t]]);
    for (int k = 0; k < 3; ++k) normal[tris[t + k]] += face;
  }
  for (auto& nv : normal) {
    const double len = nv.norm();
    nv = len > 0 ? Eigen::Vector3d(nv / len) : Eigen::Vector3d(0, 0, -1);
  }
  return normal;
}

// Snapped corners; ok = false for a vertex projecting beyond VD_RASTER_MAX_PX. The viewer's pixel
// centres sit at half-integer coordinates, the shared math's at integers: shift by half a pixel.
struct Corner {
  VdRasterCorner c{};
  bool ok = false;
};

std::vector<Corner> Project(const View& view) {
  std::vector<Corner> corners(view.p.size());
  for (size_t i = 0; i < view.p.size(); ++i) {
    const double u = view.f * view.p[i].x() / view.p[i].z() + view.cx - 0.5;
    const double v = view.f * view.p[i].y() / view.p[i].z() + view.cy - 0.5;
    if (!(std::fabs(u) < VD_RASTER_MAX_PX && std::fabs(v) < VD_RASTER_MAX_PX)) continue;
    corners[i].c = VdRasterCorner{std::llround(u * VD_RASTER_SUB_SCALE), std::llround(v * VD_RASTER_SUB_SCALE),
                                  static_cast<float>(view.p[i].z())};
    corners[i].ok = true;
  }
  return corners;
}

VdRasterTri Setup(const std::vector<Corner>& corners, const int32_t* tri, int w, int h) {
  if (!(corners[tri[0]].ok && corners[tri[1]].ok && corners[tri[2]].ok)) return vd_raster_tri_empty();
  return vd_raster_tri(corners[tri[0]].c, corners[tri[1]].c, corners[tri[2]].c, VdRasterBox{0, 0, w - 1, h - 1});
}

// The triangle seen at each pixel (-1: none). The z-buffer holds 1 / z; the first triangle wins ties.
std::vector<int32_t> Visibility(const std::vector<Corner>& corners, const std::vector<int32_t>& tris, int w, int h) {
  std::vector<float> inv_depth(static_cast<size_t>(w) * h, 0.f);
  std::vector<int32_t> visible(inv_depth.size(), -1);
  for (size_t t = 0; t < tris.size() / 3; ++t) {
    const VdRasterTri r = Setup(corners, &tris[3 * t], w, h);
    for (int y = r.box.y0; y <= r.box.y1; ++y)
      for (int x = r.box.x0; x <= r.box.x1; ++x) {
        vd_long w0, w1, w2;
        if (!vd_raster_cover(r, x, y, &w0, &w1, &w2)) continue;
        const size_t idx = static_cast<size_t>(y) * w + x;
        const float inv_z = vd_raster_inv_depth(r, w0, w1, w2);
        if (inv_z <= inv_depth[idx]) continue;
        inv_depth[idx] = inv_z;
        visible[idx] = static_cast<int32_t>(t);
      }
  }
  return visible;
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
                                  const RenderOptions& options, const ViewParams& params) {
  VD_RETURN_IF_ERROR(options.Validate());
  VD_RETURN_IF_ERROR(mesh.Validate());
  if (!rgb.empty() && rgb.size() != mesh.positions.size())
    return InvalidArgument("RenderMesh: " + std::to_string(rgb.size() / 3) + " colours for " +
                           std::to_string(mesh.num_vertices()) + " vertices");
  if (!std::isfinite(params.yaw) || !std::isfinite(params.pitch) || !std::isfinite(params.zoom) ||
      params.zoom < kMinZoom || params.zoom > kMaxZoom)
    return InvalidArgument("ViewParams: yaw and pitch must be finite and zoom within [0.001, 1000], got zoom = " +
                           std::to_string(params.zoom));

  const int w = options.width;
  const int h = options.height;
  RenderResult result;
  result.image = cv::Mat(h, w, CV_8UC3, cv::Scalar(options.background[0], options.background[1], options.background[2]));
  result.depth = cv::Mat::zeros(h, w, CV_32FC1);
  result.intrinsics = Intrinsics{1.f, 1.f, w / 2.f, h / 2.f, w, h};
  if (mesh.empty()) return result;

  const View view = OrbitAndFit(mesh, options, params);
  result.eye_offset_z = static_cast<float>(view.eye_offset_z);
  result.intrinsics = Intrinsics{static_cast<float>(view.f), static_cast<float>(view.f), static_cast<float>(view.cx),
                                 static_cast<float>(view.cy), w, h};
  const std::vector<Eigen::Vector3d> normal = VertexNormals(view.p, mesh.triangles);
  const std::vector<Corner> corners = Project(view);
  // Shading waits for the visibility pass, so hidden surfaces cost no shading.
  const std::vector<int32_t> visible = Visibility(corners, mesh.triangles, w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const int32_t t = visible[static_cast<size_t>(y) * w + x];
      if (t < 0) continue;
      const int32_t* tri = &mesh.triangles[3 * t];
      const VdRasterTri r = Setup(corners, tri, w, h);
      vd_long w0, w1, w2;
      vd_raster_cover(r, x, y, &w0, &w1, &w2);
      const vd_float4 b = vd_raster_bary(r, w0, w1, w2);
      const Eigen::Vector3d nrm = (b.x * normal[tri[0]] + b.y * normal[tri[1]] + b.z * normal[tri[2]]).normalized();
      const Eigen::Vector3d ray =
          Eigen::Vector3d((x + 0.5 - view.cx) / view.f, (y + 0.5 - view.cy) / view.f, 1.0).normalized();
      // Headlight: the light sits at the eye, so brightness is |cos| between normal and ray
      // (two-sided: marching-cubes surfaces seen from behind at their borders stay lit).
      const double lambert = std::isfinite(nrm.x()) ? std::abs(nrm.dot(ray)) : 1.0;
      const double shade = options.ambient + (1.0 - options.ambient) * lambert;
      cv::Vec3b& px = result.image.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c) {
        const double value =
            rgb.empty() ? kGrey : b.x * rgb[3 * tri[0] + c] + b.y * rgb[3 * tri[1] + c] + b.z * rgb[3 * tri[2] + c];
        px[2 - c] = static_cast<uint8_t>(std::clamp(value * shade + 0.5, 0.0, 255.0));
      }
      result.depth.at<float>(y, x) = 1.f / vd_raster_inv_depth(r, w0, w1, w2);
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
  if (mode == ColorMode::kCanonical && !live.canonical.empty() && live.canonical.size() == live.positions.size()) {
    TriangleMesh own;
    own.positions = live.canonical;
    out.rgb = CanonicalColors(own);
    out.used = ColorMode::kCanonical;
    return out;
  }
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
