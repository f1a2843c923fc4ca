#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "vd/common/codecs.h"

namespace vd {
namespace {

constexpr float kPi = 3.14159265358979f;

// A closed UV sphere; every vertex gets a unique colour so decoded vertices can be matched back.
TriangleMesh Sphere(int rings, int segments, float radius, bool normals) {
  TriangleMesh mesh;
  auto add = [&](float theta, float phi) {
    const float n[3] = {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
    for (int k = 0; k < 3; ++k) mesh.positions.push_back(radius * n[k] + 0.1f * k);
    if (normals)
      for (float v : n) mesh.normals.push_back(v);
  };
  add(0.f, 0.f);
  for (int r = 1; r < rings; ++r)
    for (int s = 0; s < segments; ++s) add(kPi * r / rings, 2 * kPi * s / segments);
  add(kPi, 0.f);
  const int south = static_cast<int>(mesh.num_vertices()) - 1;
  auto ring = [&](int r, int s) { return 1 + (r - 1) * segments + (s % segments); };
  for (int s = 0; s < segments; ++s) {
    mesh.triangles.insert(mesh.triangles.end(), {0, ring(1, s), ring(1, s + 1)});
    mesh.triangles.insert(mesh.triangles.end(), {south, ring(rings - 1, s + 1), ring(rings - 1, s)});
  }
  for (int r = 1; r + 1 < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      mesh.triangles.insert(mesh.triangles.end(), {ring(r, s), ring(r + 1, s), ring(r + 1, s + 1)});
      mesh.triangles.insert(mesh.triangles.end(), {ring(r, s), ring(r + 1, s + 1), ring(r, s + 1)});
    }
  for (size_t i = 0; i < mesh.num_vertices(); ++i)
    mesh.colors.insert(mesh.colors.end(), {static_cast<uint8_t>(i), static_cast<uint8_t>(i >> 8), static_cast<uint8_t>(i >> 16)});
  return mesh;
}

uint32_t ColorKey(const TriangleMesh& m, size_t v) {
  return m.colors[3 * v] | m.colors[3 * v + 1] << 8 | m.colors[3 * v + 2] << 16;
}

// Largest position error Draco's quantisation may introduce: half a step over the largest extent.
float QuantisationBound(const TriangleMesh& mesh, int bits) {
  float mn[3], mx[3];
  mesh.Bounds(mn, mx);
  const float range = std::max({mx[0] - mn[0], mx[1] - mn[1], mx[2] - mn[2]});
  return 0.5f * range / static_cast<float>((1 << bits) - 1) * 1.01f + 1e-7f;
}

std::vector<std::array<int, 3>> CanonicalTriangles(const TriangleMesh& m, const std::vector<int>& to_original) {
  std::vector<std::array<int, 3>> out;
  for (size_t f = 0; f < m.num_triangles(); ++f) {
    std::array<int, 3> t = {to_original[m.triangles[3 * f]], to_original[m.triangles[3 * f + 1]],
                            to_original[m.triangles[3 * f + 2]]};
    // Rotate (keeping orientation) so the smallest index comes first.
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
    out.push_back(t);
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Checks the decoded mesh is the original up to vertex/face order and quantisation.
void ExpectSameMesh(const TriangleMesh& original, const TriangleMesh& decoded, int bits) {
  ASSERT_EQ(decoded.num_triangles(), original.num_triangles());
  ASSERT_EQ(decoded.num_vertices(), original.num_vertices());
  ASSERT_EQ(decoded.colors.size(), decoded.positions.size());
  std::vector<int> to_original(decoded.num_vertices(), -1);
  const float bound = QuantisationBound(original, bits);
  float worst = 0.f;
  for (size_t v = 0; v < decoded.num_vertices(); ++v) {
    const uint32_t key = ColorKey(decoded, v);
    ASSERT_LT(key, original.num_vertices()) << "colour not preserved exactly";
    to_original[v] = static_cast<int>(key);
    for (int k = 0; k < 3; ++k)
      worst = std::max(worst, std::abs(decoded.positions[3 * v + k] - original.positions[3 * key + k]));
  }
  EXPECT_LE(worst, bound);
  // Quantisation really happened (the bound is not vacuous) unless bits are very high.
  if (bits <= 12) {
    EXPECT_GT(worst, bound * 0.05f);
  }
  std::vector<int> identity(original.num_vertices());
  for (size_t i = 0; i < identity.size(); ++i) identity[i] = static_cast<int>(i);
  EXPECT_EQ(CanonicalTriangles(decoded, to_original), CanonicalTriangles(original, identity));
}

TEST(DracoCodecTest, RoundTripWithinQuantisationBound) {
  const TriangleMesh sphere = Sphere(20, 36, 0.5f, false);
  ASSERT_TRUE(sphere.Validate().ok());
  for (int bits : {8, 11, 14}) {
    for (int speed : {0, 3, 7, 10}) {
      SCOPED_TRACE("bits " + std::to_string(bits) + " speed " + std::to_string(speed));
      DracoOptions options;
      options.position_bits = bits;
      options.speed = speed;
      auto bytes = EncodeMeshDraco(sphere, options);
      ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
      auto decoded = DecodeMeshDraco(bytes->data(), bytes->size());
      ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
      EXPECT_TRUE(decoded->normals.empty());
      ExpectSameMesh(sphere, *decoded, bits);
    }
  }
}

// Speed 10 codes the connectivity sequentially (Draco's header byte 8: 0) and keeps the vertex
// order; below 10 a manifold mesh takes edgebreaker (1), which reorders the vertices and is what
// makes the messages small: the server's --draco-speed trades one for the other.
TEST(DracoCodecTest, SpeedTenIsSequentialAndKeepsTheOrder) {
  const TriangleMesh sphere = Sphere(40, 80, 0.5f, false);
  DracoOptions fast, small;
  fast.speed = 10;
  small.speed = 7;
  auto sequential = EncodeMeshDraco(sphere, fast);
  auto edgebreaker = EncodeMeshDraco(sphere, small);
  ASSERT_TRUE(sequential.ok() && edgebreaker.ok());
  EXPECT_EQ((*sequential)[8], 0);
  EXPECT_EQ((*edgebreaker)[8], 1);
  EXPECT_LT(edgebreaker->size() * 3, sequential->size() * 2);
  auto decoded = DecodeMeshDraco(sequential->data(), sequential->size());
  ASSERT_TRUE(decoded.ok());
  EXPECT_EQ(decoded->triangles, sphere.triangles);
  ASSERT_EQ(decoded->positions.size(), sphere.positions.size());
  for (size_t i = 0; i < sphere.positions.size(); ++i) EXPECT_NEAR(decoded->positions[i], sphere.positions[i], 1e-4f);
}

TEST(DracoCodecTest, CompressesWellBelowRawSize) {
  const TriangleMesh sphere = Sphere(40, 80, 0.5f, false);
  auto bytes = EncodeMeshDraco(sphere, {});
  ASSERT_TRUE(bytes.ok());
  auto ply = EncodePly(sphere);
  ASSERT_TRUE(ply.ok());
  // ~6.3k vertices, ~12.6k triangles: PLY ~260 KB; Draco at 14 bits is well under a fifth.
  EXPECT_LT(bytes->size() * 5, ply->size());
}

TEST(DracoCodecTest, NormalsAreKeptWhenAsked) {
  const TriangleMesh sphere = Sphere(12, 20, 1.f, true);
  DracoOptions options;
  options.include_normals = true;
  auto bytes = EncodeMeshDraco(sphere, options);
  ASSERT_TRUE(bytes.ok());
  auto decoded = DecodeMeshDraco(bytes->data(), bytes->size());
  ASSERT_TRUE(decoded.ok());
  ASSERT_EQ(decoded->normals.size(), decoded->positions.size());
  double worst_deg = 0;
  for (size_t v = 0; v < decoded->num_vertices(); ++v) {
    const uint32_t o = ColorKey(*decoded, v);
    double dot = 0;
    for (int k = 0; k < 3; ++k) dot += decoded->normals[3 * v + k] * sphere.normals[3 * o + k];
    worst_deg = std::max(worst_deg, std::acos(std::min(1.0, dot)) * 180.0 / kPi);
  }
  EXPECT_LT(worst_deg, 1.0);
  // And dropped by default.
  auto plain = EncodeMeshDraco(sphere, {});
  ASSERT_TRUE(plain.ok());
  EXPECT_LT(plain->size(), bytes->size());
  EXPECT_TRUE(DecodeMeshDraco(plain->data(), plain->size())->normals.empty());
}

TEST(DracoCodecTest, MeshWithoutColoursDecodesWithoutColours) {
  TriangleMesh mesh = Sphere(6, 8, 1.f, false);
  mesh.colors.clear();
  auto bytes = EncodeMeshDraco(mesh, {});
  ASSERT_TRUE(bytes.ok());
  auto decoded = DecodeMeshDraco(bytes->data(), bytes->size());
  ASSERT_TRUE(decoded.ok());
  EXPECT_TRUE(decoded->colors.empty());
  EXPECT_EQ(decoded->num_triangles(), mesh.num_triangles());
}

TEST(DracoCodecTest, CountsSurviveUnreferencedVerticesAndDegenerateTriangles) {
  // Edgebreaker would drop the unreferenced vertex and the degenerate triangle; the encoder must
  // notice and keep counts exact (the message layer checks them).
  TriangleMesh mesh = Sphere(6, 8, 1.f, false);
  mesh.positions.insert(mesh.positions.end(), {5.f, 5.f, 5.f});
  mesh.colors.insert(mesh.colors.end(), {1, 2, 3});
  mesh.triangles.insert(mesh.triangles.end(), {0, 0, 1});
  ASSERT_TRUE(mesh.Validate().ok());
  for (int speed : {3, 7, 10}) {
    DracoOptions options;
    options.speed = speed;
    auto bytes = EncodeMeshDraco(mesh, options);
    ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
    auto decoded = DecodeMeshDraco(bytes->data(), bytes->size());
    ASSERT_TRUE(decoded.ok());
    EXPECT_EQ(decoded->num_vertices(), mesh.num_vertices()) << "speed " << speed;
    EXPECT_EQ(decoded->num_triangles(), mesh.num_triangles()) << "speed " << speed;
  }
}

TEST(DracoCodecTest, EmptyMeshIsAClearError) {
  TriangleMesh empty;
  auto bytes = EncodeMeshDraco(empty, {});
  ASSERT_FALSE(bytes.ok());
  EXPECT_EQ(bytes.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(bytes.status().message().find("no triangles"), std::string::npos);
  // Points but no triangles is still empty.
  TriangleMesh points;
  points.positions = {0.f, 0.f, 0.f, 1.f, 1.f, 1.f};
  EXPECT_EQ(EncodeMeshDraco(points, {}).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(DecodeMeshDraco(nullptr, 0).status().code(), StatusCode::kDataLoss);
}

TEST(DracoCodecTest, InvalidInputIsRefused) {
  TriangleMesh bad = Sphere(4, 6, 1.f, false);
  bad.triangles.push_back(0);
  EXPECT_FALSE(EncodeMeshDraco(bad, {}).ok());
  bad = Sphere(4, 6, 1.f, false);
  bad.triangles[4] = 9999;
  EXPECT_FALSE(EncodeMeshDraco(bad, {}).ok());
  bad = Sphere(4, 6, 1.f, false);
  bad.positions[2] = NAN;
  EXPECT_FALSE(EncodeMeshDraco(bad, {}).ok());
}

TEST(DracoCodecTest, OptionsValidateNamesFieldAndBound) {
  EXPECT_TRUE(DracoOptions{}.Validate().ok());
  DracoOptions o;
  o.position_bits = 0;
  EXPECT_NE(o.Validate().message().find("position_bits = 0"), std::string::npos);
  o.position_bits = 31;
  EXPECT_FALSE(o.Validate().ok());
  o = DracoOptions{};
  o.speed = 11;
  EXPECT_NE(o.Validate().message().find("speed = 11"), std::string::npos);
  o.speed = -1;
  EXPECT_FALSE(o.Validate().ok());
  EXPECT_FALSE(EncodeMeshDraco(Sphere(4, 6, 1.f, false), o).ok());
}

}  // namespace
}  // namespace vd

namespace vd {
namespace {

// The live mesh's canonical positions (issue 16): a GENERIC attribute quantised like the positions,
// read back per vertex; a mesh without it decodes without it.
TEST(DracoCodecTest, CanonicalPositionsRoundTripPerVertex) {
  TriangleMesh live = Sphere(20, 36, 0.5f, false);
  // Canonical = live scaled by 2 and moved: a different box, so a mix-up of the two would show.
  for (size_t i = 0; i < live.positions.size(); ++i)
    live.canonical.push_back(2.f * live.positions[i] + (i % 3 == 2 ? 1.f : -0.25f));
  for (int bits : {11, 14}) {
    DracoOptions options;
    options.position_bits = bits;
    auto bytes = EncodeMeshDraco(live, options);
    ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
    auto decoded = DecodeMeshDraco(bytes->data(), bytes->size());
    ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
    ASSERT_EQ(decoded->canonical.size(), decoded->positions.size());
    ExpectSameMesh(live, *decoded, bits);
    const float bound = 2.f * QuantisationBound(live, bits);
    float worst = 0.f;
    for (size_t v = 0; v < decoded->num_vertices(); ++v) {
      const uint32_t key = ColorKey(*decoded, v);
      for (int k = 0; k < 3; ++k)
        worst = std::max(worst, std::abs(decoded->canonical[3 * v + k] - live.canonical[3 * key + k]));
    }
    EXPECT_LE(worst, bound) << bits << " bits";
    EXPECT_GT(worst, 0.f) << "the canonical positions were not quantised";
  }
  TriangleMesh plain = live;
  plain.canonical.clear();
  auto bytes = EncodeMeshDraco(plain, {});
  ASSERT_TRUE(bytes.ok());
  auto decoded = DecodeMeshDraco(bytes->data(), bytes->size());
  ASSERT_TRUE(decoded.ok());
  EXPECT_TRUE(decoded->canonical.empty());
  TriangleMesh wrong = live;
  wrong.canonical.resize(wrong.canonical.size() - 3);
  EXPECT_EQ(EncodeMeshDraco(wrong, {}).status().code(), StatusCode::kInvalidArgument);
}

// Debian's draco_decoder (package draco) still decodes a live mesh with the canonical attribute.
TEST(DracoCodecTest, DebiansDracoDecoderDecodesTheLivePayload) {
  if (std::system("command -v draco_decoder >/dev/null 2>&1") != 0) GTEST_SKIP() << "draco_decoder not installed";
  TriangleMesh live = Sphere(20, 36, 0.5f, false);
  live.canonical = live.positions;
  auto bytes = EncodeMeshDraco(live, {});
  ASSERT_TRUE(bytes.ok());
  const std::string stem = ::testing::TempDir() + "/vd_canonical_" + std::to_string(getpid());
  {
    std::ofstream out(stem + ".drc", std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes->data()), static_cast<std::streamsize>(bytes->size()));
  }
  const std::string command = "draco_decoder -i " + stem + ".drc -o " + stem + ".ply >/dev/null 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
  std::ifstream ply(stem + ".ply", std::ios::binary);
  std::string header((std::istreambuf_iterator<char>(ply)), std::istreambuf_iterator<char>());
  header = header.substr(0, std::min<size_t>(header.size(), 400));
  EXPECT_NE(header.find("element vertex " + std::to_string(live.num_vertices())), std::string::npos) << header;
  std::remove((stem + ".drc").c_str());
  std::remove((stem + ".ply").c_str());
}

}  // namespace
}  // namespace vd
