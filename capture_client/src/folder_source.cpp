// Data set folders: VolumeDeform, 7-Scenes / BundleFusion, DeepDeform, TUM RGB-D, KillingFusion.
//
// Decisions (also in the report):
// - VolumeDeform without an intrinsics file (intrinsics.txt, camera-intrinsics.txt,
//   depthIntrinsics.txt, colorIntrinsics.txt, looked for in that order) uses the intrinsics of the
//   published sequences (fx = fy = 570.342, cx = 320, cy = 240) and logs a warning, because those
//   sequences are normally distributed without one; --intrinsics overrides.
// - TUM RGB-D uses the published freiburg1/2/3 intrinsics when the folder name says which camera
//   (e.g. rgbd_dataset_freiburg1_xyz); otherwise --intrinsics is required.
// - A colour image of another size than the depth image is resized to the depth size (the
//   intrinsics describe the depth image and the frame carries one pixel grid); logged once.
// - KillingFusion omask_*.png and DeepDeform mask/*.png object masks, when present, invalidate the
//   depth outside the object (mask value < 128), since those sequences are meant to be fused as
//   the masked object only.
// - Frames are read when Next() asks for them; opening reads only the file list and frame 0.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "source_internal.h"
#include "vd/common/log.h"

namespace vd {
namespace {

namespace fs = std::filesystem;

constexpr double kDefaultFps = 30.0;
// Colour and depth of TUM RGB-D are associated when their time stamps differ by at most this.
constexpr double kTumMaxDifferenceS = 0.02;

struct FolderFrame {
  std::string depth;
  std::string color;
  // Empty when the frame has no object mask.
  std::string mask;
  // Seconds since the start of the recording (TUM: since the epoch).
  double time_s = 0.0;
};

struct FolderLayout {
  std::string name;
  std::vector<FolderFrame> frames;
  float depth_scale = 1000.f;
  std::optional<Intrinsics> intrinsics;
  // Where the intrinsics came from, for Describe().
  std::string intrinsics_origin;
  double fps = kDefaultFps;
};

// Index of "PREFIX<digits>SUFFIX", or -1 when the name has another shape.
int64_t MatchNumbered(const std::string& name, const std::string& prefix, const std::string& suffix) {
  if (name.size() <= prefix.size() + suffix.size()) return -1;
  if (name.compare(0, prefix.size(), prefix) != 0) return -1;
  if (name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0) return -1;
  const std::string digits = name.substr(prefix.size(), name.size() - prefix.size() - suffix.size());
  // Exactly what %06d prints, so the index maps back to this very name.
  if (digits.size() < 6 || digits.size() > 12 || (digits.size() > 6 && digits[0] == '0')) return -1;
  for (char c : digits)
    if (!std::isdigit(static_cast<unsigned char>(c))) return -1;
  return std::stoll(digits);
}

std::string Numbered(const std::string& prefix, int64_t index, const std::string& suffix) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%06lld", static_cast<long long>(index));
  return prefix + buf + suffix;
}

// File names (not paths) directly inside dir.
StatusOr<std::set<std::string>> ListFiles(const fs::path& dir) {
  std::set<std::string> names;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code type_ec;
    if (it->is_regular_file(type_ec)) names.insert(it->path().filename().string());
  }
  if (ec) return Unavailable("cannot list folder '" + dir.string() + "': " + ec.message());
  return names;
}

