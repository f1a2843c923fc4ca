// Writes a synthetic scene as a VolumeDeform-layout folder with ground truth.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

#include <opencv2/imgcodecs.hpp>

#include "vd/capture/synthetic.h"
#include "vd/common/codecs.h"

namespace vd {
namespace {

std::string FramePath(const std::string& dir, int k, const char* suffix) {
  char name[64];
  std::snprintf(name, sizeof(name), "frame-%06d.%s", k, suffix);
  return (std::filesystem::path(dir) / name).string();
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
    VD_RETURN_IF_ERROR(WritePly(FramePath(dir, i, "gt.ply"), scene.GroundTruthMesh(i)));
    const Eigen::Matrix4d pose = scene.CameraPose(i).matrix();
    std::ostringstream text;
    text << std::setprecision(17);
    for (int r = 0; r < 4; ++r) text << pose(r, 0) << " " << pose(r, 1) << " " << pose(r, 2) << " " << pose(r, 3) << "\n";
    VD_RETURN_IF_ERROR(WriteText(FramePath(dir, i, "pose.txt"), text.str()));
  }
  return Status::Ok();
}

}  // namespace vd
