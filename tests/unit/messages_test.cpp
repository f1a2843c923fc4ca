#include <cmath>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "vd/common/messages.h"

namespace vd {
namespace {

RgbdFrame TestFrame(int width, int height, bool color) {
  RgbdFrame f;
  f.utime = 1234567;
  f.seq = 42;
  f.source_id = "cam0";
  f.intrinsics = {525.f, 526.f, width / 2.f, height / 2.f, width, height};
  f.depth_scale = 1000.f;
  f.depth.create(height, width, CV_16UC1);
  std::mt19937 rng(5);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) f.depth.at<uint16_t>(y, x) = (rng() % 10 == 0) ? 0 : 900 + x + y + rng() % 4;
  if (color) {
    f.color.create(height, width, CV_8UC3);
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x)
        f.color.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<uint8_t>(x * 4), static_cast<uint8_t>(y * 4), 90);
  }
  return f;
}

vdeform::rgbd_frame_t GoodMessage() {
  FrameEncodeOptions options;
  options.color = ColorEncoding::kRawBgr8;
  auto msg = FrameToMessage(TestFrame(32, 24, true), options);
  EXPECT_TRUE(msg.ok());
  return *msg;
}

TEST(MessagesTest, FrameRoundTripThroughLcmBytesForEveryEncoding) {
  const RgbdFrame frame = TestFrame(64, 48, true);
  for (DepthEncoding depth : {DepthEncoding::kRaw16, DepthEncoding::kPng16, DepthEncoding::kRvl})
    for (ColorEncoding color : {ColorEncoding::kNone, ColorEncoding::kRawBgr8, ColorEncoding::kJpeg}) {
      SCOPED_TRACE(std::string(DepthEncodingName(depth)) + "/" + ColorEncodingName(color));
      FrameEncodeOptions options;
      options.depth = depth;
      options.color = color;
      auto msg = FrameToMessage(frame, options);
      ASSERT_TRUE(msg.ok()) << msg.status().ToString();
      EXPECT_EQ(msg->depth_encoding, static_cast<int8_t>(depth));
      EXPECT_EQ(msg->color_encoding, static_cast<int8_t>(color));
      EXPECT_EQ(msg->depth_size, static_cast<int32_t>(msg->depth_data.size()));
      std::vector<uint8_t> wire(msg->getEncodedSize());
      ASSERT_EQ(msg->encode(wire.data(), 0, static_cast<int>(wire.size())), static_cast<int>(wire.size()));
      auto received = DecodeLcm<vdeform::rgbd_frame_t>(wire.data(), wire.size());
      ASSERT_TRUE(received.ok()) << received.status().ToString();
      auto out = MessageToFrame(*received);
      ASSERT_TRUE(out.ok()) << out.status().ToString();
      EXPECT_TRUE(out->Validate().ok());
      EXPECT_EQ(out->utime, frame.utime);
      EXPECT_EQ(out->seq, frame.seq);
      EXPECT_EQ(out->source_id, frame.source_id);
      EXPECT_EQ(out->intrinsics.fx, frame.intrinsics.fx);
      EXPECT_EQ(out->intrinsics.cy, frame.intrinsics.cy);
      EXPECT_EQ(out->depth_scale, frame.depth_scale);
      EXPECT_EQ(cv::countNonZero(out->depth != frame.depth), 0);
      if (color == ColorEncoding::kNone) {
        EXPECT_TRUE(out->color.empty());
      } else {
        ASSERT_EQ(out->color.size(), frame.color.size());
        cv::Mat diff;
        cv::absdiff(out->color, frame.color, diff);
        double max_diff = 0;
        cv::minMaxLoc(diff.reshape(1), nullptr, &max_diff);
        EXPECT_LE(max_diff, color == ColorEncoding::kRawBgr8 ? 0.0 : 40.0);
      }
    }
}