// Indices i for which PREFIX%06dSUFFIX is in names, ascending.
std::vector<int64_t> Indices(const std::set<std::string>& names, const std::string& prefix, const std::string& suffix) {
  std::vector<int64_t> out;
  for (const std::string& n : names) {
    const int64_t i = MatchNumbered(n, prefix, suffix);
    if (i >= 0) out.push_back(i);
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

// Fills frames from depth indices, requiring the colour of each; adds the mask when present.
Status NumberedFrames(const fs::path& dir, const std::set<std::string>& names, const std::vector<int64_t>& indices,
                      const std::string& depth_prefix, const std::string& depth_suffix, const std::string& color_prefix,
                      const std::string& color_suffix, const std::set<std::string>* mask_names,
                      const std::string& mask_prefix, const std::string& mask_suffix, const fs::path& mask_dir,
                      std::vector<FolderFrame>* frames) {
  int64_t k = 0;
  for (int64_t i : indices) {
    FolderFrame f;
    f.depth = (dir / Numbered(depth_prefix, i, depth_suffix)).string();
    const std::string color_name = Numbered(color_prefix, i, color_suffix);
    const fs::path color_path = dir / color_name;
    if (!names.count(color_name))
      return NotFound("colour image '" + color_path.string() + "' is missing for depth '" + f.depth + "'");
    f.color = color_path.string();
    if (mask_names) {
      const std::string mask_name = Numbered(mask_prefix, i, mask_suffix);
      if (mask_names->count(mask_name)) f.mask = (mask_dir / mask_name).string();
    }
    f.time_s = static_cast<double>(k++) / kDefaultFps;
    frames->push_back(std::move(f));
  }
  return Status::Ok();
}

// First of `candidates` present in dir, loaded; std::nullopt when none is.
StatusOr<std::optional<std::pair<Intrinsics, std::string>>> FindIntrinsicsFile(
    const fs::path& dir, const std::vector<std::string>& candidates) {
  for (const std::string& c : candidates) {
    const fs::path p = dir / c;
    std::error_code ec;
    if (!fs::is_regular_file(p, ec)) continue;
    auto k = LoadIntrinsicsFile(p.string());
    if (!k.ok()) return k.status();
    return std::optional<std::pair<Intrinsics, std::string>>(std::make_pair(*k, p.string()));
  }
  return std::optional<std::pair<Intrinsics, std::string>>();
}

// VolumeDeform (colour .png) and 7-Scenes / BundleFusion (colour .jpg): frame-%06d.*.
StatusOr<std::optional<FolderLayout>> DetectFramePrefixed(const fs::path& dir, const std::set<std::string>& names) {
  const std::vector<int64_t> indices = Indices(names, "frame-", ".depth.png");
  if (indices.empty()) return std::optional<FolderLayout>();
  FolderLayout layout;
  const bool jpg = names.count(Numbered("frame-", indices[0], ".color.jpg")) > 0;
  const std::string color_suffix = jpg ? ".color.jpg" : ".color.png";
  layout.name = jpg ? "7-Scenes" : "VolumeDeform";
  VD_RETURN_IF_ERROR(NumberedFrames(dir, names, indices, "frame-", ".depth.png", "frame-", color_suffix, nullptr, "",
                                    "", dir, &layout.frames));
  VD_ASSIGN_OR_RETURN(auto file, FindIntrinsicsFile(dir, {"intrinsics.txt", "camera-intrinsics.txt",
                                                          "depthIntrinsics.txt", "colorIntrinsics.txt"}));
  if (file) {
    layout.intrinsics = file->first;
    layout.intrinsics_origin = file->second;
  } else if (!jpg) {
    Intrinsics k;
    k.fx = k.fy = 570.342f;
    k.cx = 320.f;
    k.cy = 240.f;
    layout.intrinsics = k;
    layout.intrinsics_origin = "VolumeDeform default";
  } else {
    layout.intrinsics_origin = "missing (looked for intrinsics.txt, camera-intrinsics.txt in " + dir.string() + ")";
  }
  return std::optional<FolderLayout>(std::move(layout));
}

// DeepDeform: color/%06d.jpg, depth/%06d.png, intrinsics.txt, optional mask/%06d.png.
StatusOr<std::optional<FolderLayout>> DetectDeepDeform(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir / "depth", ec) || !fs::is_directory(dir / "color", ec)) return std::optional<FolderLayout>();
  VD_ASSIGN_OR_RETURN(auto depth_names, ListFiles(dir / "depth"));
  const std::vector<int64_t> indices = Indices(depth_names, "", ".png");
  if (indices.empty()) return std::optional<FolderLayout>();
  VD_ASSIGN_OR_RETURN(auto color_names, ListFiles(dir / "color"));
  std::set<std::string> mask_names;
  if (fs::is_directory(dir / "mask", ec)) {
    VD_ASSIGN_OR_RETURN(mask_names, ListFiles(dir / "mask"));
  }
  FolderLayout layout;
  layout.name = "DeepDeform";
  const std::string color_suffix = color_names.count(Numbered("", indices[0], ".png")) ? ".png" : ".jpg";
  int64_t k = 0;
  for (int64_t i : indices) {
    FolderFrame f;
    f.depth = (dir / "depth" / Numbered("", i, ".png")).string();
    const std::string color_name = Numbered("", i, color_suffix);
    if (!color_names.count(color_name))
      return NotFound("colour image '" + (dir / "color" / color_name).string() + "' is missing for depth '" +
                      f.depth + "'");
    f.color = (dir / "color" / color_name).string();
    const std::string mask_name = Numbered("", i, ".png");
    if (mask_names.count(mask_name)) f.mask = (dir / "mask" / mask_name).string();
    f.time_s = static_cast<double>(k++) / kDefaultFps;
    layout.frames.push_back(std::move(f));
  }
  VD_ASSIGN_OR_RETURN(auto file, FindIntrinsicsFile(dir, {"intrinsics.txt"}));
  if (file) {
    layout.intrinsics = file->first;
    layout.intrinsics_origin = file->second;
  } else {
    layout.intrinsics_origin = "missing (looked for " + (dir / "intrinsics.txt").string() + ")";
  }
  return std::optional<FolderLayout>(std::move(layout));
}

