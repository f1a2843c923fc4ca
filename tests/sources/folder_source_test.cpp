// Data set folders: the real 7-Scenes and KillingFusion samples (skipped when absent) and tiny
// VolumeDeform, DeepDeform and TUM RGB-D fixtures written to a temporary folder at test time.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "vd/capture/source.h"

namespace vd {
namespace {

namespace fs = std::filesystem;

const std::string kData = VD_SHARED_DATA_DIR;

// A fresh temporary folder, removed at the end of the test.
class TempDir {
 public:
  explicit TempDir(const std::string& leaf = "") {
    std::string tmpl = (fs::temp_directory_path() / "vd_folder_test_XXXXXX").string();
    std::vector<char> buf(tmpl.begin(), tmpl.end());
    buf.push_back('\0');
    root_ = mkdtemp(buf.data());
    path_ = leaf.empty() ? root_ : root_ / leaf;
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }
  const fs::path& path() const { return path_; }
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path root_;
  fs::path path_;
};

// Depth whose every pixel is `value` except a ramp in the first row, so frames differ.
cv::Mat FixtureDepth(int w, int h, uint16_t value) {
  cv::Mat d(h, w, CV_16UC1, cv::Scalar(value));
  for (int x = 0; x < w; ++x) d.at<uint16_t>(0, x) = static_cast<uint16_t>(value + x);
  return d;
}

cv::Mat FixtureColor(int w, int h, int k) { return cv::Mat(h, w, CV_8UC3, cv::Scalar(10 * k, 100, 200)); }

void WriteText(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

StatusOr<std::vector<RgbdFrame>> ReadAll(FrameSource& source, int limit = 1000) {
  std::vector<RgbdFrame> frames;
  for (int i = 0; i < limit; ++i) {
    VD_ASSIGN_OR_RETURN(std::optional<RgbdFrame> f, source.Next());
    if (!f) break;
    frames.push_back(std::move(*f));
  }
  return frames;
}

bool SameImage(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

std::string SevenScenes() {
  const std::string dir = kData + "/7scenes_redkitchen";
  return fs::exists(dir + "/frame-000000.depth.png") ? dir : std::string();
}

TEST(FolderSource, SevenScenesRedKitchen) {
  const std::string dir = SevenScenes();
  if (dir.empty()) GTEST_SKIP() << "shared data " << kData << "/7scenes_redkitchen is absent";
  auto source = OpenSource("folder:" + dir, {});
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  EXPECT_EQ((*source)->NumFrames(), 300);
  EXPECT_DOUBLE_EQ((*source)->NominalFps(), 30.0);
  EXPECT_NE((*source)->Describe().find("7-Scenes"), std::string::npos) << (*source)->Describe();
  auto first = (*source)->Next();
  ASSERT_TRUE(first.ok()) << first.status().ToString();
  ASSERT_TRUE(first->has_value());
  const RgbdFrame& f = **first;
  ASSERT_TRUE(f.Validate().ok()) << f.Validate().ToString();
  EXPECT_EQ(f.depth.cols, 640);
  EXPECT_EQ(f.depth.rows, 480);
  EXPECT_EQ(f.color.type(), CV_8UC3);
  EXPECT_EQ(f.color.size(), f.depth.size());
  EXPECT_FLOAT_EQ(f.intrinsics.fx, 585.f);
  EXPECT_FLOAT_EQ(f.intrinsics.fy, 585.f);
  EXPECT_FLOAT_EQ(f.intrinsics.cx, 320.f);
  EXPECT_FLOAT_EQ(f.intrinsics.cy, 240.f);
  EXPECT_FLOAT_EQ(f.depth_scale, 1000.f);
  EXPECT_EQ(f.seq, 0);
  // A kitchen seen from a hand-held Kinect: most pixels valid, median depth at arm's length.
  std::vector<float> valid;
  const cv::Mat metres = f.DepthMetres();
  for (int y = 0; y < metres.rows; ++y)
    for (int x = 0; x < metres.cols; ++x)
      if (std::isfinite(metres.at<float>(y, x))) valid.push_back(metres.at<float>(y, x));
  EXPECT_GT(valid.size(), 640u * 480u / 2);
  std::nth_element(valid.begin(), valid.begin() + valid.size() / 2, valid.end());
  const float median = valid[valid.size() / 2];
  EXPECT_GT(median, 0.5f);
  EXPECT_LT(median, 4.f);
  // Colour really is the JPEG of frame 0.
  EXPECT_TRUE(SameImage(f.color, cv::imread(dir + "/frame-000000.color.jpg", cv::IMREAD_COLOR)));
}

TEST(FolderSource, SevenScenesStartCountStride) {
  const std::string dir = SevenScenes();
  if (dir.empty()) GTEST_SKIP() << "shared data " << kData << "/7scenes_redkitchen is absent";
  SourceOptions o;
  o.start = 10;
  o.count = 5;
  o.stride = 3;
  auto source = OpenSource("folder:" + dir, o);
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  EXPECT_EQ((*source)->NumFrames(), 5);
  auto frames = ReadAll(**source);
  ASSERT_TRUE(frames.ok()) << frames.status().ToString();
  ASSERT_EQ(frames->size(), 5u);
  const int expected[] = {10, 13, 16, 19, 22};
  for (int i = 0; i < 5; ++i) {
    char name[64];
    std::snprintf(name, sizeof(name), "/frame-%06d.depth.png", expected[i]);
    EXPECT_TRUE(SameImage((*frames)[i].depth, cv::imread(dir + name, cv::IMREAD_UNCHANGED))) << name;
    EXPECT_EQ((*frames)[i].seq, i);
    // utime follows the raw frame index at 30 Hz.
    EXPECT_NEAR((*frames)[i].utime, expected[i] * 1e6 / 30.0, 1.0);
  }
  // ceil((300 - 290) / 4) = 3 frames remain.
  o = SourceOptions();
  o.start = 290;
  o.stride = 4;
  auto tail = OpenSource("folder:" + dir, o);
  ASSERT_TRUE(tail.ok());
  EXPECT_EQ((*tail)->NumFrames(), 3);
  o.start = 300;
  auto past = OpenSource("folder:" + dir, o);
  ASSERT_FALSE(past.ok());
  EXPECT_EQ(past.status().code(), StatusCode::kOutOfRange);
  EXPECT_NE(past.status().message().find("300"), std::string::npos) << past.status().message();
}

TEST(FolderSource, SevenScenesLoopRepeatsTheSelection) {
  const std::string dir = SevenScenes();
  if (dir.empty()) GTEST_SKIP() << "shared data " << kData << "/7scenes_redkitchen is absent";
  SourceOptions o;
  o.start = 5;
  o.count = 2;
  o.loop = true;
  auto source = OpenSource("folder:" + dir, o);
  ASSERT_TRUE(source.ok());
  EXPECT_EQ((*source)->NumFrames(), -1);
  auto frames = ReadAll(**source, 5);
  ASSERT_TRUE(frames.ok());
  ASSERT_EQ(frames->size(), 5u);
  EXPECT_TRUE(SameImage((*frames)[0].depth, (*frames)[2].depth));
  EXPECT_TRUE(SameImage((*frames)[1].depth, (*frames)[3].depth));
  EXPECT_FALSE(SameImage((*frames)[0].depth, (*frames)[1].depth));
  for (size_t i = 1; i < frames->size(); ++i) {
    EXPECT_GT((*frames)[i].utime, (*frames)[i - 1].utime);
    EXPECT_EQ((*frames)[i].seq, static_cast<int64_t>(i));
  }
}

TEST(FolderSource, KillingFusionSnoopyAppliesTheObjectMask) {
  const std::string dir = kData + "/killingfusion_snoopy";
  if (!fs::exists(dir + "/depth_000000.png")) GTEST_SKIP() << "shared data " << dir << " is absent";
  auto source = OpenSource("folder:" + dir, {});
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  EXPECT_EQ((*source)->NumFrames(), 2);
  auto frames = ReadAll(**source);
  ASSERT_TRUE(frames.ok()) << frames.status().ToString();
  ASSERT_EQ(frames->size(), 2u);
  for (int k = 0; k < 2; ++k) {
    const RgbdFrame& f = (*frames)[k];
    ASSERT_TRUE(f.Validate().ok());
    EXPECT_FLOAT_EQ(f.intrinsics.fx, 517.f);
    EXPECT_FLOAT_EQ(f.intrinsics.cx, 320.f);
    char suffix[32];
    std::snprintf(suffix, sizeof(suffix), "_%06d.png", k);
    const cv::Mat mask = cv::imread(dir + "/omask" + suffix, cv::IMREAD_GRAYSCALE);
    const cv::Mat raw = cv::imread(dir + "/depth" + suffix, cv::IMREAD_UNCHANGED);
    ASSERT_EQ(mask.size(), f.depth.size());
    int outside_raw = 0, outside_kept = 0, inside_raw = 0, inside_kept = 0;
    for (int y = 0; y < raw.rows; ++y)
      for (int x = 0; x < raw.cols; ++x) {
        const bool object = mask.at<uint8_t>(y, x) >= 128;
        const uint16_t r = raw.at<uint16_t>(y, x), d = f.depth.at<uint16_t>(y, x);
        if (object) {
          inside_raw += r > 0;
          inside_kept += d > 0 && d == r;
        } else {
          outside_raw += r > 0;
          outside_kept += d > 0;
        }
      }
    EXPECT_GT(outside_raw, 1000) << "the mask should remove something";
    EXPECT_EQ(outside_kept, 0);
    EXPECT_GT(inside_raw, 1000);
    EXPECT_EQ(inside_kept, inside_raw) << "depth on the object is untouched";
  }
}

TEST(FolderSource, VolumeDeformFixtureDefaultsIntrinsicsAndResizesColour) {
  TempDir dir;
  for (int k = 0; k < 3; ++k) {
    char name[64];
    std::snprintf(name, sizeof(name), "frame-%06d.depth.png", k);
    ASSERT_TRUE(cv::imwrite(dir / name, FixtureDepth(320, 240, static_cast<uint16_t>(1000 + k))));
    std::snprintf(name, sizeof(name), "frame-%06d.color.png", k);
    // Colour at half the depth size: resized to the depth grid.
    ASSERT_TRUE(cv::imwrite(dir / name, FixtureColor(160, 120, k)));
  }
  auto source = OpenSource("folder:" + dir.path().string(), {});
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  EXPECT_NE((*source)->Describe().find("VolumeDeform"), std::string::npos);
  EXPECT_EQ((*source)->NumFrames(), 3);
  auto frames = ReadAll(**source);
  ASSERT_TRUE(frames.ok()) << frames.status().ToString();
  ASSERT_EQ(frames->size(), 3u);
  for (int k = 0; k < 3; ++k) {
    const RgbdFrame& f = (*frames)[k];
    ASSERT_TRUE(f.Validate().ok()) << f.Validate().ToString();
    EXPECT_FLOAT_EQ(f.intrinsics.fx, 570.342f);
    EXPECT_FLOAT_EQ(f.intrinsics.cy, 240.f);
    EXPECT_EQ(f.intrinsics.width, 320);
    EXPECT_EQ(f.depth.at<uint16_t>(100, 100), 1000 + k);
    EXPECT_EQ(f.depth.at<uint16_t>(0, 5), 1005 + k);
    ASSERT_EQ(f.color.size(), cv::Size(320, 240));
    EXPECT_EQ(f.color.at<cv::Vec3b>(120, 160), cv::Vec3b(10 * k, 100, 200));
  }
  // An intrinsics file wins over the default, --intrinsics over both, depth scale overrides.
  WriteText(dir / "intrinsics.txt", "500 0 160\n0 501 120\n0 0 1\n");
  auto with_file = OpenSource("folder:" + dir.path().string(), {});
  ASSERT_TRUE(with_file.ok());
  auto f = (*with_file)->Next();
  ASSERT_TRUE(f.ok() && f->has_value());
  EXPECT_FLOAT_EQ((*f)->intrinsics.fx, 500.f);
  EXPECT_FLOAT_EQ((*f)->intrinsics.fy, 501.f);
  SourceOptions o;
  o.intrinsics = "300,301,150,110";
  o.depth_scale = 2000.f;
  auto with_flag = OpenSource("folder:" + dir.path().string(), o);
  ASSERT_TRUE(with_flag.ok());
  f = (*with_flag)->Next();
  ASSERT_TRUE(f.ok() && f->has_value());
  EXPECT_FLOAT_EQ((*f)->intrinsics.fx, 300.f);
  EXPECT_FLOAT_EQ((*f)->intrinsics.cy, 110.f);
  EXPECT_FLOAT_EQ((*f)->depth_scale, 2000.f);
}

TEST(FolderSource, DeepDeformFixtureWithPartialMasks) {
  TempDir dir;
  fs::create_directories(dir.path() / "color");
  fs::create_directories(dir.path() / "depth");
  fs::create_directories(dir.path() / "mask");
  for (int k = 0; k < 2; ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d", k);
    ASSERT_TRUE(cv::imwrite(dir / ("depth/" + std::string(name) + ".png"), FixtureDepth(64, 48, 1500)));
    ASSERT_TRUE(cv::imwrite(dir / ("color/" + std::string(name) + ".jpg"), FixtureColor(64, 48, k)));
  }
  // Only frame 1 has a mask: the left half is the object.
  cv::Mat mask(48, 64, CV_8UC1, cv::Scalar(0));
  mask.colRange(0, 32).setTo(255);
  ASSERT_TRUE(cv::imwrite(dir / "mask/000001.png", mask));
  WriteText(dir / "intrinsics.txt", "60 0 32 0\n0 61 24 0\n0 0 1 0\n0 0 0 1\n");
  auto source = OpenSource("folder:" + dir.path().string(), {});
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  EXPECT_NE((*source)->Describe().find("DeepDeform"), std::string::npos);
  auto frames = ReadAll(**source);
  ASSERT_TRUE(frames.ok()) << frames.status().ToString();
  ASSERT_EQ(frames->size(), 2u);
  EXPECT_FLOAT_EQ((*frames)[0].intrinsics.fx, 60.f);
  EXPECT_FLOAT_EQ((*frames)[0].intrinsics.fy, 61.f);
  EXPECT_FLOAT_EQ((*frames)[0].intrinsics.cy, 24.f);
  EXPECT_EQ(cv::countNonZero((*frames)[0].depth), 64 * 48);
  EXPECT_EQ(cv::countNonZero((*frames)[1].depth), 32 * 48);
  EXPECT_EQ((*frames)[1].depth.at<uint16_t>(20, 10), 1500);
  EXPECT_EQ((*frames)[1].depth.at<uint16_t>(20, 50), 0);
}

// depth.txt / rgb.txt with comments; depth at 1.000, 1.033, 1.066, 1.100 s, colour at 0.990,
// 1.040, 1.060, 1.200 s: the first three pair up (10, 7, 6 ms apart), the last depth has no
// colour within 20 ms and is skipped.
void WriteTumFixture(const TempDir& dir) {
  fs::create_directories(dir.path() / "rgb");
  fs::create_directories(dir.path() / "depth");
  const char* rgb_stamps[] = {"0.990000", "1.040000", "1.060000", "1.200000"};
  const char* depth_stamps[] = {"1.000000", "1.033000", "1.066000", "1.100000"};
  std::string rgb_txt = "# color images\n# file: 'rgbd_dataset_freiburg1_test.bag'\n# timestamp filename\n";
  std::string depth_txt = "# depth maps\n# file: 'rgbd_dataset_freiburg1_test.bag'\n# timestamp filename\n";
  for (int k = 0; k < 4; ++k) {
    const std::string rgb = std::string("rgb/") + rgb_stamps[k] + ".png";
    const std::string depth = std::string("depth/") + depth_stamps[k] + ".png";
    cv::imwrite(dir / rgb, FixtureColor(64, 48, k));
    cv::imwrite(dir / depth, FixtureDepth(64, 48, static_cast<uint16_t>(5000 + k)));
    rgb_txt += std::string(rgb_stamps[k]) + " " + rgb + "\n";
    depth_txt += std::string(depth_stamps[k]) + " " + depth + "\n";
  }
  WriteText(dir / "rgb.txt", rgb_txt);
  WriteText(dir / "depth.txt", depth_txt);
}

TEST(FolderSource, TumFixtureAssociatesByTimestamp) {
  TempDir dir("rgbd_dataset_freiburg1_test");
  WriteTumFixture(dir);
  SourceOptions o;
  // The published fr1 intrinsics refer to 640x480; these fixture images are 64x48.
  o.intrinsics = "51.73,51.65,31.86,25.53";
  auto source = OpenSource("folder:" + dir.path().string(), o);
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  EXPECT_EQ((*source)->NumFrames(), 3);
  // Three frames over 66 ms.
  EXPECT_NEAR((*source)->NominalFps(), 2.0 / 0.066, 1e-6);
  auto frames = ReadAll(**source);
  ASSERT_TRUE(frames.ok()) << frames.status().ToString();
  ASSERT_EQ(frames->size(), 3u);
  for (int k = 0; k < 3; ++k) {
    const RgbdFrame& f = (*frames)[k];
    EXPECT_FLOAT_EQ(f.depth_scale, 5000.f);
    EXPECT_EQ(f.depth.at<uint16_t>(10, 10), 5000 + k);
    // Colour k is the one nearest in time to depth k.
    EXPECT_EQ(f.color.at<cv::Vec3b>(10, 10), cv::Vec3b(10 * k, 100, 200)) << "frame " << k;
  }
  EXPECT_NEAR((*frames)[1].utime, 1.033e6, 1.0);
}

TEST(FolderSource, TumIntrinsicsFromTheFolderNameOrRequired) {
  TempDir named("rgbd_dataset_freiburg3_test");
  WriteTumFixture(named);
  // Full-size depth so the published 640x480 intrinsics validate.
  cv::imwrite(named / "depth/1.000000.png", FixtureDepth(640, 480, 5000));
  auto source = OpenSource("folder:" + named.path().string(), {});
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  EXPECT_NE((*source)->Describe().find("fx=535.4"), std::string::npos) << (*source)->Describe();

  TempDir unnamed("my_recording");
  WriteTumFixture(unnamed);
  auto missing = OpenSource("folder:" + unnamed.path().string(), {});
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(missing.status().message().find("--intrinsics"), std::string::npos) << missing.status().message();
  EXPECT_NE(missing.status().message().find("my_recording"), std::string::npos) << missing.status().message();
}

TEST(FolderSource, MissingFolder) {
  auto s = OpenSource("folder:/nonexistent/vd_no_such_folder", {});
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), StatusCode::kNotFound);
  EXPECT_NE(s.status().message().find("/nonexistent/vd_no_such_folder"), std::string::npos);
}

TEST(FolderSource, UnknownLayoutSaysWhatWasLookedFor) {
  TempDir dir;
  WriteText(dir / "notes.txt", "nothing here");
  cv::imwrite(dir / "image0.png", FixtureDepth(8, 8, 1));
  // Not %06d numbering: "frame-1" would map back to "frame-000001", a file that does not exist.
  cv::imwrite(dir / "frame-1.depth.png", FixtureDepth(8, 8, 1));
  cv::imwrite(dir / "frame-1.color.png", FixtureColor(8, 8, 1));
  auto s = OpenSource("folder:" + dir.path().string(), {});
  ASSERT_FALSE(s.ok());
  const std::string& m = s.status().message();
  EXPECT_NE(m.find("rgb.txt"), std::string::npos) << m;
  EXPECT_NE(m.find("frame-NNNNNN.depth.png"), std::string::npos) << m;
  EXPECT_NE(m.find("depth_NNNNNN.png"), std::string::npos) << m;
  EXPECT_NE(m.find("depth/NNNNNN.png"), std::string::npos) << m;
}

TEST(FolderSource, SevenScenesLayoutWithoutIntrinsics) {
  TempDir dir;
  cv::imwrite(dir / "frame-000000.depth.png", FixtureDepth(64, 48, 1000));
  cv::imwrite(dir / "frame-000000.color.jpg", FixtureColor(64, 48, 0));
  auto s = OpenSource("folder:" + dir.path().string(), {});
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(s.status().message().find("camera-intrinsics.txt"), std::string::npos) << s.status().message();
  EXPECT_NE(s.status().message().find("--intrinsics"), std::string::npos) << s.status().message();
  SourceOptions o;
  o.intrinsics = "50,50,32,24";
  EXPECT_TRUE(OpenSource("folder:" + dir.path().string(), o).ok());
}

TEST(FolderSource, CorruptAndWrongImagesNameTheFile) {
  TempDir dir;
  WriteText(dir / "camera-intrinsics.txt", "50 0 32\n0 50 24\n0 0 1\n");
  for (int k = 0; k < 3; ++k) {
    char name[64];
    std::snprintf(name, sizeof(name), "frame-%06d.color.jpg", k);
    cv::imwrite(dir / name, FixtureColor(64, 48, k));
  }
  cv::imwrite(dir / "frame-000000.depth.png", FixtureDepth(64, 48, 1000));
  WriteText(dir / "frame-000001.depth.png", "this is not a PNG file");
  cv::imwrite(dir / "frame-000002.depth.png", cv::Mat(48, 64, CV_8UC1, cv::Scalar(7)));
  auto source = OpenSource("folder:" + dir.path().string(), {});
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  auto f0 = (*source)->Next();
  ASSERT_TRUE(f0.ok() && f0->has_value());
  auto f1 = (*source)->Next();
  ASSERT_FALSE(f1.ok());
  EXPECT_EQ(f1.status().code(), StatusCode::kDataLoss);
  EXPECT_NE(f1.status().message().find("frame-000001.depth.png"), std::string::npos) << f1.status().message();
  auto f2 = (*source)->Next();
  ASSERT_FALSE(f2.ok());
  EXPECT_NE(f2.status().message().find("frame-000002.depth.png"), std::string::npos) << f2.status().message();
  EXPECT_NE(f2.status().message().find("16-bit"), std::string::npos) << f2.status().message();

  // An 8-bit first frame is refused when the folder is opened.
  SourceOptions o;
  o.start = 2;
  auto eight_bit = OpenSource("folder:" + dir.path().string(), o);
  ASSERT_FALSE(eight_bit.ok());
  EXPECT_NE(eight_bit.status().message().find("16-bit"), std::string::npos);
}

TEST(FolderSource, MissingColourImageIsNamed) {
  TempDir dir;
  WriteText(dir / "camera-intrinsics.txt", "50 0 32\n0 50 24\n0 0 1\n");
  cv::imwrite(dir / "frame-000000.depth.png", FixtureDepth(64, 48, 1000));
  cv::imwrite(dir / "frame-000000.color.jpg", FixtureColor(64, 48, 0));
  cv::imwrite(dir / "frame-000001.depth.png", FixtureDepth(64, 48, 1000));
  auto s = OpenSource("folder:" + dir.path().string(), {});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find("frame-000001.color.jpg"), std::string::npos) << s.status().message();
}

TEST(FolderSource, BadIntrinsicsFileIsReported) {
  TempDir dir;
  WriteText(dir / "camera-intrinsics.txt", "50 0 thirty-two\n");
  cv::imwrite(dir / "frame-000000.depth.png", FixtureDepth(64, 48, 1000));
  cv::imwrite(dir / "frame-000000.color.jpg", FixtureColor(64, 48, 0));
  auto s = OpenSource("folder:" + dir.path().string(), {});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find("camera-intrinsics.txt"), std::string::npos) << s.status().message();
}

}  // namespace
}  // namespace vd
