#include <algorithm>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "vd/common/codecs.h"

namespace vd {
namespace {

const DepthEncoding kAllDepth[] = {DepthEncoding::kRaw16, DepthEncoding::kPng16, DepthEncoding::kRvl};

// A noisy ramp with holes, a zero border, extreme values and sudden jumps.
cv::Mat NoisyDepth(int width, int height, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 3.0);
  std::uniform_int_distribution<int> coin(0, 99);
  cv::Mat depth(height, width, CV_16UC1);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      int v = 800 + 3 * x + 2 * y + static_cast<int>(noise(rng));
      if (coin(rng) < 7) v = 0;
      if (x < 4) v = 0;
      if (x == width / 2) v = 65535;
      if (x == width / 2 + 1) v = 1;
      depth.at<uint16_t>(y, x) = static_cast<uint16_t>(std::clamp(v, 0, 65535));
    }
  return depth;
}

bool Equal(const cv::Mat& a, const cv::Mat& b) {
  return a.type() == b.type() && a.size() == b.size() && cv::countNonZero(a != b) == 0;
}

void ExpectRoundTrip(const cv::Mat& depth, DepthEncoding encoding) {
  SCOPED_TRACE(std::string(DepthEncodingName(encoding)) + " " + std::to_string(depth.cols) + "x" +
               std::to_string(depth.rows));
  auto bytes = EncodeDepth(depth, encoding);
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  auto decoded = DecodeDepth(bytes->data(), bytes->size(), encoding, depth.cols, depth.rows);
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  EXPECT_EQ(decoded->type(), CV_16UC1);
  EXPECT_TRUE(Equal(depth, *decoded));
}

TEST(DepthCodecTest, EveryEncodingIsLosslessOnNoisyDepth) {
  const cv::Mat depth = NoisyDepth(160, 120, 7);
  for (DepthEncoding e : kAllDepth) ExpectRoundTrip(depth, e);
}

TEST(DepthCodecTest, EdgeCasesRoundTrip) {
  std::vector<cv::Mat> images;
  images.push_back(cv::Mat::zeros(7, 5, CV_16UC1));
  images.push_back(cv::Mat(3, 9, CV_16UC1, cv::Scalar(65535)));
  images.push_back(cv::Mat(1, 1, CV_16UC1, cv::Scalar(1)));
  images.push_back(cv::Mat::zeros(1, 1, CV_16UC1));
  // Largest possible jumps between consecutive valid pixels.
  cv::Mat alternating(4, 6, CV_16UC1);
  for (int i = 0; i < 24; ++i) alternating.at<uint16_t>(i / 6, i % 6) = (i % 2) ? 65535 : 1;
  images.push_back(alternating);
  for (const cv::Mat& img : images)
    for (DepthEncoding e : kAllDepth) ExpectRoundTrip(img, e);
}

TEST(DepthCodecTest, NonContinuousRoiEncodes) {
  const cv::Mat big = NoisyDepth(64, 48, 3);
  const cv::Mat roi = big(cv::Rect(5, 7, 33, 20));
  ASSERT_FALSE(roi.isContinuous());
  for (DepthEncoding e : kAllDepth) ExpectRoundTrip(roi, e);
}

TEST(DepthCodecTest, RvlStreamMatchesTheHandComputedBytes) {
  // Pixels 0 0 5 6: zero run 2, value run 2, zig-zag(5) = 10 -> nibbles A 1, zig-zag(1) = 2.
  const cv::Mat depth = (cv::Mat_<uint16_t>(1, 4) << 0, 0, 5, 6);
  auto bytes = EncodeDepth(depth, DepthEncoding::kRvl);
  ASSERT_TRUE(bytes.ok());
  const std::vector<uint8_t> expected = {'R', 'V', 'L', '1', 4, 0, 0, 0, 1, 0, 0, 0, 0x00, 0x20, 0xA1, 0x22};
  EXPECT_EQ(*bytes, expected);
}

TEST(DepthCodecTest, RawIsLittleEndian) {
  const cv::Mat depth = (cv::Mat_<uint16_t>(1, 2) << 0x1234, 0xABCD);
  auto bytes = EncodeDepth(depth, DepthEncoding::kRaw16);
  ASSERT_TRUE(bytes.ok());
  EXPECT_EQ(*bytes, (std::vector<uint8_t>{0x34, 0x12, 0xCD, 0xAB}));
}