TEST(MessagesTest, FrameWithoutColourIsSentAsNone) {
  auto msg = FrameToMessage(TestFrame(16, 12, false), FrameEncodeOptions{});
  ASSERT_TRUE(msg.ok());
  EXPECT_EQ(msg->color_encoding, +vdeform::rgbd_frame_t::COLOR_NONE);
  EXPECT_EQ(msg->color_size, 0);
  EXPECT_TRUE(MessageToFrame(*msg).ok());
}

TEST(MessagesTest, FrameToMessageRejectsBadInput) {
  FrameEncodeOptions options;
  options.jpeg_quality = 0;
  EXPECT_FALSE(FrameToMessage(TestFrame(16, 12, true), options).ok());
  RgbdFrame frame = TestFrame(16, 12, true);
  frame.intrinsics.width = 17;
  EXPECT_FALSE(FrameToMessage(frame, {}).ok());
  frame = TestFrame(16, 12, true);
  frame.source_id.assign(300, 'x');
  EXPECT_FALSE(FrameToMessage(frame, {}).ok());
  // Raw 4096x2048 depth + colour is 41 MB: above kMaxPayloadBytes.
  frame = TestFrame(4096, 2048, true);
  options = FrameEncodeOptions{};
  options.depth = DepthEncoding::kRaw16;
  options.color = ColorEncoding::kRawBgr8;
  EXPECT_EQ(FrameToMessage(frame, options).status().code(), StatusCode::kOutOfRange);
}

TEST(MessagesTest, MessageToFrameValidatesEveryField) {
  ASSERT_TRUE(MessageToFrame(GoodMessage()).ok());
  struct Case {
    const char* what;
    void (*mutate)(vdeform::rgbd_frame_t*);
  } cases[] = {
      {"depth_encoding", [](vdeform::rgbd_frame_t* m) { m->depth_encoding = 7; }},
      {"depth_encoding", [](vdeform::rgbd_frame_t* m) { m->depth_encoding = -1; }},
      {"color_encoding", [](vdeform::rgbd_frame_t* m) { m->color_encoding = 3; }},
      {"depth_size", [](vdeform::rgbd_frame_t* m) { m->depth_size += 1; }},
      {"depth_size", [](vdeform::rgbd_frame_t* m) { m->depth_size = -5; }},
      {"color_size", [](vdeform::rgbd_frame_t* m) { m->color_data.pop_back(); }},
      {"width", [](vdeform::rgbd_frame_t* m) { m->width = 0; }},
      {"height", [](vdeform::rgbd_frame_t* m) { m->height = 100000; }},
      {"fx", [](vdeform::rgbd_frame_t* m) { m->fx = NAN; }},
      {"cy", [](vdeform::rgbd_frame_t* m) { m->cy = -1e6f; }},
      {"depth_scale", [](vdeform::rgbd_frame_t* m) { m->depth_scale = 0.f; }},
      {"depth_scale", [](vdeform::rgbd_frame_t* m) { m->depth_scale = INFINITY; }},
      {"source_id", [](vdeform::rgbd_frame_t* m) { m->source_id.assign(1000, 'a'); }},
      // Declared size disagrees with the encoded images.
      {"depth", [](vdeform::rgbd_frame_t* m) { m->width = 33; }},
      {"colour", [](vdeform::rgbd_frame_t* m) { m->color_encoding = vdeform::rgbd_frame_t::COLOR_JPEG; }},
      {"colour", [](vdeform::rgbd_frame_t* m) {
         m->color_encoding = vdeform::rgbd_frame_t::COLOR_NONE;
       }},
      {"kMaxPayloadBytes", [](vdeform::rgbd_frame_t* m) {
         m->color_data.resize(kMaxPayloadBytes);
         m->color_size = static_cast<int32_t>(m->color_data.size());
       }},
  };
  for (const Case& c : cases) {
    vdeform::rgbd_frame_t msg = GoodMessage();
    c.mutate(&msg);
    auto frame = MessageToFrame(msg);
    ASSERT_FALSE(frame.ok()) << c.what;
    EXPECT_NE(frame.status().message().find(c.what), std::string::npos)
        << "'" << c.what << "' not in: " << frame.status().message();
  }
}

