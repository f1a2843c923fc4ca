// Writes a synthetic scene as a VolumeDeform-layout folder with ground truth.
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

#include <opencv2/imgcodecs.hpp>

#include "vd/capture/synthetic.h"

namespace vd {
namespace {

std::string FramePath(const std::string& dir, int k, const char* suffix) {
  char name[64];
  std::snprintf(name, sizeof(name), "frame-%06d.%s", k, suffix);
  return (std::filesystem::path(dir) / name).string();
}

template <typename T>
void AppendLittleEndian(std::string* out, T value) {
  unsigned char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  const uint16_t probe = 1;
  const bool little = *reinterpret_cast<const unsigned char*>(&probe) == 1;
  for (size_t i = 0; i < sizeof(T); ++i) out->push_back(static_cast<char>(bytes[little ? i : sizeof(T) - 1 - i]));
}

// Binary little-endian PLY with float xyz, float normals and uchar rgb when present, and int32
// faces: the layout codecs.h documents for vd::WritePly, which lives in vd::common.
Status WriteGroundTruthPly(const std::string& path, const TriangleMesh& mesh) {
  VD_RETURN_IF_ERROR(mesh.Validate());
  const bool normals = !mesh.normals.empty();
  const bool colors = !mesh.colors.empty();
  std::ostringstream header;
  header << "ply\nformat binary_little_endian 1.0\ncomment vdeform synthetic ground truth\n"
         << "element vertex " << mesh.num_vertices() << "\nproperty float x\nproperty float y\nproperty float z\n";
  if (normals) header << "property float nx\nproperty float ny\nproperty float nz\n";
  if (colors) header << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  header << "element face " << mesh.num_triangles() << "\nproperty list uchar int vertex_indices\nend_header\n";
  std::string body = header.str();
  body.reserve(body.size() + mesh.num_vertices() * 27 + mesh.num_triangles() * 13);
  for (size_t v = 0; v < mesh.num_vertices(); ++v) {
    for (int a = 0; a < 3; ++a) AppendLittleEndian(&body, mesh.positions[3 * v + a]);
    if (normals)
      for (int a = 0; a < 3; ++a) AppendLittleEndian(&body, mesh.normals[3 * v + a]);
    if (colors)
      for (int a = 0; a < 3; ++a) body.push_back(static_cast<char>(mesh.colors[3 * v + a]));
  }
  for (size_t t = 0; t < mesh.num_triangles(); ++t) {
    body.push_back(3);
    for (int a = 0; a < 3; ++a) AppendLittleEndian(&body, mesh.triangles[3 * t + a]);
  }
  std::ofstream out(path, std::ios::binary);
  if (!out) return Unavailable("cannot create '" + path + "'");
  out.write(body.data(), static_cast<std::streamsize>(body.size()));
  if (!out) return DataLoss("short write to '" + path + "'");
  return Status::Ok();
}

Status WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  if (!out) return Unavailable("cannot create '" + path + "'");
  out << text;
  if (!out) return DataLoss("short write to '" + path + "'");
  return Status::Ok();
}

Status WriteImage(const std::string& path, const cv::Mat& image) {
  try {
    if (!cv::imwrite(path, image)) return Unavailable("cannot write image '" + path + "'");
  } catch (const cv::Exception& e) {
    return Internal("OpenCV failed to write '" + path + "': " + e.what());
  }
  return Status::Ok();
}

}  // namespace

Status WriteSyntheticDataset(const SyntheticScene& scene, const std::string& dir, int n) {
  if (n < 1 || n > scene.num_frames())
    return InvalidArgument("WriteSyntheticDataset: n = " + std::to_string(n) + " violates 1 <= n <= " +
                           std::to_string(scene.num_frames()) + " (frames in scene '" + scene.name() + "')");
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return Unavailable("cannot create folder '" + dir + "': " + ec.message());

  const Intrinsics& k = scene.intrinsics();
  std::ostringstream intrinsics;
  intrinsics << std::setprecision(9) << k.fx << " 0 " << k.cx << "\n0 " << k.fy << " " << k.cy << "\n0 0 1\n";
  VD_RETURN_IF_ERROR(WriteText((std::filesystem::path(dir) / "intrinsics.txt").string(), intrinsics.str()));

  for (int i = 0; i < n; ++i) {
    const RgbdFrame frame = scene.Render(i);
    VD_RETURN_IF_ERROR(WriteImage(FramePath(dir, i, "color.png"), frame.color));
    VD_RETURN_IF_ERROR(WriteImage(FramePath(dir, i, "depth.png"), frame.depth));
    VD_RETURN_IF_ERROR(WriteGroundTruthPly(FramePath(dir, i, "gt.ply"), scene.GroundTruthMesh(i)));
    const Eigen::Matrix4d pose = scene.CameraPose(i).matrix();
    std::ostringstream text;
    text << std::setprecision(17);
    for (int r = 0; r < 4; ++r) text << pose(r, 0) << " " << pose(r, 1) << " " << pose(r, 2) << " " << pose(r, 3) << "\n";
    VD_RETURN_IF_ERROR(WriteText(FramePath(dir, i, "pose.txt"), text.str()));
  }
  return Status::Ok();
}

}  // namespace vd
