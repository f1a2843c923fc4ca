// Bugs the libFuzzer targets (tests/fuzz) found, one case each; the reproducers themselves are
// in tests/fuzz/regressions/<target>/ and run_fuzz.sh replays them.
#include <cstring>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "vd/common/codecs.h"
#include "vd/common/log.h"
#include "vd/common/messages.h"

namespace vd {
namespace {

template <typename Msg>
std::vector<uint8_t> Wire(const Msg& msg) {
  std::vector<uint8_t> out(static_cast<size_t>(msg.getEncodedSize()));
  EXPECT_EQ(msg.encode(out.data(), 0, static_cast<int>(out.size())), static_cast<int>(out.size()));
  return out;
}

// Replaces the first occurrence of `from` in the wire bytes by `to` (same length).
void Patch(std::vector<uint8_t>* wire, const std::string& from, const std::string& to) {
  ASSERT_EQ(from.size(), to.size());
  const std::string text(wire->begin(), wire->end());
  const size_t at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  std::memcpy(wire->data() + at, to.data(), to.size());
}

vdeform::control_t Control() {
  vdeform::control_t msg{};
  msg.utime = 1700000000000000;
  msg.command = vdeform::control_t::COMMAND_SAVE_SNAPSHOT;
  msg.path = "run-1";
  msg.sender = "viewer@hXost";
  return msg;
}

vdeform::rgbd_frame_t Frame() {
  vdeform::rgbd_frame_t msg{};
  msg.seq = 1;
  msg.source_id = "synthetic:Xtube";
  msg.fx = msg.fy = 20.f;
  msg.cx = 1.5f;
  msg.cy = 0.5f;
  msg.width = 4;
  msg.height = 2;
  msg.depth_scale = 1000.f;
  msg.depth_encoding = vdeform::rgbd_frame_t::DEPTH_RAW16;
  msg.depth_data.assign(4 * 2 * 2, 7);
  msg.depth_size = static_cast<int32_t>(msg.depth_data.size());
  msg.color_encoding = vdeform::rgbd_frame_t::COLOR_NONE;
  return msg;
}

// fuzz_lcm_control, fuzz_lcm_frame, fuzz_lcm_status: lcm-gen's decode() keeps a NUL inside a
// string (sender "viewer@h\0ost"), while every encoder and C API stops at it. The decoded message
// then re-encoded to fewer bytes than getEncodedSize() (LCM::publish sends the rest of its buffer
// uninitialised), and the server checked a different snapshot path or source id than the one it
// used. ValidateLcmWire now refuses such strings, and strings without their terminating NUL.
TEST(FuzzRegressionTest, LcmStringWithNulInsideIsRefused) {
  std::vector<uint8_t> control = Wire(Control());
  ASSERT_TRUE(DecodeLcm<vdeform::control_t>(control.data(), control.size()).ok());
  Patch(&control, "hXost", std::string("h\0ost", 5));
  auto decoded = DecodeLcm<vdeform::control_t>(control.data(), control.size());
  ASSERT_FALSE(decoded.ok());
  EXPECT_NE(decoded.status().message().find("control_t.sender holds a NUL byte"), std::string::npos)
      << decoded.status().message();

  std::vector<uint8_t> frame = Wire(Frame());
  ASSERT_TRUE(DecodeLcm<vdeform::rgbd_frame_t>(frame.data(), frame.size()).ok());
  ASSERT_TRUE(MessageToFrame(*DecodeLcm<vdeform::rgbd_frame_t>(frame.data(), frame.size())).ok());
  Patch(&frame, "c:Xtube", std::string("c:\0tube", 7));
  auto frame_msg = DecodeLcm<vdeform::rgbd_frame_t>(frame.data(), frame.size());
  ASSERT_FALSE(frame_msg.ok());
  EXPECT_NE(frame_msg.status().message().find("source_id"), std::string::npos) << frame_msg.status().message();

  vdeform::server_status_t status{};
  status.message = "ok";
  status.reject_reason = {"malformed_Xmessage"};
  status.reject_count = {1};
  status.num_reject_reasons = 1;
  std::vector<uint8_t> status_wire = Wire(status);
  ASSERT_TRUE(DecodeLcm<vdeform::server_status_t>(status_wire.data(), status_wire.size()).ok());
  Patch(&status_wire, "malformed_X", std::string("malformed_\0", 11));
  EXPECT_FALSE(DecodeLcm<vdeform::server_status_t>(status_wire.data(), status_wire.size()).ok());
}

TEST(FuzzRegressionTest, LcmStringWithoutTerminatingNulIsRefused) {
  std::vector<uint8_t> control = Wire(Control());
  // "run-1\0" becomes "run-12": the length still counts six bytes, the last is not the NUL.
  Patch(&control, std::string("run-1\0", 6), "run-12");
  auto decoded = DecodeLcm<vdeform::control_t>(control.data(), control.size());
  ASSERT_FALSE(decoded.ok());
  EXPECT_NE(decoded.status().message().find("control_t.path is not NUL-terminated"), std::string::npos)
      << decoded.status().message();
}

TEST(FuzzRegressionTest, LcmEmptyStringsStillDecode) {
  vdeform::control_t msg = Control();
  msg.path.clear();
  msg.sender.clear();
  const std::vector<uint8_t> wire = Wire(msg);
  auto decoded = DecodeLcm<vdeform::control_t>(wire.data(), wire.size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  EXPECT_TRUE(decoded->path.empty());
  EXPECT_TRUE(decoded->sender.empty());
}

// fuzz_draco: a Draco stream whose four triangles all repeat a vertex decodes to a valid mesh, but
// EncodeMeshDraco returned "All triangles are degenerate" from edgebreaker instead of falling back
// to sequential coding as it does when edgebreaker changes the counts.
TEST(FuzzRegressionTest, DracoAllDegenerateTrianglesEncode) {
  SetLogLevel(LogLevel::kWarning);
  const std::vector<uint8_t> reproducer = {
      0x44, 0x52, 0x41, 0x43, 0x4f, 0x02, 0x02, 0x01, 0x00, 0x00, 0x00, 0x04, 0x04, 0x01, 0x00, 0x02, 0x00, 0x00, 0x00,
      0x00, 0x02, 0x00, 0x00, 0x00, 0x00, 0x03, 0x01, 0x02, 0x00, 0x09, 0x03, 0x00, 0x00, 0x02, 0x02, 0x03, 0x01, 0x01,
      0x02, 0x01, 0x00, 0x01, 0x01, 0x00, 0x03, 0x03, 0x01, 0x20, 0x01, 0x20, 0x03, 0x00, 0x20, 0x84, 0x88, 0x81, 0x01,
      0x00, 0x00, 0x00, 0x00, 0xff, 0x3f, 0x00, 0x00, 0x00, 0x01, 0x01, 0x00, 0x08, 0x03, 0x01, 0x10, 0x01, 0x20, 0x0f,
      0x01, 0x10, 0x03, 0x90, 0x90, 0x31, 0xb0, 0x26, 0xbb, 0x0d, 0x00, 0x00, 0x00, 0x00, 0xff, 0x00, 0x00, 0x00, 0x00,
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xcd, 0xcc, 0xcc, 0x3d, 0x0e};
  auto decoded = DecodeMeshDraco(reproducer.data(), reproducer.size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  ASSERT_EQ(decoded->num_triangles(), 4u);

  TriangleMesh mesh;
  mesh.positions = {0.f, 0.f, 0.f, 0.1f, 0.f, 0.f, 0.f, 0.1f, 0.f, 0.f, 0.f, 0.1f};
  mesh.triangles = {0, 2, 0, 0, 0, 0, 1, 1, 3, 0, 0, 3};
  for (const TriangleMesh* m : {&*decoded, &mesh}) {
    for (int speed : {0, 7, 10}) {
      DracoOptions options;
      options.speed = speed;
      auto encoded = EncodeMeshDraco(*m, options);
      ASSERT_TRUE(encoded.ok()) << "speed " << speed << ": " << encoded.status().ToString();
      auto again = DecodeMeshDraco(encoded->data(), encoded->size());
      ASSERT_TRUE(again.ok()) << again.status().ToString();
      EXPECT_EQ(again->num_vertices(), m->num_vertices());
      EXPECT_EQ(again->triangles, m->triangles);
    }
  }
  SetLogLevel(LogLevel::kInfo);
}

// fuzz_draco: a Draco stream can decode to finite coordinates of both signs near FLT_MAX (here
// -1.7e38 .. 1.7e38 on one axis, 3e38 below). Their extent overflows float, and EncodeMeshDraco
// crashed inside Draco's quantiser (SEGV in ComputeShannonEntropy). It now refuses such a mesh.
TEST(FuzzRegressionTest, DracoExtentOverflowingFloatIsRefused) {
  TriangleMesh mesh;
  mesh.positions = {-3e38f, 0.f, 0.f, 3e38f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f};
  mesh.triangles = {0, 1, 2, 0, 2, 3, 0, 3, 1, 1, 3, 2};
  ASSERT_TRUE(mesh.Validate().ok());
  auto encoded = EncodeMeshDraco(mesh);
  ASSERT_FALSE(encoded.ok());
  EXPECT_EQ(encoded.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(encoded.status().message().find("along axis 0"), std::string::npos) << encoded.status().message();
  // Coordinates up to kMaxDracoCoordinate still encode.
  for (float& p : mesh.positions) p *= 0.5f * kMaxDracoCoordinate / 3e38f;
  auto half = EncodeMeshDraco(mesh);
  ASSERT_TRUE(half.ok()) << half.status().ToString();
  auto decoded = DecodeMeshDraco(half->data(), half->size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  EXPECT_EQ(decoded->num_triangles(), 4u);
}

// fuzz_draco (invariant, found by the CI run of fuzz_short): a stream decoding to coordinates near
// -FLT_MAX with a finite extent re-encoded fine, but Draco's dequantisation of that box gave
// infinity, so the re-encoded mesh no longer decoded. EncodeMeshDraco now refuses coordinates and
// extents beyond kMaxDracoCoordinate (1e30).
TEST(FuzzRegressionTest, DracoCoordinatesNearFloatMaxAreRefusedBeforeEncoding) {
  const std::vector<uint8_t> stream = {
      0x44, 0x52, 0x41, 0x43, 0x4f, 0x02, 0x02, 0x01, 0x00, 0x00, 0x00, 0x04, 0x04, 0x01, 0x00, 0x02, 0x01, 0x00,
      0x01, 0x03, 0x00, 0x03, 0x02, 0x01, 0x02, 0x03, 0x01, 0x02, 0x00, 0x09, 0x03, 0x00, 0x00, 0x06, 0x02, 0x03,
      0x00, 0x00, 0x00, 0x01, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x08, 0xfb, 0xff, 0x00,
      0x6e, 0xff, 0xff, 0xff, 0x7f, 0xff, 0xc6, 0x00, 0x00, 0x10, 0x61, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xff, 0xff, 0xff, 0x1b, 0x00, 0x00, 0x00, 0x00, 0xcd,
      0xcc, 0xcc, 0x3d, 0x0e,
  };
  auto mesh = DecodeMeshDraco(stream.data(), stream.size());
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  auto encoded = EncodeMeshDraco(*mesh);
  ASSERT_FALSE(encoded.ok()) << "encoding it produced a stream that decodes to infinity";
  EXPECT_EQ(encoded.status().code(), StatusCode::kInvalidArgument);
}

// fuzz_draco (out of memory): Draco allocates for the face and vertex counts at the start of the
// connectivity before reading any data. This 237-byte stream declares 160638654 faces; decoding it
// took over 3 GB. DecodeMeshDraco now refuses counts above 64 per input byte (and 2^24) first.
TEST(FuzzRegressionTest, DracoDeclaredCountsBoundedByInputSize) {
  const std::vector<uint8_t> bomb = {
      0x44, 0x52, 0x41, 0x43, 0x4f, 0x02, 0x02, 0x01, 0x01, 0x00, 0x00, 0x00, 0x30, 0xbe, 0xcd, 0xcc, 0x4c, 0x3f,
      0xce, 0xcc, 0xcc, 0x3e, 0x08, 0x01, 0x01, 0x01, 0x01, 0x06, 0x62, 0x89, 0x39, 0xb8, 0x3b, 0xb8, 0xb8, 0x4f,
      0xb8, 0xb8, 0x47, 0xb8, 0xb8, 0x87, 0xb8, 0x03, 0xb8, 0x0b, 0x18, 0x35, 0x9d, 0x51, 0x04, 0x14, 0x4b, 0x69,
      0xb0, 0x8e, 0x9b, 0x00, 0x00, 0x00, 0x00, 0x80, 0x00, 0x00, 0x00, 0x06, 0x03, 0x01, 0x00, 0x0b, 0x03, 0x89,
      0x08, 0x1f, 0x79, 0x37, 0x05, 0x8a, 0x2d, 0xf1, 0x4a, 0x80, 0x48, 0xe0, 0xec, 0x7c, 0x0c, 0x38, 0x27, 0xd1,
      0xbe, 0x0b, 0xfe, 0x0b, 0x10, 0xfd, 0xdf, 0x93, 0xb2, 0xf5, 0x0b, 0xec, 0x27, 0x81, 0x73, 0x0c, 0xcf, 0xe3,
      0x8c, 0x04, 0xb8, 0x4f, 0xb8, 0xb8, 0x47, 0xb8, 0xb8, 0x87, 0xb8, 0x03, 0xb8, 0x0b, 0x18, 0x35, 0x9d, 0x51,
      0x04, 0x14, 0x4b, 0x69, 0xb0, 0x8e, 0x9b, 0x00, 0x00, 0x00, 0x00, 0x80, 0x00, 0x00, 0x00, 0x06, 0x03, 0x01,
      0x00, 0x0b, 0x03, 0x89, 0x08, 0x1f, 0x79, 0x37, 0x05, 0x8a, 0x2d, 0xf1, 0x4a, 0x80, 0x48, 0xe0, 0xec, 0x7c,
      0x0c, 0x38, 0x27, 0xd1, 0xbe, 0x0b, 0xfe, 0x0b, 0x10, 0xfd, 0xdf, 0x93, 0xb2, 0xf5, 0x0b, 0xec, 0x27, 0x81,
      0x73, 0x0c, 0xcf, 0xe3, 0x8c, 0x04, 0xf8, 0xf3, 0x6f, 0x4d, 0x8a, 0x00, 0xfd, 0xbf, 0xc0, 0x3e, 0xfd, 0xde,
      0x37, 0x1f, 0x83, 0x15, 0x83, 0xf3, 0x49, 0xe0, 0x4c, 0xca, 0xd6, 0x49, 0xdc, 0x7c, 0x73, 0x12, 0xea, 0xc3,
      0xf0, 0x3d, 0xfd, 0x38, 0x27, 0xb1, 0x35, 0x29, 0xff, 0x03, 0x00, 0x00, 0xff, 0x01, 0x00, 0x00, 0xff, 0x02,
      0x0e, 0x42, 0x0a};
  auto decoded = DecodeMeshDraco(bomb.data(), bomb.size());
  ASSERT_FALSE(decoded.ok());
  EXPECT_EQ(decoded.status().code(), StatusCode::kDataLoss);
  EXPECT_NE(decoded.status().message().find("declares 160638654 faces"), std::string::npos) << decoded.status().message();

  // The same for sequential coding's point count: a valid stream whose count of 30 points (one
  // varint byte after the face count) is rewritten to 2^28 - 1.
  DracoOptions sequential;
  sequential.speed = 10;
  TriangleMesh mesh;
  for (int r = 0; r <= 4; ++r)
    for (int s = 0; s < 6; ++s) mesh.positions.insert(mesh.positions.end(), {0.1f * r, 0.1f * s, 0.01f * r * s});
  for (int r = 0; r < 4; ++r)
    for (int s = 0; s < 5; ++s) {
      const int a = r * 6 + s;
      mesh.triangles.insert(mesh.triangles.end(), {a, a + 6, a + 7, a, a + 7, a + 1});
    }
  auto valid = EncodeMeshDraco(mesh, sequential);
  ASSERT_TRUE(valid.ok()) << valid.status().ToString();
  ASSERT_TRUE(DecodeMeshDraco(valid->data(), valid->size()).ok());
  std::vector<uint8_t> patched = *valid;
  // Header (11 bytes), faces = 40 (one byte), points = 30 (one byte).
  ASSERT_EQ(patched[8], 0);
  ASSERT_EQ(patched[11], 40);
  ASSERT_EQ(patched[12], 30);
  patched[12] = 0xFF;
  patched.insert(patched.begin() + 13, {0xFF, 0xFF, 0x7F});
  decoded = DecodeMeshDraco(patched.data(), patched.size());
  ASSERT_FALSE(decoded.ok());
  EXPECT_NE(decoded.status().message().find("268435455 vertices"), std::string::npos) << decoded.status().message();
}

// fuzz_lcm_mesh: a RAW mesh_t could carry a PLY with vertices and no triangles, and MessageToMesh
// returned it, while MeshToMessage sends a mesh without triangles as no data and Draco refuses one.
// Both encodings now refuse data that declares no triangles.
TEST(FuzzRegressionTest, MeshMessageWithDataButNoTrianglesIsRefused) {
  TriangleMesh points;
  points.positions = {0.f, 0.f, 1.f, 0.1f, 0.f, 1.f, 0.f, 0.1f, 1.f, 0.1f, 0.1f, 1.f};
  auto ply = EncodePly(points);
  ASSERT_TRUE(ply.ok());
  ASSERT_TRUE(DecodePly(ply->data(), ply->size()).ok());
  vdeform::mesh_t msg{};
  msg.kind = vdeform::mesh_t::KIND_LIVE;
  msg.encoding = vdeform::mesh_t::ENCODING_RAW;
  msg.num_vertices = 4;
  msg.num_triangles = 0;
  msg.data = *ply;
  msg.data_size = static_cast<int32_t>(ply->size());
  auto mesh = MessageToMesh(msg);
  ASSERT_FALSE(mesh.ok());
  EXPECT_NE(mesh.status().message().find("declares no triangles"), std::string::npos) << mesh.status().message();
}

}  // namespace
}  // namespace vd