// KillingFusion: color_%06d.png, depth_%06d.png, omask_%06d.png, intrinsics_*.txt.
StatusOr<std::optional<FolderLayout>> DetectKillingFusion(const fs::path& dir, const std::set<std::string>& names) {
  const std::vector<int64_t> indices = Indices(names, "depth_", ".png");
  if (indices.empty()) return std::optional<FolderLayout>();
  FolderLayout layout;
  layout.name = "KillingFusion";
  VD_RETURN_IF_ERROR(NumberedFrames(dir, names, indices, "depth_", ".png", "color_", ".png", &names, "omask_", ".png",
                                    dir, &layout.frames));
  std::vector<std::string> intrinsics_files;
  for (const std::string& n : names)
    if (n.rfind("intrinsics", 0) == 0 && n.size() > 4 && n.compare(n.size() - 4, 4, ".txt") == 0)
      intrinsics_files.push_back(n);
  VD_ASSIGN_OR_RETURN(auto file, FindIntrinsicsFile(dir, intrinsics_files));
  if (file) {
    layout.intrinsics = file->first;
    layout.intrinsics_origin = file->second;
  } else {
    layout.intrinsics_origin = "missing (looked for intrinsics*.txt in " + dir.string() + ")";
  }
  return std::optional<FolderLayout>(std::move(layout));
}

struct TumEntry {
  double time_s = 0.0;
  std::string path;
};

StatusOr<std::vector<TumEntry>> ReadTumList(const fs::path& file) {
  std::ifstream in(file);
  if (!in) return NotFound("cannot open '" + file.string() + "'");
  std::vector<TumEntry> entries;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream ls(line);
    std::string stamp;
    TumEntry e;
    ls >> stamp >> e.path;
    char* end = nullptr;
    e.time_s = std::strtod(stamp.c_str(), &end);
    if (stamp.empty() || e.path.empty() || end != stamp.c_str() + stamp.size() || !std::isfinite(e.time_s))
      return InvalidArgument(file.string() + ":" + std::to_string(line_number) + ": expected 'timestamp path', got '" +
                             line + "'");
    entries.push_back(std::move(e));
  }
  std::sort(entries.begin(), entries.end(), [](const TumEntry& a, const TumEntry& b) { return a.time_s < b.time_s; });
  return entries;
}