TriangleMesh Grid(int n) {
  TriangleMesh m;
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) {
      m.positions.insert(m.positions.end(), {x * 0.01f, y * 0.02f, 0.5f + 0.001f * ((x * y) % 7)});
      m.colors.insert(m.colors.end(), {static_cast<uint8_t>(x), static_cast<uint8_t>(y), 7});
    }
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const int a = y * (n + 1) + x, b = a + 1, c = a + n + 1, d = c + 1;
      m.triangles.insert(m.triangles.end(), {a, b, d, a, d, c});
    }
  return m;
}

TEST(MessagesTest, MeshRoundTripDracoAndRaw) {
  const TriangleMesh mesh = Grid(20);
  for (int8_t encoding : {vdeform::mesh_t::ENCODING_DRACO, vdeform::mesh_t::ENCODING_RAW}) {
    auto msg = MeshToMessage(mesh, 99, 7, vdeform::mesh_t::KIND_LIVE, encoding);
    ASSERT_TRUE(msg.ok()) << msg.status().ToString();
    EXPECT_EQ(msg->num_vertices, 441);
    EXPECT_EQ(msg->num_triangles, 800);
    EXPECT_EQ(msg->utime, 99);
    EXPECT_EQ(msg->seq, 7);
    EXPECT_FLOAT_EQ(msg->bbox_min[0], 0.f);
    EXPECT_FLOAT_EQ(msg->bbox_max[0], 0.2f);
    EXPECT_FLOAT_EQ(msg->bbox_max[1], 0.4f);
    EXPECT_FLOAT_EQ(msg->bbox_min[2], 0.5f);
    EXPECT_EQ(msg->data_size, static_cast<int32_t>(msg->data.size()));
    std::vector<uint8_t> wire(msg->getEncodedSize());
    ASSERT_GT(msg->encode(wire.data(), 0, static_cast<int>(wire.size())), 0);
    auto received = DecodeLcm<vdeform::mesh_t>(wire.data(), wire.size());
    ASSERT_TRUE(received.ok());
    auto out = MessageToMesh(*received);
    ASSERT_TRUE(out.ok()) << out.status().ToString();
    EXPECT_EQ(out->num_vertices(), mesh.num_vertices());
    EXPECT_EQ(out->num_triangles(), mesh.num_triangles());
    if (encoding == vdeform::mesh_t::ENCODING_RAW) {
      EXPECT_EQ(out->positions, mesh.positions);
      EXPECT_EQ(out->triangles, mesh.triangles);
    }
  }
}

// A --track-mesh server's KIND_TRACKED mesh goes through like the others; kinds past it do not.
TEST(MessagesTest, TrackedKindRoundTripsAndUnknownKindsAreRefused) {
  const TriangleMesh mesh = Grid(6);
  auto msg = MeshToMessage(mesh, 5, 9, vdeform::mesh_t::KIND_TRACKED, vdeform::mesh_t::ENCODING_RAW);
  ASSERT_TRUE(msg.ok()) << msg.status().ToString();
  EXPECT_EQ(int(msg->kind), int(vdeform::mesh_t::KIND_TRACKED));
  auto out = MessageToMesh(*msg);
  ASSERT_TRUE(out.ok()) << out.status().ToString();
  EXPECT_EQ(out->positions, mesh.positions);
  EXPECT_EQ(out->triangles, mesh.triangles);
  EXPECT_FALSE(MeshToMessage(mesh, 5, 9, 3).ok());
  msg->kind = 3;
  EXPECT_FALSE(MessageToMesh(*msg).ok());
}

