// HMAC-SHA256 of control commands, frames and the server's output (meshes, status): the RFC 4231
// vectors, sign/verify, tampering with every field (for the output: every bit of the wire bytes),
// no MAC valid across kinds, key files (control keys; frame key files with one or per-source keys;
// the output key file with one key).
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <set>

#include <gtest/gtest.h>

#include "vd/common/auth.h"
#include "vd/common/messages.h"

namespace vd {
namespace {

TEST(AuthTest, HmacMatchesRfc4231) {
  // RFC 4231 test case 2.
  EXPECT_EQ(ToHex(HmacSha256("Jefe", "what do ya want for nothing?")),
            "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843");
  // Test case 1: 20 bytes of 0x0b, "Hi There".
  EXPECT_EQ(ToHex(HmacSha256(std::string(20, '\x0b'), "Hi There")),
            "b0344c61d8db38535ca8afceaf0bf12b881dc200c9833da726e9376c2e32cff7");
  // FIPS 180-2: SHA-256("abc").
  EXPECT_EQ(ToHex(Sha256("abc", 3)), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

vdeform::control_t Command() {
  vdeform::control_t m{};
  m.utime = 1764633600000000;
  m.command = vdeform::control_t::COMMAND_SAVE_SNAPSHOT;
  m.path = "run1";
  m.sender = "tester";
  m.auth_size = 0;
  return m;
}

TEST(AuthTest, SignedCommandsVerifyAndAnyChangeIsCaught) {
  const std::string key = "0123456789abcdef0123";
  vdeform::control_t m = Command();
  EXPECT_EQ(VerifyControl(key, m).code(), StatusCode::kPermissionDenied) << "unsigned";
  SignControl(key, &m);
  ASSERT_EQ(m.auth_size, 32);
  EXPECT_TRUE(VerifyControl(key, m).ok());
  EXPECT_FALSE(VerifyControl(key + "x", m).ok()) << "another key";
  auto tampered = [&](auto change) {
    vdeform::control_t t = m;
    change(&t);
    return VerifyControl(key, t).ok();
  };
  EXPECT_FALSE(tampered([](vdeform::control_t* t) { t->path = "../etc"; }));
  EXPECT_FALSE(tampered([](vdeform::control_t* t) { t->command = vdeform::control_t::COMMAND_RESET; }));
  EXPECT_FALSE(tampered([](vdeform::control_t* t) { t->utime += 1; }));
  EXPECT_FALSE(tampered([](vdeform::control_t* t) { t->sender = "other"; }));
  EXPECT_FALSE(tampered([](vdeform::control_t* t) { t->auth[31] ^= 1; }));
  EXPECT_FALSE(tampered([](vdeform::control_t* t) {
    t->auth.pop_back();
    t->auth_size = 31;
  }));
  // Length prefixes: moving bytes between path and sender changes the MAC.
  vdeform::control_t a = Command(), b = Command();
  a.path = "ab";
  a.sender = "c";
  b.path = "a";
  b.sender = "bc";
  EXPECT_NE(ControlAuthBytes(a), ControlAuthBytes(b));
}

TEST(AuthTest, KeyFilesMustExistBePrivateAndLongEnough) {
  const std::string dir = testing::TempDir() + "/vd_auth_keys";
  std::filesystem::create_directories(dir);
  auto write = [&](const std::string& name, const std::string& text, mode_t mode) {
    const std::string p = dir + "/" + name;
    std::ofstream(p, std::ios::binary | std::ios::trunc) << text;
    chmod(p.c_str(), mode);
    return p;
  };
  EXPECT_EQ(ReadControlKey(dir + "/missing").status().code(), StatusCode::kNotFound);
  EXPECT_EQ(ReadControlKey(write("open", "0123456789abcdef\n", 0644)).status().code(), StatusCode::kPermissionDenied);
  EXPECT_EQ(ReadControlKey(write("short", "0123456789\n", 0600)).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(ReadControlKey(dir).status().code(), StatusCode::kInvalidArgument) << "a directory";
  auto key = ReadControlKey(write("good", "0123456789abcdef-key\n\n", 0600));
  ASSERT_TRUE(key.ok()) << key.status().ToString();
  EXPECT_EQ(*key, "0123456789abcdef-key") << "trailing newlines are not part of the key";
}

vdeform::rgbd_frame_t FrameMessage() {
  vdeform::rgbd_frame_t m{};
  m.utime = 1764633600000000;
  m.seq = 7;
  m.epoch = 0x1234567890abcdefLL;
  m.source_id = "cam";
  m.fx = m.fy = 500.f;
  m.cx = 2.f;
  m.cy = 1.5f;
  m.width = 4;
  m.height = 3;
  m.depth_scale = 1000.f;
  m.depth_encoding = vdeform::rgbd_frame_t::DEPTH_RAW16;
  m.depth_data.assign(4 * 3 * 2, 9);
  m.depth_size = int32_t(m.depth_data.size());
  m.color_encoding = vdeform::rgbd_frame_t::COLOR_RAW_BGR8;
  m.color_data.assign(4 * 3 * 3, 200);
  m.color_size = int32_t(m.color_data.size());
  m.auth_size = 0;
  return m;
}

const std::string kFrameKey(32, '\x5a');

TEST(AuthTest, SignedFramesVerifyAndEveryFieldIsCovered) {
  vdeform::rgbd_frame_t m = FrameMessage();
  const Status unsigned_status = VerifyFrame(kFrameKey, m);
  EXPECT_EQ(unsigned_status.code(), StatusCode::kPermissionDenied);
  EXPECT_NE(unsigned_status.message().find("auth_size 0"), std::string::npos) << unsigned_status.message();
  ASSERT_TRUE(SignFrame(kFrameKey, &m).ok());
  ASSERT_EQ(m.auth_size, 32);
  ASSERT_EQ(m.auth.size(), 32u);
  EXPECT_TRUE(VerifyFrame(kFrameKey, m).ok());
  EXPECT_FALSE(VerifyFrame(std::string(32, '\x5b'), m).ok()) << "another key";
  // The same frame signed again gives the same MAC (a re-sent frame is a duplicate, not a forgery).
  vdeform::rgbd_frame_t again = m;
  ASSERT_TRUE(SignFrame(kFrameKey, &again).ok());
  EXPECT_EQ(again.auth, m.auth);
  using Change = void (*)(vdeform::rgbd_frame_t*);
  const std::pair<const char*, Change> changes[] = {
      {"utime", [](vdeform::rgbd_frame_t* t) { t->utime += 1; }},
      {"seq", [](vdeform::rgbd_frame_t* t) { t->seq += 1; }},
      {"epoch", [](vdeform::rgbd_frame_t* t) { t->epoch ^= 1; }},
      {"source_id", [](vdeform::rgbd_frame_t* t) { t->source_id = "cam2"; }},
      {"fx", [](vdeform::rgbd_frame_t* t) { t->fx = 501.f; }},
      {"fy", [](vdeform::rgbd_frame_t* t) { t->fy = 499.f; }},
      {"cx", [](vdeform::rgbd_frame_t* t) { t->cx = 2.5f; }},
      {"cy", [](vdeform::rgbd_frame_t* t) { t->cy = 1.f; }},
      {"width", [](vdeform::rgbd_frame_t* t) { t->width = 3; }},
      {"height", [](vdeform::rgbd_frame_t* t) { t->height = 4; }},
      {"depth_scale", [](vdeform::rgbd_frame_t* t) { t->depth_scale = 5000.f; }},
      {"depth_encoding", [](vdeform::rgbd_frame_t* t) { t->depth_encoding = vdeform::rgbd_frame_t::DEPTH_PNG16; }},
      {"color_encoding", [](vdeform::rgbd_frame_t* t) { t->color_encoding = vdeform::rgbd_frame_t::COLOR_JPEG; }},
      {"depth byte", [](vdeform::rgbd_frame_t* t) { t->depth_data[5] ^= 0x80; }},
      {"last colour byte", [](vdeform::rgbd_frame_t* t) { t->color_data.back() ^= 1; }},
      // One byte moved from the end of depth to the start of colour: same bytes, other split.
      {"depth/colour split", [](vdeform::rgbd_frame_t* t) {
         t->color_data.insert(t->color_data.begin(), t->depth_data.back());
         t->depth_data.pop_back();
         t->depth_size -= 1;
         t->color_size += 1;
       }},
      {"auth byte", [](vdeform::rgbd_frame_t* t) { t->auth[0] ^= 1; }},
      {"auth length", [](vdeform::rgbd_frame_t* t) {
         t->auth.pop_back();
         t->auth_size = 31;
       }},
  };
  for (const auto& [what, change] : changes) {
    vdeform::rgbd_frame_t t = m;
    change(&t);
    EXPECT_EQ(VerifyFrame(kFrameKey, t).code(), StatusCode::kPermissionDenied) << what;
  }
}

TEST(AuthTest, RandomEpochsAreNonZeroAndDiffer) {
  std::set<int64_t> seen;
  for (int i = 0; i < 100; ++i) {
    const int64_t e = RandomEpoch();
    EXPECT_NE(e, 0);
    seen.insert(e);
  }
  EXPECT_EQ(seen.size(), 100u);
}

const std::string kHexA = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff";
const std::string kHexB = "FFEEDDCCBBAA99887766554433221100FFEEDDCCBBAA99887766554433221100";

TEST(AuthTest, FrameKeyFilesHoldOneKeyOrOnePerSource) {
  auto one = FrameKeys::Parse("# the key of every capture node\n\n  " + kHexA + "  \n", "k");
  ASSERT_TRUE(one.ok()) << one.status().ToString();
  EXPECT_FALSE(one->per_source());
  EXPECT_EQ(one->size(), 1u);
  ASSERT_NE(one->For("anything"), nullptr);
  const std::string half("\x00\x11\x22\x33\x44\x55\x66\x77\x88\x99\xaa\xbb\xcc\xdd\xee\xff", 16);
  EXPECT_EQ(*one->For("anything"), half + half);
  auto per = FrameKeys::Parse("left " + kHexA + "\nright\t" + kHexB + "\n", "k");
  ASSERT_TRUE(per.ok()) << per.status().ToString();
  EXPECT_TRUE(per->per_source());
  EXPECT_EQ(per->size(), 2u);
  ASSERT_NE(per->For("left"), nullptr);
  ASSERT_NE(per->For("right"), nullptr);
  EXPECT_EQ(per->For("left")->size(), 32u);
  EXPECT_EQ(uint8_t((*per->For("right"))[0]), 0xff) << "upper-case hex";
  EXPECT_NE(*per->For("left"), *per->For("right"));
  EXPECT_EQ(per->For("lef"), nullptr) << "exact ids";
}

TEST(AuthTest, BadFrameKeyFilesNameTheFileAndLine) {
  struct Case {
    std::string text, expected;
  } cases[] = {
      {"", "frame key file 'keys.txt' holds no key"},
      {"# only a comment\n\n", "frame key file 'keys.txt' holds no key"},
      {"\n" + kHexA.substr(2) + "\n", "'keys.txt' line 2: the key has 62 characters; 64 hex digits"},
      {kHexA + "00\n", "'keys.txt' line 1: the key has 66 characters"},
      {"cam " + kHexA.substr(0, 63) + "g\n", "'keys.txt' line 1: the key is not hexadecimal (character 64)"},
      {"a " + kHexA + "\nb " + kHexB + "\na " + kHexB + "\n",
       "'keys.txt' line 3: source 'a' already has a key on line 1"},
      {kHexA + "\n" + kHexB + "\n", "'keys.txt' line 2: a second key for every source (the first is on line 1)"},
      {"a " + kHexA + "\n" + kHexB + "\n", "'keys.txt' line 2: a key for every source among SOURCE_ID KEY lines"},
      {kHexA + "\na " + kHexB + "\n", "'keys.txt' line 2: SOURCE_ID KEY after the key for every source on line 1"},
      {"a b " + kHexA + "\n", "'keys.txt' line 1: expected KEY or SOURCE_ID KEY, got 3 fields"},
  };
  for (const Case& c : cases) {
    auto keys = FrameKeys::Parse(c.text, "keys.txt");
    ASSERT_FALSE(keys.ok()) << c.text;
    EXPECT_EQ(keys.status().code(), StatusCode::kInvalidArgument) << c.text;
    EXPECT_NE(keys.status().message().find(c.expected), std::string::npos)
        << "got: " << keys.status().message() << "\nexpected: " << c.expected;
  }
}

TEST(AuthTest, FrameKeyFilesMustExistAndBePrivate) {
  const std::string dir = testing::TempDir() + "/vd_frame_keys";
  std::filesystem::create_directories(dir);
  const std::string path = dir + "/frame.key";
  std::ofstream(path, std::ios::trunc) << "cam " << kHexA << "\n";
  chmod(path.c_str(), 0640);
  auto open = ReadFrameKeys(path);
  EXPECT_EQ(open.status().code(), StatusCode::kPermissionDenied);
  EXPECT_NE(open.status().message().find(path), std::string::npos);
  chmod(path.c_str(), 0600);
  auto keys = ReadFrameKeys(path);
  ASSERT_TRUE(keys.ok()) << keys.status().ToString();
  EXPECT_NE(keys->For("cam"), nullptr);
  auto missing = ReadFrameKeys(dir + "/missing.key");
  EXPECT_EQ(missing.status().code(), StatusCode::kNotFound);
  EXPECT_NE(missing.status().message().find("frame key file '" + dir + "/missing.key'"), std::string::npos);
}

const std::string kOutputKey(32, '\x3c');

vdeform::mesh_t MeshMessage() {
  vdeform::mesh_t m{};
  m.utime = 1764633600000000;
  m.seq = 41;
  m.kind = vdeform::mesh_t::KIND_LIVE;
  m.num_vertices = 1200;
  m.num_triangles = 2300;
  m.encoding = vdeform::mesh_t::ENCODING_DRACO;
  // Sign and Verify do not decode the payload: any bytes stand for the Draco stream.
  for (int i = 0; i < 24; ++i) m.data.push_back(uint8_t(31 * i + 7));
  m.data_size = int32_t(m.data.size());
  for (int a = 0; a < 3; ++a) {
    m.bbox_min[a] = -0.25f * float(a + 1);
    m.bbox_max[a] = 0.5f * float(a + 1);
  }
  m.epoch = 0x1234567890abcdefLL;
  m.out_seq = 77;
  m.auth_size = 0;
  return m;
}

vdeform::server_status_t StatusMessage() {
  vdeform::server_status_t s{};
  s.utime = 1764633600000123;
  s.state = vdeform::server_status_t::STATE_TRACKING;
  s.message = "tracking on pthread-cpu";
  s.frames_received = 10;
  s.frames_processed = 9;
  s.frames_rejected = 1;
  s.reject_reason = {"bad_signature"};
  s.reject_count = {1};
  s.num_reject_reasons = 1;
  s.last_processed_seq = 8;
  s.last_source_id = "camA";
  s.last_epoch = 555;
  s.stage_name = {"preprocess", "track"};
  s.stage_ms_last = {1.5f, 20.f};
  s.stage_ms_mean = {1.25f, 19.f};
  s.num_stages = 2;
  s.fps = 9.5f;
  s.model_frames = 9;
  s.checkpoint_message = "none";
  s.epoch = 0x0fedcba987654321LL;
  s.out_seq = 78;
  s.auth_size = 0;
  return s;
}

template <typename Msg>
std::vector<uint8_t> Wire(const Msg& msg) {
  std::vector<uint8_t> out(size_t(msg.getEncodedSize()));
  EXPECT_EQ(msg.encode(out.data(), 0, int(out.size())), int(out.size()));
  return out;
}

// Every single-bit change of a signed message's wire bytes either no longer decodes or decodes to
// a message that does not verify: each field, the payload, the counts and the MAC are covered.
// (An accepted message re-encodes to its own bytes, so one that decodes differs in some field.)
// Returns how many of the changed messages decoded, which must be most of them for the test to
// mean something.
template <typename Msg>
size_t ExpectEveryBitCovered(const Msg& signed_msg, Status (*verify)(const std::string&, const Msg&)) {
  const std::vector<uint8_t> wire = Wire(signed_msg);
  size_t decoded = 0;
  for (size_t byte = 0; byte < wire.size(); ++byte) {
    for (int bit = 0; bit < 8; ++bit) {
      std::vector<uint8_t> changed = wire;
      changed[byte] ^= uint8_t(1u << bit);
      StatusOr<Msg> msg = DecodeLcm<Msg>(changed.data(), changed.size());
      if (!msg.ok()) continue;
      ++decoded;
      EXPECT_EQ(verify(kOutputKey, *msg).code(), StatusCode::kPermissionDenied) << "byte " << byte << " bit " << bit;
    }
  }
  return decoded;
}

TEST(AuthTest, SignedMeshesVerifyAndEveryBitIsCovered) {
  vdeform::mesh_t m = MeshMessage();
  const Status unsigned_status = VerifyMesh(kOutputKey, m);
  EXPECT_EQ(unsigned_status.code(), StatusCode::kPermissionDenied);
  EXPECT_NE(unsigned_status.message().find("mesh carries no HMAC-SHA256 (auth_size 0)"), std::string::npos)
      << unsigned_status.message();
  ASSERT_TRUE(SignMesh(kOutputKey, &m).ok());
  ASSERT_EQ(m.auth_size, 32);
  ASSERT_EQ(m.auth.size(), 32u);
  EXPECT_TRUE(VerifyMesh(kOutputKey, m).ok());
  EXPECT_EQ(VerifyMesh(std::string(32, '\x3d'), m).code(), StatusCode::kPermissionDenied) << "another key";
  // Signing again gives the same MAC (the auth field itself is not covered).
  vdeform::mesh_t again = m;
  ASSERT_TRUE(SignMesh(kOutputKey, &again).ok());
  EXPECT_EQ(again.auth, m.auth);
  // The fields a forger would change, by name; then every bit.
  using Change = void (*)(vdeform::mesh_t*);
  const std::pair<const char*, Change> changes[] = {
      {"seq", [](vdeform::mesh_t* t) { t->seq += 1; }},
      {"epoch", [](vdeform::mesh_t* t) { t->epoch ^= 1; }},
      {"out_seq", [](vdeform::mesh_t* t) { t->out_seq += 1; }},
      {"kind", [](vdeform::mesh_t* t) { t->kind = vdeform::mesh_t::KIND_CANONICAL; }},
      {"last data byte", [](vdeform::mesh_t* t) { t->data.back() ^= 1; }},
      {"bbox", [](vdeform::mesh_t* t) { t->bbox_max[2] = 9.f; }},
  };
  for (const auto& [what, change] : changes) {
    vdeform::mesh_t t = m;
    change(&t);
    EXPECT_EQ(VerifyMesh(kOutputKey, t).code(), StatusCode::kPermissionDenied) << what;
  }
  const size_t decoded = ExpectEveryBitCovered(m, &VerifyMesh);
  EXPECT_GT(decoded, Wire(m).size() * 8 / 2) << "most single-bit changes still decode";
}

TEST(AuthTest, SignedStatusVerifiesAndEveryBitIsCovered) {
  vdeform::server_status_t s = StatusMessage();
  const Status unsigned_status = VerifyStatus(kOutputKey, s);
  EXPECT_EQ(unsigned_status.code(), StatusCode::kPermissionDenied);
  EXPECT_NE(unsigned_status.message().find("status carries no HMAC-SHA256 (auth_size 0)"), std::string::npos)
      << unsigned_status.message();
  ASSERT_TRUE(SignStatus(kOutputKey, &s).ok());
  ASSERT_EQ(s.auth_size, 32);
  EXPECT_TRUE(VerifyStatus(kOutputKey, s).ok());
  EXPECT_EQ(VerifyStatus(std::string(32, '\x3d'), s).code(), StatusCode::kPermissionDenied) << "another key";
  vdeform::server_status_t again = s;
  ASSERT_TRUE(SignStatus(kOutputKey, &again).ok());
  EXPECT_EQ(again.auth, s.auth);
  using Change = void (*)(vdeform::server_status_t*);
  const std::pair<const char*, Change> changes[] = {
      {"last_processed_seq", [](vdeform::server_status_t* t) { t->last_processed_seq += 1; }},
      {"last_source_id", [](vdeform::server_status_t* t) { t->last_source_id = "camB"; }},
      {"last_epoch", [](vdeform::server_status_t* t) { t->last_epoch += 1; }},
      {"epoch", [](vdeform::server_status_t* t) { t->epoch ^= 1; }},
      {"out_seq", [](vdeform::server_status_t* t) { t->out_seq += 1; }},
      {"checkpoint_message", [](vdeform::server_status_t* t) { t->checkpoint_message += "!"; }},
  };
  for (const auto& [what, change] : changes) {
    vdeform::server_status_t t = s;
    change(&t);
    EXPECT_EQ(VerifyStatus(kOutputKey, t).code(), StatusCode::kPermissionDenied) << what;
  }
  // A status whose arrays disagree with their counts (a programmer's error; LCM's encode would read
  // past the vector) is neither signed nor verified.
  vdeform::server_status_t inconsistent = s;
  inconsistent.num_stages = 3;
  EXPECT_EQ(SignStatus(kOutputKey, &inconsistent).code(), StatusCode::kInternal);
  EXPECT_EQ(inconsistent.auth_size, 0);
  inconsistent = s;
  inconsistent.reject_count.push_back(5);
  EXPECT_EQ(VerifyStatus(kOutputKey, inconsistent).code(), StatusCode::kInternal);
  const size_t decoded = ExpectEveryBitCovered(s, &VerifyStatus);
  EXPECT_GT(decoded, Wire(s).size() * 8 / 2) << "most single-bit changes still decode";
}

// A MAC made for one kind of message never verifies as another kind: each starts from its own
// domain tag. The status carries the mesh's MAC and the mesh the status's, with the fields they
// share (utime, epoch, out_seq) equal.
TEST(AuthTest, OutputSignaturesDoNotVerifyAcrossKinds) {
  vdeform::mesh_t m = MeshMessage();
  vdeform::server_status_t s = StatusMessage();
  s.utime = m.utime;
  s.epoch = m.epoch;
  s.out_seq = m.out_seq;
  ASSERT_TRUE(SignMesh(kOutputKey, &m).ok());
  ASSERT_TRUE(SignStatus(kOutputKey, &s).ok());
  ASSERT_NE(m.auth, s.auth);
  vdeform::server_status_t status_with_mesh_mac = s;
  status_with_mesh_mac.auth = m.auth;
  EXPECT_EQ(VerifyStatus(kOutputKey, status_with_mesh_mac).code(), StatusCode::kPermissionDenied);
  vdeform::mesh_t mesh_with_status_mac = m;
  mesh_with_status_mac.auth = s.auth;
  EXPECT_EQ(VerifyMesh(kOutputKey, mesh_with_status_mac).code(), StatusCode::kPermissionDenied);
  // Nor does a frame's MAC under the same key (an operator may reuse one key file for both).
  vdeform::rgbd_frame_t f = FrameMessage();
  ASSERT_TRUE(SignFrame(kOutputKey, &f).ok());
  mesh_with_status_mac.auth = f.auth;
  EXPECT_EQ(VerifyMesh(kOutputKey, mesh_with_status_mac).code(), StatusCode::kPermissionDenied);
}

TEST(AuthTest, OutputKeyFilesHoldOneKey) {
  auto key = ParseOutputKey("# the server's output key\n" + kHexA + "\n", "out.key");
  ASSERT_TRUE(key.ok()) << key.status().ToString();
  EXPECT_EQ(key->size(), 32u);
  EXPECT_EQ(uint8_t((*key)[1]), 0x11);
  auto per_source = ParseOutputKey("camA " + kHexA + "\n", "out.key");
  ASSERT_FALSE(per_source.ok());
  EXPECT_EQ(per_source.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(per_source.status().message().find("output key file 'out.key' has SOURCE_ID KEY lines"),
            std::string::npos)
      << per_source.status().message();
  auto short_key = ParseOutputKey(kHexA.substr(1) + "\n", "out.key");
  ASSERT_FALSE(short_key.ok());
  EXPECT_NE(short_key.status().message().find("output key file 'out.key' line 1: the key has 63 characters"),
            std::string::npos)
      << short_key.status().message();
  EXPECT_FALSE(ParseOutputKey("", "out.key").ok());

  const std::string dir = testing::TempDir() + "/vd_output_key";
  std::filesystem::create_directories(dir);
  const std::string path = dir + "/output.key";
  std::ofstream(path, std::ios::trunc) << kHexB << "\n";
  chmod(path.c_str(), 0644);
  auto open = ReadOutputKey(path);
  EXPECT_EQ(open.status().code(), StatusCode::kPermissionDenied);
  EXPECT_NE(open.status().message().find("output key file '" + path + "' is readable by group or others"),
            std::string::npos)
      << open.status().message();
  chmod(path.c_str(), 0600);
  auto read = ReadOutputKey(path);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  EXPECT_EQ(uint8_t((*read)[0]), 0xff);
  // A program's flag: the file's key, or no key without the flag.
  EXPECT_EQ(OutputKeyFromFlag(path).value(), *read);
  EXPECT_EQ(OutputKeyFromFlag("").value(), "");
  EXPECT_EQ(OutputKeyFromFlag(dir + "/missing.key").status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace vd
