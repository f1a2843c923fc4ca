#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "vd/common/codecs.h"

namespace vd {
namespace {

TriangleMesh Tetrahedron(bool normals, bool colors) {
  TriangleMesh m;
  m.positions = {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.5f, 0.f, 0.25f, 0.25f, -2.125f};
  m.triangles = {0, 2, 1, 0, 1, 3, 1, 2, 3, 2, 0, 3};
  if (normals) m.normals = {0.f, 0.f, -1.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.6f, 0.8f};
  if (colors) m.colors = {255, 0, 0, 0, 255, 0, 0, 0, 255, 10, 20, 30};
  return m;
}

StatusOr<TriangleMesh> Decode(const std::string& s) {
  return DecodePly(reinterpret_cast<const uint8_t*>(s.data()), s.size());
}

void ExpectEqualMesh(const TriangleMesh& a, const TriangleMesh& b) {
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.normals, b.normals);
  EXPECT_EQ(a.colors, b.colors);
  EXPECT_EQ(a.triangles, b.triangles);
}

TEST(PlyTest, BinaryRoundTripIsExact) {
  for (bool normals : {false, true})
    for (bool colors : {false, true}) {
      const TriangleMesh mesh = Tetrahedron(normals, colors);
      auto bytes = EncodePly(mesh);
      ASSERT_TRUE(bytes.ok());
      const size_t per_vertex = 12 + (normals ? 12 : 0) + (colors ? 3 : 0);
      const std::string text(bytes->begin(), bytes->end());
      const size_t header_end = text.find("end_header\n") + 11;
      EXPECT_EQ(bytes->size(), header_end + 4 * per_vertex + 4 * 13);
      auto decoded = DecodePly(bytes->data(), bytes->size());
      ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
      ExpectEqualMesh(mesh, *decoded);
    }
}

TEST(PlyTest, HeaderIsTheDocumentedLayout) {
  auto bytes = EncodePly(Tetrahedron(false, true));
  ASSERT_TRUE(bytes.ok());
  const std::string text(bytes->begin(), bytes->end());
  EXPECT_EQ(text.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
  EXPECT_NE(text.find("element vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                      "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                      "element face 4\nproperty list uchar int vertex_indices\nend_header\n"),
            std::string::npos);
}

TEST(PlyTest, FileRoundTrip) {
  const std::string path = testing::TempDir() + "/vd_ply_test.ply";
  const TriangleMesh mesh = Tetrahedron(true, true);
  ASSERT_TRUE(WritePly(path, mesh).ok());
  auto read = ReadPly(path);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ExpectEqualMesh(mesh, *read);
  std::remove(path.c_str());
  EXPECT_EQ(ReadPly(path).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(WritePly("/nonexistent-dir/x.ply", mesh).code(), StatusCode::kNotFound);
}

TEST(PlyTest, ReadsAsciiWithDoublesNormalsColourAndAlpha) {
  const std::string ply =
      "ply\r\nformat ascii 1.0\r\ncomment made by hand\r\nobj_info test\r\n"
      "element vertex 3\r\nproperty double x\r\nproperty double y\r\nproperty double z\r\n"
      "property float nx\r\nproperty float ny\r\nproperty float nz\r\n"
      "property uchar red\r\nproperty uchar green\r\nproperty uchar blue\r\nproperty uchar alpha\r\n"
      "element face 1\r\nproperty list int uint vertex_index\r\nend_header\r\n"
      "0.5 -1e-3 2 0 0 1 255 128 0 255\r\n1 0 0 0 1 0 1 2 3 0\r\n0 1 0 1 0 0 9 8 7 100\r\n3 2 0 1\r\n";
  auto mesh = Decode(ply);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  EXPECT_EQ(mesh->positions, (std::vector<float>{0.5f, -1e-3f, 2.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}));
  EXPECT_EQ(mesh->normals, (std::vector<float>{0, 0, 1, 0, 1, 0, 1, 0, 0}));
  EXPECT_EQ(mesh->colors, (std::vector<uint8_t>{255, 128, 0, 1, 2, 3, 9, 8, 7}));
  EXPECT_EQ(mesh->triangles, (std::vector<int32_t>{2, 0, 1}));
}

TEST(PlyTest, ReadsBinaryDoubleXyzWithIntCountsFacesFirst) {
  std::string ply =
      "ply\nformat binary_little_endian 1.0\nelement face 1\nproperty list int int vertex_indices\n"
      "element vertex 3\nproperty double x\nproperty double y\nproperty double z\nend_header\n";
  auto put = [&](const void* p, size_t n) { ply.append(static_cast<const char*>(p), n); };
  const int32_t face[4] = {3, 1, 2, 0};
  put(face, sizeof(face));
  const double xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0.125};
  put(xyz, sizeof(xyz));
  auto mesh = Decode(ply);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  EXPECT_EQ(mesh->triangles, (std::vector<int32_t>{1, 2, 0}));
  EXPECT_EQ(mesh->positions, (std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0.125f}));
  EXPECT_TRUE(mesh->colors.empty());
  EXPECT_TRUE(mesh->normals.empty());
}

TEST(PlyTest, RejectsUnsupportedHeadersWithAClearError) {
  const std::string v = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
  struct Case {
    std::string header;
    std::string expect;
  } cases[] = {
      {"plx\nformat ascii 1.0\n" + v + "end_header\n", "not a PLY"},
      {"ply\nformat binary_big_endian 1.0\n" + v + "end_header\n", "binary_big_endian"},
      {"ply\nformat ascii 2.0\n" + v + "end_header\n", "version"},
      {"ply\n" + v + "end_header\n", "no format"},
      {"ply\nformat ascii 1.0\n" + v, "end_header"},
      {"ply\nformat ascii 1.0\n" + v + "property float intensity\nend_header\n", "intensity"},
      {"ply\nformat ascii 1.0\n" + v + "property ushort red\nend_header\n", "uchar"},
      {"ply\nformat ascii 1.0\n" + v + "property uchar nx\nend_header\n", "float or double"},
      {"ply\nformat ascii 1.0\n" + v + "property float nx\nend_header\n", "nx, ny, nz"},
      {"ply\nformat ascii 1.0\n" + v + "property float x\nend_header\n", "repeated"},
      {"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nend_header\n", "x, y or z"},
      {"ply\nformat ascii 1.0\n" + v + "element edge 0\nend_header\n", "edge"},
      {"ply\nformat ascii 1.0\n" + v + "element face 1\nproperty list short int vertex_indices\nend_header\n",
       "face count type"},
      {"ply\nformat ascii 1.0\n" + v + "element face 1\nproperty list uchar float vertex_indices\nend_header\n",
       "face index type"},
      {"ply\nformat ascii 1.0\n" + v + "element face 1\nproperty list uchar int texcoord\nend_header\n", "texcoord"},
      {"ply\nformat ascii 1.0\nelement vertex -1\nend_header\n", "count"},
      {"ply\nformat ascii 1.0\nelement vertex 99999999999\nend_header\n", "count"},
      {"ply\nformat ascii 1.0\nproperty float x\nend_header\n", "outside"},
  };
  for (const Case& c : cases) {
    auto mesh = Decode(c.header + "0 0 0\n");
    ASSERT_FALSE(mesh.ok()) << c.header;
    EXPECT_NE(mesh.status().message().find(c.expect), std::string::npos)
        << "'" << c.expect << "' not in: " << mesh.status().message();
  }
}

TEST(PlyTest, RejectsBadBodies) {
  const std::string h = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                        "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  const std::string verts = "0 0 0\n1 0 0\n0 1 0\n";
  EXPECT_TRUE(Decode(h + verts + "3 0 1 2\n").ok());
  EXPECT_NE(Decode(h + verts + "4 0 1 2 0\n").status().message().find("only triangles"), std::string::npos);
  EXPECT_NE(Decode(h + verts + "3 0 1 3\n").status().message().find("refers to vertex 3"), std::string::npos);
  EXPECT_NE(Decode(h + verts + "3 0 1 -1\n").status().message().find("refers to vertex -1"), std::string::npos);
  EXPECT_FALSE(Decode(h + verts + "3 0 1\n").ok());
  EXPECT_FALSE(Decode(h + verts + "3 0 1 2 7\n").ok());
  EXPECT_FALSE(Decode(h + "0 0 0\n1 0 zero\n0 1 0\n3 0 1 2\n").ok());
  EXPECT_FALSE(Decode(h + "0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n").ok());
  EXPECT_FALSE(Decode(h + "0 0 0\n1 0 1e300\n0 1 0\n3 0 1 2\n").ok());
  // Binary: short and long bodies.
  auto bytes = EncodePly(Tetrahedron(false, true));
  ASSERT_TRUE(bytes.ok());
  EXPECT_EQ(DecodePly(bytes->data(), bytes->size() - 1).status().code(), StatusCode::kDataLoss);
  std::vector<uint8_t> longer = *bytes;
  longer.push_back(0);
  EXPECT_NE(DecodePly(longer.data(), longer.size()).status().message().find("after the last element"), std::string::npos);
  EXPECT_EQ(DecodePly(nullptr, 0).status().code(), StatusCode::kDataLoss);
  // Counts far larger than the body are refused before allocating.
  const std::string huge = "ply\nformat binary_little_endian 1.0\nelement vertex 700000000\nproperty float x\n"
                           "property float y\nproperty float z\nend_header\n";
  EXPECT_EQ(Decode(huge + "abcd").status().code(), StatusCode::kDataLoss);
}

TEST(PlyTest, EncodeRefusesInvalidMesh) {
  TriangleMesh bad = Tetrahedron(false, false);
  bad.triangles[0] = 4;
  EXPECT_FALSE(EncodePly(bad).ok());
  bad = Tetrahedron(false, true);
  bad.colors.pop_back();
  EXPECT_FALSE(EncodePly(bad).ok());
}

TEST(PlyTest, EmptyMeshRoundTrips) {
  auto bytes = EncodePly(TriangleMesh{});
  ASSERT_TRUE(bytes.ok());
  auto decoded = DecodePly(bytes->data(), bytes->size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  EXPECT_TRUE(decoded->positions.empty());
  EXPECT_TRUE(decoded->triangles.empty());
}

}  // namespace
}  // namespace vd
