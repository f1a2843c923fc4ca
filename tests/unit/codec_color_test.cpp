#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

// After <cstdio>: jpeglib.h uses FILE without including it.
#include <jpeglib.h>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "vd/common/codecs.h"

namespace vd {
namespace {

// Smooth gradients and waves: what JPEG is meant for (sharp chroma edges suffer from 4:2:0).
cv::Mat TestColor(int width, int height) {
  cv::Mat color(height, width, CV_8UC3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      color.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<uint8_t>(x * 255 / width), static_cast<uint8_t>(y * 255 / height),
                                            static_cast<uint8_t>(128 + 100 * std::sin(x * 0.1) * std::cos(y * 0.07)));
  return color;
}

double MeanAbsDiff(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  const cv::Scalar s = cv::mean(diff);
  return (s[0] + s[1] + s[2]) / 3.0;
}

TEST(ColorCodecTest, RawIsExact) {
  const cv::Mat color = TestColor(64, 48);
  auto bytes = EncodeColor(color, ColorEncoding::kRawBgr8);
  ASSERT_TRUE(bytes.ok());
  EXPECT_EQ(bytes->size(), 64u * 48u * 3u);
  auto decoded = DecodeColor(bytes->data(), bytes->size(), ColorEncoding::kRawBgr8, 64, 48);
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  EXPECT_EQ(MeanAbsDiff(color, *decoded), 0.0);
  // A non-continuous view encodes the same bytes as its copy.
  const cv::Mat big = TestColor(100, 80);
  const cv::Mat roi = big(cv::Rect(3, 4, 64, 48));
  auto roi_bytes = EncodeColor(roi, ColorEncoding::kRawBgr8);
  auto copy_bytes = EncodeColor(roi.clone(), ColorEncoding::kRawBgr8);
  ASSERT_TRUE(roi_bytes.ok() && copy_bytes.ok());
  EXPECT_EQ(*roi_bytes, *copy_bytes);
}

TEST(ColorCodecTest, JpegIsCloseAndQualityOrdersSize) {
  const cv::Mat color = TestColor(160, 120);
  size_t previous = 0;
  double previous_error = 1e9;
  for (int quality : {50, 75, 90, 95}) {
    auto bytes = EncodeColor(color, ColorEncoding::kJpeg, quality);
    ASSERT_TRUE(bytes.ok());
    EXPECT_GT(bytes->size(), previous) << "quality " << quality;
    previous = bytes->size();
    auto decoded = DecodeColor(bytes->data(), bytes->size(), ColorEncoding::kJpeg, 160, 120);
    ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
    EXPECT_EQ(decoded->type(), CV_8UC3);
    const double error = MeanAbsDiff(color, *decoded);
    EXPECT_LT(error, quality >= 90 ? 1.0 : 3.0) << "quality " << quality;
    EXPECT_LT(error, previous_error) << "quality " << quality;
    previous_error = error;
  }
}

TEST(ColorCodecTest, NoneCarriesNoBytes) {
  auto bytes = EncodeColor(TestColor(8, 8), ColorEncoding::kNone);
  ASSERT_TRUE(bytes.ok());
  EXPECT_TRUE(bytes->empty());
  auto decoded = DecodeColor(nullptr, 0, ColorEncoding::kNone, 8, 8);
  ASSERT_TRUE(decoded.ok());
  EXPECT_TRUE(decoded->empty());
  const uint8_t one = 1;
  EXPECT_EQ(DecodeColor(&one, 1, ColorEncoding::kNone, 8, 8).status().code(), StatusCode::kDataLoss);
}

TEST(ColorCodecTest, WrongDeclaredSizeIsAnError) {
  const cv::Mat color = TestColor(40, 30);
  for (ColorEncoding e : {ColorEncoding::kRawBgr8, ColorEncoding::kJpeg}) {
    auto bytes = EncodeColor(color, e);
    ASSERT_TRUE(bytes.ok());
    EXPECT_FALSE(DecodeColor(bytes->data(), bytes->size(), e, 40, 31).ok());
    EXPECT_FALSE(DecodeColor(bytes->data(), bytes->size(), e, 41, 30).ok());
    EXPECT_FALSE(DecodeColor(bytes->data(), bytes->size(), e, 0, 30).ok());
    EXPECT_FALSE(DecodeColor(bytes->data(), bytes->size(), e, 40, 100000).ok());
    EXPECT_FALSE(DecodeColor(bytes->data(), bytes->size(), ColorEncoding::kInvalid, 40, 30).ok());
  }
  // Transposed JPEG: the frame header check names both sizes.
  auto jpeg = EncodeColor(color, ColorEncoding::kJpeg);
  auto status = DecodeColor(jpeg->data(), jpeg->size(), ColorEncoding::kJpeg, 30, 40).status();
  EXPECT_NE(status.message().find("40x30"), std::string::npos) << status.message();
}

TEST(ColorCodecTest, GreyJpegDecodesToThreeChannels) {
  const cv::Mat grey(30, 40, CV_8UC1, cv::Scalar(128));
  std::vector<uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", grey, jpeg));
  auto decoded = DecodeColor(jpeg.data(), jpeg.size(), ColorEncoding::kJpeg, 40, 30);
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  EXPECT_EQ(decoded->type(), CV_8UC3);
}

// The codec calls libjpeg directly, converting to and from BGR inside libjpeg-turbo. It must give
// the bytes and pixels OpenCV's imencode/imdecode give (they use the same libjpeg, by way of RGB):
// baseline 4:2:0 at several qualities, progressive, greyscale, and a view into a larger image.
TEST(ColorCodecTest, JpegIsBitIdenticalToOpenCv) {
  const cv::Mat big = TestColor(200, 150);
  const cv::Mat roi = big(cv::Rect(7, 5, 160, 120));
  for (const cv::Mat& color : {TestColor(160, 120), roi}) {
    for (int quality : {50, 75, 90, 95}) {
      auto ours = EncodeColor(color, ColorEncoding::kJpeg, quality);
      ASSERT_TRUE(ours.ok()) << ours.status().ToString();
      std::vector<uint8_t> opencv;
      ASSERT_TRUE(cv::imencode(".jpg", color, opencv, {cv::IMWRITE_JPEG_QUALITY, quality}));
      EXPECT_EQ(*ours, opencv) << "quality " << quality;
      auto decoded = DecodeColor(ours->data(), ours->size(), ColorEncoding::kJpeg, 160, 120);
      ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
      const cv::Mat reference = cv::imdecode(*ours, cv::IMREAD_COLOR);
      EXPECT_EQ(cv::norm(*decoded, reference, cv::NORM_INF), 0.0) << "quality " << quality;
    }
  }
  std::vector<uint8_t> progressive, grey;
  ASSERT_TRUE(cv::imencode(".jpg", TestColor(160, 120), progressive, {cv::IMWRITE_JPEG_PROGRESSIVE, 1}));
  cv::Mat grey_image;
  cv::cvtColor(TestColor(160, 120), grey_image, cv::COLOR_BGR2GRAY);
  ASSERT_TRUE(cv::imencode(".jpg", grey_image, grey));
  for (const std::vector<uint8_t>* bytes : {&progressive, &grey}) {
    auto decoded = DecodeColor(bytes->data(), bytes->size(), ColorEncoding::kJpeg, 160, 120);
    ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
    EXPECT_EQ(cv::norm(*decoded, cv::imdecode(*bytes, cv::IMREAD_COLOR), cv::NORM_INF), 0.0);
  }
}

// A JPEG cut short decodes in libjpeg (and in OpenCV) to an image whose rest is grey. The codec
// refuses it: a frame with a grey band would be fused as if it were seen.
TEST(ColorCodecTest, TruncatedJpegIsAnError) {
  auto bytes = EncodeColor(TestColor(160, 120), ColorEncoding::kJpeg, 90);
  ASSERT_TRUE(bytes.ok());
  const std::vector<uint8_t> cut(bytes->begin(), bytes->begin() + bytes->size() / 2);
  ASSERT_FALSE(cv::imdecode(cut, cv::IMREAD_COLOR).empty()) << "OpenCV accepts the cut image";
  const Status status = DecodeColor(cut.data(), cut.size(), ColorEncoding::kJpeg, 160, 120).status();
  EXPECT_EQ(status.code(), StatusCode::kDataLoss);
  EXPECT_NE(status.message().find("corrupt"), std::string::npos) << status.message();
}

// What cameras' own JPEG (webcam MJPEG) often carries is not corruption: stray bytes before the end
// marker, or no end marker at all after complete image data. Both decode, as OpenCV decodes them.
TEST(ColorCodecTest, BenignJpegQuirksDecode) {
  auto bytes = EncodeColor(TestColor(160, 120), ColorEncoding::kJpeg, 90);
  ASSERT_TRUE(bytes.ok());
  ASSERT_GE(bytes->size(), 2u);
  ASSERT_EQ((*bytes)[bytes->size() - 2], 0xFF);
  ASSERT_EQ((*bytes)[bytes->size() - 1], 0xD9);
  std::vector<uint8_t> stray(*bytes), no_end(bytes->begin(), bytes->end() - 2);
  stray.insert(stray.end() - 2, {0x00, 0x11, 0x22, 0x33, 0x44});
  for (const std::vector<uint8_t>* quirk : {&stray, &no_end}) {
    auto decoded = DecodeColor(quirk->data(), quirk->size(), ColorEncoding::kJpeg, 160, 120);
    ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
    EXPECT_EQ(cv::norm(*decoded, cv::imdecode(*bytes, cv::IMREAD_COLOR), cv::NORM_INF), 0.0);
  }
}

// A progressive JPEG of `color` with every AC coefficient in its own scan per component: 190
// scans, or 380 when each is also sent in two successive-approximation passes (all valid JPEG).
std::vector<uint8_t> ManyScanJpeg(const cv::Mat& color, bool refine) {
  std::vector<jpeg_scan_info> scans;
  const int al = refine ? 1 : 0;
  scans.push_back({3, {0, 1, 2, 0}, 0, 0, 0, al});
  if (refine) scans.push_back({3, {0, 1, 2, 0}, 0, 0, 1, 0});
  for (int pass = 0; pass < (refine ? 2 : 1); ++pass)
    for (int c = 0; c < 3; ++c)
      for (int k = 1; k < 64; ++k) scans.push_back({1, {c, 0, 0, 0}, k, k, pass == 1 ? 1 : 0, pass == 0 ? al : 0});
  jpeg_compress_struct cinfo;
  jpeg_error_mgr err;
  cinfo.err = jpeg_std_error(&err);
  jpeg_create_compress(&cinfo);
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  jpeg_mem_dest(&cinfo, &buffer, &size);
  cinfo.image_width = color.cols;
  cinfo.image_height = color.rows;
  cinfo.input_components = 3;
  cinfo.in_color_space = JCS_EXT_BGR;
  jpeg_set_defaults(&cinfo);
  cinfo.scan_info = scans.data();
  cinfo.num_scans = int(scans.size());
  jpeg_start_compress(&cinfo, TRUE);
  for (int y = 0; y < color.rows; ++y) {
    JSAMPROW row = const_cast<uint8_t*>(color.ptr<uint8_t>(y));
    jpeg_write_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_compress(&cinfo);
  jpeg_destroy_compress(&cinfo);
  std::vector<uint8_t> out(buffer, buffer + size);
  std::free(buffer);
  return out;
}

// A progressive JPEG made of hundreds of tiny scans costs libjpeg a decode per scan (seconds for a
// crafted few kilobytes): beyond 200 scans the frame is refused; 190 still decode as OpenCV does.
TEST(ColorCodecTest, JpegWithTooManyScansIsRefused) {
  const cv::Mat color = TestColor(160, 120);
  const std::vector<uint8_t> many = ManyScanJpeg(color, false), too_many = ManyScanJpeg(color, true);
  ASSERT_FALSE(cv::imdecode(too_many, cv::IMREAD_COLOR).empty()) << "a valid JPEG";
  auto decoded = DecodeColor(many.data(), many.size(), ColorEncoding::kJpeg, 160, 120);
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  EXPECT_EQ(cv::norm(*decoded, cv::imdecode(many, cv::IMREAD_COLOR), cv::NORM_INF), 0.0);
  EXPECT_LT(MeanAbsDiff(color, *decoded), 3.0);  // libjpeg's default quality, 75
  const Status status = DecodeColor(too_many.data(), too_many.size(), ColorEncoding::kJpeg, 160, 120).status();
  EXPECT_EQ(status.code(), StatusCode::kDataLoss);
  EXPECT_NE(status.message().find("more than 200 scans"), std::string::npos) << status.message();
}

TEST(ColorCodecTest, EncodeRejectsBadInput) {
  EXPECT_EQ(EncodeColor(cv::Mat(), ColorEncoding::kJpeg).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(EncodeColor(cv::Mat(4, 4, CV_8UC1), ColorEncoding::kJpeg).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(EncodeColor(TestColor(8, 8), ColorEncoding::kJpeg, 0).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(EncodeColor(TestColor(8, 8), ColorEncoding::kJpeg, 101).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(EncodeColor(TestColor(8, 8), ColorEncoding::kInvalid).status().code(), StatusCode::kInvalidArgument);
}

TEST(ColorCodecTest, RealFrameJpegRoundTrip) {
  const std::string path = std::string(VD_SHARED_DATA_DIR) + "/7scenes_redkitchen/frame-000000.color.jpg";
  const cv::Mat color = cv::imread(path, cv::IMREAD_COLOR);
  if (color.empty()) GTEST_SKIP() << "no shared data at " << path;
  auto bytes = EncodeColor(color, ColorEncoding::kJpeg, 90);
  ASSERT_TRUE(bytes.ok());
  // A 640x480 kitchen at q90 is a few tens of KB, far below the 921,600 raw bytes.
  EXPECT_LT(bytes->size(), 200000u);
  auto decoded = DecodeColor(bytes->data(), bytes->size(), ColorEncoding::kJpeg, color.cols, color.rows);
  ASSERT_TRUE(decoded.ok());
  EXPECT_LT(MeanAbsDiff(color, *decoded), 3.0);
}

}  // namespace
}  // namespace vd