// The published intrinsics of the three TUM RGB-D cameras, keyed by "freiburgN" in a folder name.
std::optional<Intrinsics> TumDefaultIntrinsics(const std::string& folder_name) {
  struct Known {
    const char* key;
    float fx, fy, cx, cy;
  };
  static const Known kKnown[] = {{"freiburg1", 517.3f, 516.5f, 318.6f, 255.3f},
                                 {"freiburg2", 520.9f, 521.0f, 325.1f, 249.7f},
                                 {"freiburg3", 535.4f, 539.2f, 320.1f, 247.6f}};
  for (const Known& k : kKnown) {
    if (folder_name.find(k.key) == std::string::npos) continue;
    Intrinsics out;
    out.fx = k.fx;
    out.fy = k.fy;
    out.cx = k.cx;
    out.cy = k.cy;
    return out;
  }
  return std::nullopt;
}

// TUM RGB-D: rgb.txt and depth.txt; each depth image is paired with the nearest colour image.
StatusOr<std::optional<FolderLayout>> DetectTum(const fs::path& dir, const std::set<std::string>& names) {
  if (!names.count("rgb.txt") || !names.count("depth.txt")) return std::optional<FolderLayout>();
  VD_ASSIGN_OR_RETURN(std::vector<TumEntry> rgb, ReadTumList(dir / "rgb.txt"));
  VD_ASSIGN_OR_RETURN(std::vector<TumEntry> depth, ReadTumList(dir / "depth.txt"));
  FolderLayout layout;
  layout.name = "TUM RGB-D";
  layout.depth_scale = 5000.f;
  int64_t unmatched = 0;
  for (const TumEntry& d : depth) {
    auto it = std::lower_bound(rgb.begin(), rgb.end(), d.time_s,
                               [](const TumEntry& e, double t) { return e.time_s < t; });
    const TumEntry* best = nullptr;
    if (it != rgb.end()) best = &*it;
    if (it != rgb.begin()) {
      const TumEntry* before = &*(it - 1);
      if (!best || d.time_s - before->time_s < best->time_s - d.time_s) best = before;
    }
    if (!best || std::abs(best->time_s - d.time_s) > kTumMaxDifferenceS) {
      ++unmatched;
      continue;
    }
    FolderFrame f;
    f.depth = (dir / d.path).string();
    f.color = (dir / best->path).string();
    f.time_s = d.time_s;
    layout.frames.push_back(std::move(f));
  }
  if (unmatched > 0) {
    VD_LOG_WARNING << dir.string() << ": " << unmatched << " of " << depth.size()
                   << " depth images have no colour image within 20 ms and are skipped";
  }
  if (layout.frames.empty())
    return NotFound("TUM RGB-D folder '" + dir.string() + "': no depth image of depth.txt (" +
                    std::to_string(depth.size()) + " entries) has a colour image of rgb.txt (" +
                    std::to_string(rgb.size()) + " entries) within 20 ms");
  if (layout.frames.size() >= 2) {
    const double span = layout.frames.back().time_s - layout.frames.front().time_s;
    if (span > 0.0) layout.fps = static_cast<double>(layout.frames.size() - 1) / span;
  }
  std::error_code ec;
  fs::path normal = fs::absolute(dir, ec).lexically_normal();
  if (ec) normal = dir.lexically_normal();
  // "a/b/" has an empty file name; its folder name is "b".
  const std::string folder_name =
      normal.filename().empty() ? normal.parent_path().filename().string() : normal.filename().string();
  layout.intrinsics = TumDefaultIntrinsics(folder_name);
  layout.intrinsics_origin = layout.intrinsics
                                 ? "TUM default for '" + folder_name + "'"
                                 : "missing (folder name '" + folder_name +
                                       "' names no TUM camera freiburg1/2/3; give --intrinsics fx,fy,cx,cy)";
  return std::optional<FolderLayout>(std::move(layout));
}

StatusOr<cv::Mat> ReadImage(const std::string& path, int flags, const char* what) {
  cv::Mat image;
  try {
    image = cv::imread(path, flags);
  } catch (const cv::Exception& e) {
    return DataLoss(std::string("cannot read ") + what + " image '" + path + "': " + e.what());
  }
  if (image.empty()) {
    std::error_code ec;
    if (!fs::exists(path, ec)) return NotFound(std::string(what) + " image '" + path + "' does not exist");
    return DataLoss(std::string("cannot decode ") + what + " image '" + path + "' (corrupt or not an image)");
  }
  return image;
}

