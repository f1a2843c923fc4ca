// Corrupted input for every decoder: truncations, random bytes (alone and behind a valid header),
// bit flips, wrong and oversized declared sizes. Each must return an error Status, or (where the
// corruption is undetectable, e.g. raw pixels or JPEG coefficients) a valid result of the right
// size; never crash, hang or read out of bounds (run under -DVD_SANITIZE=ON to check the latter).
#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "vd/common/codecs.h"
#include "vd/common/log.h"

namespace vd {
namespace {

constexpr int kW = 64;
constexpr int kH = 48;

// Decodes and, on success, checks the result; returns whether decoding succeeded.
using Decoder = std::function<bool(const uint8_t* data, size_t size)>;

struct FuzzStats {
  int runs = 0;
  int accepted = 0;
};

FuzzStats Fuzz(const std::vector<uint8_t>& valid, size_t header_bytes, const Decoder& decode, bool truncation_must_fail,
               uint32_t seed) {
  FuzzStats stats;
  auto run = [&](const std::vector<uint8_t>& bytes) {
    ++stats.runs;
    if (decode(bytes.data(), bytes.size())) ++stats.accepted;
  };
  EXPECT_TRUE(decode(valid.data(), valid.size())) << "the valid encoding must decode";
  // Truncations: every length for short buffers, ~400 spread lengths otherwise.
  const size_t step = std::max<size_t>(1, valid.size() / 400);
  for (size_t n = 0; n < valid.size(); n += step) {
    const std::vector<uint8_t> cut(valid.begin(), valid.begin() + n);
    const bool ok = decode(cut.data(), cut.size());
    ++stats.runs;
    if (truncation_must_fail) {
      EXPECT_FALSE(ok) << "truncated to " << n << " of " << valid.size() << " bytes";
    }
  }
  std::mt19937 rng(seed);
  for (int it = 0; it < 300; ++it) {
    // Pure random bytes of random length.
    std::vector<uint8_t> bytes(rng() % (2 * valid.size() + 1));
    for (uint8_t& b : bytes) b = static_cast<uint8_t>(rng());
    run(bytes);
    // A valid header followed by random bytes reaches the decoder's body.
    bytes.assign(valid.begin(), valid.begin() + std::min(header_bytes, valid.size()));
    bytes.resize(header_bytes + rng() % (valid.size() + 1));
    for (size_t k = header_bytes; k < bytes.size(); ++k) bytes[k] = static_cast<uint8_t>(rng());
    run(bytes);
    // One to three flipped bits.
    bytes = valid;
    for (int f = 0, flips = 1 + static_cast<int>(rng() % 3); f < flips; ++f) {
      const size_t bit = rng() % (bytes.size() * 8);
      bytes[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
    }
    run(bytes);
  }
  return stats;
}

cv::Mat Depth() {
  cv::Mat depth(kH, kW, CV_16UC1);
  std::mt19937 rng(9);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) depth.at<uint16_t>(y, x) = (rng() % 8 == 0) ? 0 : 1000 + 5 * x + 3 * y + rng() % 5;
  return depth;
}

cv::Mat Color() {
  cv::Mat color(kH, kW, CV_8UC3);
  std::mt19937 rng(10);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x)
      color.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<uint8_t>(4 * x), static_cast<uint8_t>(5 * y), static_cast<uint8_t>(rng()));
  return color;
}

TriangleMesh Sphere() {
  TriangleMesh m;
  const int rings = 8, segments = 12;
  for (int r = 0; r <= rings; ++r)
    for (int s = 0; s < segments; ++s) {
      const float t = 3.14159f * r / rings, p = 6.28318f * s / segments;
      m.positions.insert(m.positions.end(), {std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t)});
      m.colors.insert(m.colors.end(), {static_cast<uint8_t>(r * 20), static_cast<uint8_t>(s * 20), 99});
    }
  for (int r = 0; r < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      const int a = r * segments + s, b = r * segments + (s + 1) % segments;
      m.triangles.insert(m.triangles.end(), {a, a + segments, b + segments, a, b + segments, b});
    }
  return m;
}

