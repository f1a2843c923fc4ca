// The bridge's rules without sockets: the mesh frame layout, the status JSON, the commands a page
// may send, tokens, query strings and cookies.
#include "vd/viewer/web_protocol.h"

#include <cmath>
#include <cstring>
#include <limits>

#include <gtest/gtest.h>

#include "vd/viewer/web_options.h"

namespace vd {
namespace {

vdeform::mesh_t SampleMesh() {
  vdeform::mesh_t msg;
  msg.utime = 1700000000000000;
  msg.seq = 42;
  msg.kind = vdeform::mesh_t::KIND_LIVE;
  msg.num_vertices = 3;
  msg.num_triangles = 1;
  msg.encoding = vdeform::mesh_t::ENCODING_DRACO;
  msg.data = {1, 2, 3, 0, 255};
  msg.data_size = 5;
  for (int i = 0; i < 3; ++i) {
    msg.bbox_min[i] = -0.5f * (i + 1);
    msg.bbox_max[i] = 0.25f * (i + 1);
  }
  return msg;
}

TEST(WebProtocolTest, MeshFrameIsMagicLengthHeaderAndTheDracoBytesUnchanged) {
  const vdeform::mesh_t msg = SampleMesh();
  StatusOr<std::string> frame = MeshFrame(msg, "CAM_A");
  ASSERT_TRUE(frame.ok()) << frame.status().ToString();
  ASSERT_GE(frame->size(), 8u);
  EXPECT_EQ(frame->substr(0, 4), "VDM1");
  uint32_t length = 0;
  for (int i = 0; i < 4; ++i) length |= uint32_t(static_cast<uint8_t>((*frame)[4 + i])) << (8 * i);
  ASSERT_EQ(frame->size(), 8 + length + msg.data.size());
  const std::string header = frame->substr(8, length);
  EXPECT_EQ(header,
            "{\"type\":\"mesh\",\"stream\":\"CAM_A\",\"kind\":\"live\",\"seq\":42,\"utime\":1700000000000000,"
            "\"vertices\":3,\"triangles\":1,\"bbox\":[-0.5,-1,-1.5,0.25,0.5,0.75]}");
  EXPECT_EQ(std::memcmp(frame->data() + 8 + length, msg.data.data(), msg.data.size()), 0);
}

TEST(WebProtocolTest, MeshFrameRefusesWhatAPageCannotUse) {
  vdeform::mesh_t raw = SampleMesh();
  raw.encoding = vdeform::mesh_t::ENCODING_RAW;
  EXPECT_EQ(MeshFrame(raw, "").status().code(), StatusCode::kInvalidArgument);
  vdeform::mesh_t kind = SampleMesh();
  kind.kind = 7;
  EXPECT_FALSE(MeshFrame(kind, "").ok());
  vdeform::mesh_t sizes = SampleMesh();
  sizes.data_size = 6;
  EXPECT_FALSE(MeshFrame(sizes, "").ok());
  vdeform::mesh_t negative = SampleMesh();
  negative.num_vertices = -1;
  EXPECT_FALSE(MeshFrame(negative, "").ok());
  vdeform::mesh_t canonical = SampleMesh();
  canonical.kind = vdeform::mesh_t::KIND_CANONICAL;
  StatusOr<std::string> frame = MeshFrame(canonical, "");
  ASSERT_TRUE(frame.ok());
  EXPECT_NE(frame->find("\"kind\":\"canonical\""), std::string::npos);
}

TEST(WebProtocolTest, JsonStringEscapesAndReplacesInvalidUtf8) {
  EXPECT_EQ(JsonString("a\"b\\c\n\t\x01"), "\"a\\\"b\\\\c\\n\\t\\u0001\"");
  EXPECT_EQ(JsonString("caf\xc3\xa9"), "\"caf\xc3\xa9\"");
  // A lone continuation byte, an overlong '/', a truncated sequence and a UTF-16 surrogate.
  EXPECT_EQ(JsonString("x\x80y"), "\"x\\ufffdy\"");
  EXPECT_EQ(JsonString("\xc0\xaf"), "\"\\ufffd\\ufffd\"");
  EXPECT_EQ(JsonString("\xe2\x82"), "\"\\ufffd\\ufffd\"");
  EXPECT_EQ(JsonString("\xed\xa0\x80"), "\"\\ufffd\\ufffd\\ufffd\"");
  EXPECT_EQ(JsonNumber(std::numeric_limits<double>::quiet_NaN()), "null");
  EXPECT_EQ(JsonNumber(INFINITY), "null");
  EXPECT_EQ(JsonNumber(2.5), "2.5");
}

TEST(WebProtocolTest, StatusJsonCarriesCountersStagesAndReasonsBoundedByTheirArrays) {
  vdeform::server_status_t s{};
  s.state = vdeform::server_status_t::STATE_TRACKING;
  s.message = "pthread \"cpu\"";
  s.frames_processed = 17;
  s.frames_dropped = 2;
  s.fps = 4.5f;
  s.latency_ms_p50 = std::numeric_limits<float>::quiet_NaN();
  s.num_reject_reasons = 5;  // more than the arrays hold: only the one present is written
  s.reject_reason = {"malformed_message"};
  s.reject_count = {3};
  s.num_stages = 2;
  s.stage_name = {"icp", "fuse"};
  s.stage_ms_last = {1.5f, 2.0f};
  s.stage_ms_mean = {1.25f, 2.5f};
  const std::string json = StatusJson(s, "");
  EXPECT_EQ(json.rfind("{\"type\":\"status\",\"stream\":\"\",\"state\":\"TRACKING\",\"message\":\"pthread \\\"cpu\\\"\"", 0),
            0u)
      << json;
  EXPECT_NE(json.find("\"frames_processed\":17"), std::string::npos);
  EXPECT_NE(json.find("\"frames_dropped\":2"), std::string::npos);
  EXPECT_NE(json.find("\"fps\":4.5"), std::string::npos);
  EXPECT_NE(json.find("\"latency_ms_p50\":null"), std::string::npos);
  EXPECT_NE(json.find("\"reject_reasons\":{\"malformed_message\":3}"), std::string::npos);
  EXPECT_NE(json.find("\"stages\":[{\"name\":\"icp\",\"last_ms\":1.5,\"mean_ms\":1.25},"
                      "{\"name\":\"fuse\",\"last_ms\":2,\"mean_ms\":2.5}]}"),
            std::string::npos)
      << json;
  EXPECT_EQ(StreamsJson({"", "CAM_B"}), "{\"type\":\"streams\",\"streams\":[\"\",\"CAM_B\"]}");
}

TEST(WebProtocolTest, APageMayOnlyRequestMeshesAndPickAStream) {
  StatusOr<ClientCommand> request = ParseClientCommand("request_mesh");
  ASSERT_TRUE(request.ok());
  EXPECT_EQ(request->kind, ClientCommand::Kind::kRequestMesh);
  StatusOr<ClientCommand> stream = ParseClientCommand("stream CAM_2");
  ASSERT_TRUE(stream.ok());
  EXPECT_EQ(stream->kind, ClientCommand::Kind::kSelectStream);
  EXPECT_EQ(stream->stream, "CAM_2");
  StatusOr<ClientCommand> default_stream = ParseClientCommand("stream ");
  ASSERT_TRUE(default_stream.ok());
  EXPECT_EQ(default_stream->stream, "");
  for (const char* bad : {"", "reset", "request_mesh ", "REQUEST_MESH", "stream a/b", "stream ../x", "snapshot /etc"})
    EXPECT_EQ(ParseClientCommand(bad).status().code(), StatusCode::kInvalidArgument) << bad;
  EXPECT_FALSE(ParseClientCommand("stream " + std::string(65, 'A')).ok());
  EXPECT_FALSE(ParseClientCommand(std::string(kMaxClientMessageBytes + 1, 'x')).ok());
}

TEST(WebProtocolTest, TokensFromQueryHeaderOrCookieComparedExactly) {
  EXPECT_EQ(RequestToken("/?a=1&token=abc%2Dd", "", "").value_or(""), "abc-d");
  EXPECT_EQ(RequestToken("/ws", "Bearer  tok123 ", "").value_or(""), "tok123");
  EXPECT_EQ(RequestToken("/app.js", "", "x=1; vdeform_token=cookie99").value_or(""), "cookie99");
  EXPECT_FALSE(RequestToken("/app.js", "Basic abc", "other=1").has_value());
  EXPECT_FALSE(RequestToken("/?token=%zz", "", "").has_value());
  EXPECT_FALSE(RequestToken("/?token=%4", "", "").has_value());
  EXPECT_EQ(TargetPath("/vendor/a.js?token=x"), "/vendor/a.js");
  EXPECT_TRUE(TokenMatches("0123456789abcdef", "0123456789abcdef"));
  EXPECT_FALSE(TokenMatches("0123456789abcdef", "0123456789abcdeg"));
  EXPECT_FALSE(TokenMatches("0123456789abcdef", "0123456789abcde"));
  EXPECT_FALSE(TokenMatches("", ""));
  EXPECT_TRUE(ValidateToken("0123456789abcdef").ok());
  EXPECT_FALSE(ValidateToken("short").ok());
  EXPECT_FALSE(ValidateToken("0123456789abcdef;x=y").ok());
  EXPECT_FALSE(ValidateToken(std::string(257, 'a')).ok());
}

TEST(WebProtocolTest, MimeTypesOfThePageFiles) {
  EXPECT_STREQ(MimeType("/index.html"), "text/html; charset=utf-8");
  EXPECT_STREQ(MimeType("/vendor/three/build/three.module.js"), "text/javascript; charset=utf-8");
  EXPECT_STREQ(MimeType("/x/draco_decoder.wasm"), "application/wasm");
  EXPECT_STREQ(MimeType("/LICENSE"), "application/octet-stream");
}

TEST(WebOptionsTest, DefaultsFlagsAndBounds) {
  StatusOr<WebOptions> defaults = ParseWebArgs({});
  ASSERT_TRUE(defaults.ok());
  EXPECT_EQ(defaults->server.bind, "127.0.0.1");
  EXPECT_EQ(defaults->server.port, 8080);
  EXPECT_EQ(defaults->server.max_clients, 16);
  StatusOr<WebOptions> set = ParseWebArgs({"--bind", "0.0.0.0", "--port=9000", "--max-clients", "3"});
  ASSERT_TRUE(set.ok());
  EXPECT_EQ(set->server.bind, "0.0.0.0");
  EXPECT_EQ(set->server.port, 9000);
  EXPECT_EQ(set->server.max_clients, 3);
  EXPECT_FALSE(ParseWebArgs({"--port", "70000"}).ok());
  EXPECT_FALSE(ParseWebArgs({"--max-clients", "0"}).ok());
  EXPECT_FALSE(ParseWebArgs({"--bind", "not-an-address"}).ok());
  EXPECT_FALSE(ParseWebArgs({"--token-file", ""}).ok());
  EXPECT_FALSE(ParseWebArgs({"--frobnicate"}).ok());
  StatusOr<WebOptions> help = ParseWebArgs({"--help"});
  ASSERT_TRUE(help.ok());
  EXPECT_TRUE(help->help);
  for (const char* flag : {"--bind", "--port", "--token-file", "--max-clients", "--web-root", "--lcm-url"})
    EXPECT_NE(WebHelpText().find(flag), std::string::npos) << flag;
}

}  // namespace
}  // namespace vd