TEST(DepthCodecTest, MismatchedDeclaredSizeIsAnError) {
  const cv::Mat depth = NoisyDepth(40, 30, 11);
  for (DepthEncoding e : kAllDepth) {
    auto bytes = EncodeDepth(depth, e);
    ASSERT_TRUE(bytes.ok());
    for (auto [w, h] : {std::pair{30, 40}, std::pair{40, 31}, std::pair{39, 30}, std::pair{20, 60}}) {
      // Raw bytes carry no header: a transposed size of equal area is indistinguishable.
      if (e == DepthEncoding::kRaw16 && w * h == 40 * 30) continue;
      auto decoded = DecodeDepth(bytes->data(), bytes->size(), e, w, h);
      EXPECT_FALSE(decoded.ok()) << DepthEncodingName(e) << " accepted " << w << "x" << h;
    }
    EXPECT_EQ(DecodeDepth(bytes->data(), bytes->size(), e, 0, 30).status().code(), StatusCode::kInvalidArgument);
    EXPECT_EQ(DecodeDepth(bytes->data(), bytes->size(), e, 9000, 30).status().code(), StatusCode::kInvalidArgument);
  }
  EXPECT_FALSE(DecodeDepth(nullptr, 0, DepthEncoding::kRvl, 40, 30).ok());
  EXPECT_FALSE(DecodeDepth(nullptr, 0, DepthEncoding::kInvalid, 40, 30).ok());
}

TEST(DepthCodecTest, PngOfTheWrongKindIsRefused) {
  const cv::Mat grey8(30, 40, CV_8UC1, cv::Scalar(9));
  std::vector<uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", grey8, png));
  auto decoded = DecodeDepth(png.data(), png.size(), DepthEncoding::kPng16, 40, 30);
  ASSERT_FALSE(decoded.ok());
  EXPECT_NE(decoded.status().message().find("16-bit"), std::string::npos) << decoded.status().message();
}

TEST(DepthCodecTest, EncodeRejectsBadInput) {
  EXPECT_EQ(EncodeDepth(cv::Mat(), DepthEncoding::kRvl).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(EncodeDepth(cv::Mat(4, 4, CV_8UC1), DepthEncoding::kRvl).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(EncodeDepth(cv::Mat(4, 4, CV_16UC1, cv::Scalar(1)), DepthEncoding::kInvalid).status().code(),
            StatusCode::kInvalidArgument);
}

TEST(DepthCodecTest, NamesParseBack) {
  for (DepthEncoding e : kAllDepth) {
    auto parsed = ParseDepthEncoding(DepthEncodingName(e));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(*parsed, e);
  }
  EXPECT_FALSE(ParseDepthEncoding("zip").ok());
  EXPECT_STREQ(DepthEncodingName(DepthEncoding::kInvalid), "invalid");
  for (ColorEncoding e : {ColorEncoding::kNone, ColorEncoding::kRawBgr8, ColorEncoding::kJpeg}) {
    auto parsed = ParseColorEncoding(ColorEncodingName(e));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(*parsed, e);
  }
  EXPECT_FALSE(ParseColorEncoding("png").ok());
  EXPECT_STREQ(ColorEncodingName(ColorEncoding::kInvalid), "invalid");
}

TEST(DepthCodecTest, RealKinectFrameIsLosslessAndRvlCompresses) {
  const std::string path = std::string(VD_SHARED_DATA_DIR) + "/7scenes_redkitchen/frame-000000.depth.png";
  const cv::Mat depth = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (depth.empty()) GTEST_SKIP() << "no shared data at " << path;
  ASSERT_EQ(depth.type(), CV_16UC1);
  size_t sizes[3] = {};
  for (int i = 0; i < 3; ++i) {
    ExpectRoundTrip(depth, kAllDepth[i]);
    sizes[i] = EncodeDepth(depth, kAllDepth[i])->size();
  }
  EXPECT_EQ(sizes[0], 640u * 480u * 2u);
  // Measured 7-Scenes frame 0: RVL ~40% of raw, PNG ~45% (see docs/BENCHMARKS.md).
  EXPECT_LT(sizes[2], sizes[0] * 6 / 10);
  EXPECT_LT(sizes[1], sizes[0] * 6 / 10);
}

}  // namespace
}  // namespace vd