Decoder DepthDecoder(DepthEncoding e, int width, int height) {
  return [=](const uint8_t* data, size_t size) {
    auto depth = DecodeDepth(data, size, e, width, height);
    if (!depth.ok()) return false;
    EXPECT_EQ(depth->type(), CV_16UC1);
    EXPECT_EQ(depth->cols, width);
    EXPECT_EQ(depth->rows, height);
    return true;
  };
}

Decoder ColorDecoder(ColorEncoding e, int width, int height) {
  return [=](const uint8_t* data, size_t size) {
    auto color = DecodeColor(data, size, e, width, height);
    if (!color.ok()) return false;
    EXPECT_EQ(color->type(), CV_8UC3);
    EXPECT_EQ(color->cols, width);
    EXPECT_EQ(color->rows, height);
    return true;
  };
}

bool MeshIsSound(const StatusOr<TriangleMesh>& mesh) {
  if (!mesh.ok()) return false;
  EXPECT_TRUE(mesh->Validate().ok());
  return true;
}

class FuzzCodecsTest : public ::testing::Test {
 protected:
  // libpng/libjpeg warnings are expected here; keep our own log quiet too.
  void SetUp() override { SetLogLevel(LogLevel::kQuiet); }
  void TearDown() override { SetLogLevel(LogLevel::kInfo); }
};

TEST_F(FuzzCodecsTest, DepthRaw16) {
  auto valid = EncodeDepth(Depth(), DepthEncoding::kRaw16);
  ASSERT_TRUE(valid.ok());
  const FuzzStats s = Fuzz(*valid, 0, DepthDecoder(DepthEncoding::kRaw16, kW, kH), true, 1);
  // Only inputs of exactly the right length decode: the bit flips (300) and lucky random lengths.
  EXPECT_GE(s.accepted, 300);
  EXPECT_LT(s.accepted, 340);
}

TEST_F(FuzzCodecsTest, DepthPng16) {
  auto valid = EncodeDepth(Depth(), DepthEncoding::kPng16);
  ASSERT_TRUE(valid.ok());
  const FuzzStats s = Fuzz(*valid, 33, DepthDecoder(DepthEncoding::kPng16, kW, kH), false, 2);
  // PNG chunks carry CRCs: nearly every corruption is detected.
  EXPECT_LT(s.accepted, s.runs / 10);
}

TEST_F(FuzzCodecsTest, DepthRvl) {
  auto valid = EncodeDepth(Depth(), DepthEncoding::kRvl);
  ASSERT_TRUE(valid.ok());
  const FuzzStats s = Fuzz(*valid, 12, DepthDecoder(DepthEncoding::kRvl, kW, kH), false, 3);
  EXPECT_LT(s.accepted, s.runs / 2);
}

TEST_F(FuzzCodecsTest, DepthOversizedDeclaredSizes) {
  auto rvl = EncodeDepth(Depth(), DepthEncoding::kRvl);
  auto png = EncodeDepth(Depth(), DepthEncoding::kPng16);
  auto raw = EncodeDepth(Depth(), DepthEncoding::kRaw16);
  ASSERT_TRUE(rvl.ok() && png.ok() && raw.ok());
  // An RVL header rewritten to claim 8192x8192 while the stream holds 64x48.
  std::vector<uint8_t> big = *rvl;
  big[4] = 0x00, big[5] = 0x20, big[8] = 0x00, big[9] = 0x20;
  big[6] = big[7] = big[10] = big[11] = 0;
  EXPECT_FALSE(DecodeDepth(big.data(), big.size(), DepthEncoding::kRvl, 8192, 8192).ok());
  EXPECT_FALSE(DecodeDepth(big.data(), big.size(), DepthEncoding::kRvl, kW, kH).ok());
  // A PNG IHDR claiming 2^31-1 x 2^31-1.
  std::vector<uint8_t> huge_png = *png;
  for (int k = 16; k < 24; ++k) huge_png[k] = k % 4 == 0 ? 0x7F : 0xFF;
  EXPECT_FALSE(DecodeDepth(huge_png.data(), huge_png.size(), DepthEncoding::kPng16, kW, kH).ok());
  for (DepthEncoding e : {DepthEncoding::kRaw16, DepthEncoding::kPng16, DepthEncoding::kRvl}) {
    const std::vector<uint8_t>& bytes = e == DepthEncoding::kRaw16 ? *raw : e == DepthEncoding::kPng16 ? *png : *rvl;
    EXPECT_FALSE(DecodeDepth(bytes.data(), bytes.size(), e, 100000, kH).ok());
    EXPECT_FALSE(DecodeDepth(bytes.data(), bytes.size(), e, kW, -1).ok());
    EXPECT_FALSE(DecodeDepth(bytes.data(), bytes.size(), e, 2 * kW, kH).ok());
  }
}