TEST(MessagesTest, EmptyMeshIsZeroBytes) {
  TriangleMesh points;
  points.positions = {1.f, 2.f, 3.f};
  for (int8_t encoding : {vdeform::mesh_t::ENCODING_DRACO, vdeform::mesh_t::ENCODING_RAW}) {
    auto msg = MeshToMessage(points, 1, 2, vdeform::mesh_t::KIND_CANONICAL, encoding);
    ASSERT_TRUE(msg.ok()) << msg.status().ToString();
    EXPECT_EQ(msg->data_size, 0);
    EXPECT_EQ(msg->num_vertices, 0);
    EXPECT_EQ(msg->num_triangles, 0);
    auto out = MessageToMesh(*msg);
    ASSERT_TRUE(out.ok());
    EXPECT_TRUE(out->empty());
    EXPECT_TRUE(out->positions.empty());
  }
}

TEST(MessagesTest, MeshMessagesAreValidated) {
  const TriangleMesh mesh = Grid(4);
  EXPECT_FALSE(MeshToMessage(mesh, 0, 0, 5, vdeform::mesh_t::ENCODING_DRACO).ok());
  EXPECT_FALSE(MeshToMessage(mesh, 0, 0, vdeform::mesh_t::KIND_LIVE, 9).ok());
  DracoOptions bad_draco;
  bad_draco.speed = 20;
  EXPECT_FALSE(MeshToMessage(mesh, 0, 0, vdeform::mesh_t::KIND_LIVE, vdeform::mesh_t::ENCODING_DRACO, bad_draco).ok());
  auto good = MeshToMessage(mesh, 0, 0, vdeform::mesh_t::KIND_LIVE, vdeform::mesh_t::ENCODING_DRACO);
  ASSERT_TRUE(good.ok());
  struct Case {
    const char* what;
    void (*mutate)(vdeform::mesh_t*);
  } cases[] = {
      {"kind", [](vdeform::mesh_t* m) { m->kind = -1; }},
      {"encoding", [](vdeform::mesh_t* m) { m->encoding = 4; }},
      {"data_size", [](vdeform::mesh_t* m) { m->data_size -= 1; }},
      {"negative", [](vdeform::mesh_t* m) { m->num_vertices = -1; }},
      {"declares", [](vdeform::mesh_t* m) { m->num_vertices += 1; }},
      {"declares", [](vdeform::mesh_t* m) { m->num_triangles -= 1; }},
      {"bounding box", [](vdeform::mesh_t* m) { m->bbox_min[1] = NAN; }},
      {"bounding box", [](vdeform::mesh_t* m) { m->bbox_min[0] = 5.f; }},
      {"no data", [](vdeform::mesh_t* m) {
         m->data.clear();
         m->data_size = 0;
       }},
      // PLY bytes labelled as Draco.
      {"Draco", [](vdeform::mesh_t* m) {
         m->data = *EncodePly(Grid(4));
         m->data_size = static_cast<int32_t>(m->data.size());
       }},
  };
  for (const Case& c : cases) {
    vdeform::mesh_t msg = *good;
    c.mutate(&msg);
    auto out = MessageToMesh(msg);
    ASSERT_FALSE(out.ok()) << c.what;
    EXPECT_NE(out.status().message().find(c.what), std::string::npos)
        << "'" << c.what << "' not in: " << out.status().message();
  }
}

TEST(MessagesTest, ResolveLcmUrlPrefersFlagThenEnvironment) {
  ::unsetenv("LCM_DEFAULT_URL");
  EXPECT_EQ(ResolveLcmUrl(""), kDefaultLcmUrl);
  EXPECT_EQ(ResolveLcmUrl("memq://"), "memq://");
  ::setenv("LCM_DEFAULT_URL", "udpm://239.255.76.67:7700?ttl=0", 1);
  EXPECT_EQ(ResolveLcmUrl(""), "udpm://239.255.76.67:7700?ttl=0");
  EXPECT_EQ(ResolveLcmUrl("memq://"), "memq://");
  ::setenv("LCM_DEFAULT_URL", "", 1);
  EXPECT_EQ(ResolveLcmUrl(""), kDefaultLcmUrl);
  ::unsetenv("LCM_DEFAULT_URL");
}