StatusOr<cv::Mat> ReadDepth(const std::string& path) {
  VD_ASSIGN_OR_RETURN(cv::Mat depth, ReadImage(path, cv::IMREAD_UNCHANGED, "depth"));
  if (depth.type() != CV_16UC1)
    return InvalidArgument("depth image '" + path + "' has " + std::to_string(depth.channels()) + " channel(s) of " +
                           std::to_string(8 * static_cast<int>(depth.elemSize1())) +
                           " bits; expected one 16-bit channel");
  return depth;
}

class FolderSource : public FrameSource {
 public:
  FolderSource(std::string dir, FolderLayout layout, FrameSelection selection, Intrinsics intrinsics,
               float depth_scale)
      : dir_(std::move(dir)),
        layout_(std::move(layout)),
        selection_(selection),
        intrinsics_(intrinsics),
        depth_scale_(depth_scale) {}

  StatusOr<std::optional<RgbdFrame>> Next() override {
    try {
      return NextFrame();
    } catch (const std::exception& e) {
      return Internal("folder:" + dir_ + ": " + e.what());
    }
  }

  double NominalFps() const override { return layout_.fps; }
  int64_t NumFrames() const override { return selection_.NumFrames(); }

  std::string Describe() const override {
    std::ostringstream os;
    os << "folder:" << dir_ << " layout=" << layout_.name << " frames=" << selection_.per_pass() << "/"
       << layout_.frames.size() << (selection_.NumFrames() < 0 ? " (looping)" : "") << " " << intrinsics_.ToString()
       << " (" << layout_.intrinsics_origin << ") depth_scale=" << depth_scale_ << " fps=" << layout_.fps;
    return os.str();
  }

 private:
  StatusOr<std::optional<RgbdFrame>> NextFrame() {
    const std::optional<int64_t> raw = selection_.Advance();
    if (!raw) return std::optional<RgbdFrame>();
    const FolderFrame& f = layout_.frames[static_cast<size_t>(*raw)];
    RgbdFrame frame;
    frame.seq = selection_.delivered() - 1;
    // Monotonic across passes: each pass starts one frame period after the previous one ended.
    const double pass_length_s =
        layout_.frames.back().time_s - layout_.frames.front().time_s + 1.0 / std::max(layout_.fps, 1e-3);
    frame.utime = static_cast<int64_t>(std::llround((f.time_s + selection_.pass() * pass_length_s) * 1e6));
    frame.intrinsics = intrinsics_;
    frame.depth_scale = depth_scale_;
    VD_ASSIGN_OR_RETURN(frame.depth, ReadDepth(f.depth));
    if (frame.depth.cols != intrinsics_.width || frame.depth.rows != intrinsics_.height)
      return InvalidArgument("depth image '" + f.depth + "' is " + std::to_string(frame.depth.cols) + "x" +
                             std::to_string(frame.depth.rows) + " but the sequence is " +
                             std::to_string(intrinsics_.width) + "x" + std::to_string(intrinsics_.height));
    VD_ASSIGN_OR_RETURN(frame.color, ReadImage(f.color, cv::IMREAD_COLOR, "colour"));
    if (frame.color.size() != frame.depth.size()) {
      if (!warned_resize_) {
        VD_LOG_WARNING << "colour images of " << dir_ << " are " << frame.color.cols << "x" << frame.color.rows
                       << ", depth " << frame.depth.cols << "x" << frame.depth.rows
                       << ": resizing colour to the depth size";
        warned_resize_ = true;
      }
      cv::Mat resized;
      cv::resize(frame.color, resized, frame.depth.size(), 0, 0, cv::INTER_AREA);
      frame.color = resized;
    }
    if (!f.mask.empty()) {
      VD_ASSIGN_OR_RETURN(cv::Mat mask, ReadImage(f.mask, cv::IMREAD_GRAYSCALE, "mask"));
      if (mask.size() != frame.depth.size())
        return InvalidArgument("mask image '" + f.mask + "' is " + std::to_string(mask.cols) + "x" +
                               std::to_string(mask.rows) + ", depth " + std::to_string(frame.depth.cols) + "x" +
                               std::to_string(frame.depth.rows));
      frame.depth.setTo(0, mask < 128);
    }
    return std::optional<RgbdFrame>(std::move(frame));
  }