TEST_F(FuzzCodecsTest, ColorRaw) {
  auto valid = EncodeColor(Color(), ColorEncoding::kRawBgr8);
  ASSERT_TRUE(valid.ok());
  Fuzz(*valid, 0, ColorDecoder(ColorEncoding::kRawBgr8, kW, kH), true, 4);
}

TEST_F(FuzzCodecsTest, ColorJpeg) {
  auto valid = EncodeColor(Color(), ColorEncoding::kJpeg, 90);
  ASSERT_TRUE(valid.ok());
  // Header up to the first SOF lets random bodies reach libjpeg.
  Fuzz(*valid, 200, ColorDecoder(ColorEncoding::kJpeg, kW, kH), false, 5);
  // A frame header claiming 65535x65535 is refused before decoding.
  std::vector<uint8_t> huge = *valid;
  for (size_t i = 2; i + 9 < huge.size(); ++i)
    if (huge[i] == 0xFF && huge[i + 1] == 0xC0) {
      huge[i + 5] = huge[i + 6] = huge[i + 7] = huge[i + 8] = 0xFF;
      break;
    }
  auto status = DecodeColor(huge.data(), huge.size(), ColorEncoding::kJpeg, kW, kH).status();
  EXPECT_NE(status.message().find("65535x65535"), std::string::npos) << status.message();
}

TEST_F(FuzzCodecsTest, Draco) {
  for (int speed : {3, 10}) {
    DracoOptions options;
    options.speed = speed;
    auto valid = EncodeMeshDraco(Sphere(), options);
    ASSERT_TRUE(valid.ok());
    Fuzz(*valid, 16, [](const uint8_t* d, size_t n) { return MeshIsSound(DecodeMeshDraco(d, n)); }, false, 6 + speed);
  }
}

TEST_F(FuzzCodecsTest, Ply) {
  const TriangleMesh sphere = Sphere();
  auto valid = EncodePly(sphere);
  ASSERT_TRUE(valid.ok());
  const std::string text(valid->begin(), valid->end());
  const size_t header = text.find("end_header\n") + 11;
  const FuzzStats s = Fuzz(*valid, header, [](const uint8_t* d, size_t n) { return MeshIsSound(DecodePly(d, n)); },
                           true, 8);
  EXPECT_LT(s.accepted, s.runs / 2);
  // ASCII with the same content.
  std::string ascii = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(sphere.num_vertices()) +
                      "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                      std::to_string(sphere.num_triangles()) + "\nproperty list uchar int vertex_indices\nend_header\n";
  const size_t ascii_header = ascii.size();
  for (size_t v = 0; v < sphere.num_vertices(); ++v)
    ascii += std::to_string(sphere.positions[3 * v]) + " " + std::to_string(sphere.positions[3 * v + 1]) + " " +
             std::to_string(sphere.positions[3 * v + 2]) + "\n";
  for (size_t f = 0; f < sphere.num_triangles(); ++f)
    ascii += "3 " + std::to_string(sphere.triangles[3 * f]) + " " + std::to_string(sphere.triangles[3 * f + 1]) + " " +
             std::to_string(sphere.triangles[3 * f + 2]) + "\n";
  const std::vector<uint8_t> ascii_bytes(ascii.begin(), ascii.end());
  Fuzz(ascii_bytes, ascii_header, [](const uint8_t* d, size_t n) { return MeshIsSound(DecodePly(d, n)); }, false, 9);
}

}  // namespace
}  // namespace vd