TEST(MessagesTest, FrameEncodeOptionsValidateNamesFieldAndBound) {
  EXPECT_TRUE(FrameEncodeOptions{}.Validate().ok());
  FrameEncodeOptions o;
  o.jpeg_quality = 101;
  EXPECT_NE(o.Validate().message().find("jpeg_quality = 101"), std::string::npos);
  o = FrameEncodeOptions{};
  o.depth = DepthEncoding::kInvalid;
  EXPECT_NE(o.Validate().message().find("FrameEncodeOptions.depth"), std::string::npos);
  o = FrameEncodeOptions{};
  o.color = static_cast<ColorEncoding>(9);
  EXPECT_NE(o.Validate().message().find("FrameEncodeOptions.color"), std::string::npos);
}

}  // namespace
}  // namespace vd

namespace vd {
namespace {

TEST(StreamChannelsTest, NamedStreamsGetTheirOwnChannelsAndTheUnnamedOneTodaysNames) {
  StatusOr<StreamChannels> unnamed = ChannelsOfStream("");
  ASSERT_TRUE(unnamed.ok());
  EXPECT_EQ(unnamed->frames, "VDEFORM_FRAMES");
  EXPECT_EQ(unnamed->mesh, "VDEFORM_MESH");
  EXPECT_EQ(unnamed->status, "VDEFORM_STATUS");
  EXPECT_EQ(unnamed->control, "VDEFORM_CONTROL");
  StatusOr<StreamChannels> named = ChannelsOfStream("cam_2-left");
  ASSERT_TRUE(named.ok());
  EXPECT_EQ(named->frames, "VDEFORM_cam_2-left_FRAMES");
  EXPECT_EQ(named->mesh, "VDEFORM_cam_2-left_MESH");
  EXPECT_EQ(named->status, "VDEFORM_cam_2-left_STATUS");
  EXPECT_EQ(named->control, "VDEFORM_cam_2-left_CONTROL");
  for (const char* bad : {"a b", "a/b", "a.b", ".*", "A$"})
    EXPECT_EQ(ChannelsOfStream(bad).status().code(), StatusCode::kInvalidArgument) << bad;
  EXPECT_FALSE(ChannelsOfStream(std::string(65, 'x')).ok());
  EXPECT_TRUE(ChannelsOfStream(std::string(64, 'x')).ok());
}

TEST(StreamChannelsTest, TheStreamOfAChannelIsReadBack) {
  EXPECT_EQ(StreamOfChannel("VDEFORM_MESH", "MESH").value_or("?"), "");
  EXPECT_EQ(StreamOfChannel("VDEFORM_CAM_1_MESH", "MESH").value_or("?"), "CAM_1");
  EXPECT_EQ(StreamOfChannel("VDEFORM_MESH_MESH", "MESH").value_or("?"), "MESH");
  EXPECT_FALSE(StreamOfChannel("VDEFORM_CAM_1_STATUS", "MESH").has_value());
  EXPECT_FALSE(StreamOfChannel("OTHER_MESH", "MESH").has_value());
  EXPECT_FALSE(StreamOfChannel("VDEFORM__MESH", "MESH").has_value());
  EXPECT_FALSE(StreamOfChannel("VDEFORM_a b_MESH", "MESH").has_value());
  for (const char* name : {"", "A", "cam_2-left"})
    EXPECT_EQ(StreamOfChannel(ChannelsOfStream(name)->status, "STATUS").value_or("?"), name);
  EXPECT_EQ(AllStreamsChannelRegex("MESH"), "VDEFORM_([A-Za-z0-9_-]+_)?MESH");
}

}  // namespace
}  // namespace vd