  std::string dir_;
  FolderLayout layout_;
  FrameSelection selection_;
  Intrinsics intrinsics_;
  float depth_scale_;
  // The resize warning is given once per source, not once per frame.
  bool warned_resize_ = false;
};

StatusOr<std::unique_ptr<FrameSource>> OpenFolder(const std::string& dir_text, const SourceOptions& options) {
  VD_RETURN_IF_ERROR(options.Validate());
  const fs::path dir(dir_text);
  std::error_code ec;
  if (!fs::exists(dir, ec)) return NotFound("folder '" + dir_text + "' does not exist");
  if (!fs::is_directory(dir, ec)) return InvalidArgument("'" + dir_text + "' is not a folder");
  VD_ASSIGN_OR_RETURN(std::set<std::string> names, ListFiles(dir));

  std::optional<FolderLayout> layout;
  VD_ASSIGN_OR_RETURN(layout, DetectTum(dir, names));
  if (!layout) {
    VD_ASSIGN_OR_RETURN(layout, DetectDeepDeform(dir));
  }
  if (!layout) {
    VD_ASSIGN_OR_RETURN(layout, DetectKillingFusion(dir, names));
  }
  if (!layout) {
    VD_ASSIGN_OR_RETURN(layout, DetectFramePrefixed(dir, names));
  }
  if (!layout)
    return NotFound("folder '" + dir_text +
                    "' has no known layout; looked for rgb.txt + depth.txt (TUM RGB-D), "
                    "depth/NNNNNN.png + color/NNNNNN.jpg (DeepDeform), depth_NNNNNN.png + color_NNNNNN.png "
                    "(KillingFusion), frame-NNNNNN.depth.png + frame-NNNNNN.color.png (VolumeDeform) or "
                    "frame-NNNNNN.color.jpg (7-Scenes / BundleFusion)");

  const std::string what = "folder '" + dir_text + "' (" + layout->name + ")";
  VD_ASSIGN_OR_RETURN(FrameSelection selection,
                      FrameSelection::Make(static_cast<int64_t>(layout->frames.size()), options, what));
  // The first delivered depth image fixes the size and shows early that depth is 16-bit.
  VD_ASSIGN_OR_RETURN(cv::Mat first, ReadDepth(layout->frames[static_cast<size_t>(options.start)].depth));
  if (!layout->intrinsics && options.intrinsics.empty())
    return FailedPrecondition(what + ": intrinsics " + layout->intrinsics_origin +
                              "; give them with --intrinsics fx,fy,cx,cy");
  VD_ASSIGN_OR_RETURN(Intrinsics intrinsics,
                      ResolveIntrinsics(layout->intrinsics, options, first.cols, first.rows, what));
  if (!options.intrinsics.empty()) layout->intrinsics_origin = "--intrinsics";
  if (layout->intrinsics_origin == "VolumeDeform default") {
    VD_LOG_WARNING << what << ": no intrinsics file (intrinsics.txt, camera-intrinsics.txt, depthIntrinsics.txt, "
                   << "colorIntrinsics.txt); using the published VolumeDeform intrinsics fx=fy=570.342 cx=320 cy=240";
  }
  const float depth_scale = options.depth_scale > 0.f ? options.depth_scale : layout->depth_scale;
  auto source = std::make_unique<FolderSource>(dir_text, std::move(*layout), selection, intrinsics, depth_scale);
  return std::unique_ptr<FrameSource>(std::move(source));
}

}  // namespace

StatusOr<std::unique_ptr<FrameSource>> OpenFolderSource(const std::string& dir_text, const SourceOptions& options) {
  try {
    return OpenFolder(dir_text, options);
  } catch (const std::exception& e) {
    return Internal("folder:" + dir_text + ": " + e.what());
  }
}

}  // namespace vd
