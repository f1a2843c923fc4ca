// FrameGate: what the node accepts from the network. Sequence numbers (duplicates, reordering,
// losses, client restarts, jumps), source filtering, signed frames, authenticated control with
// replay protection, and the rate limits (frames per source, control per sender, REQUEST_MESH)
// on a clock the test moves.
#include <gtest/gtest.h>

#include "gate.h"
#include "vd/capture/synthetic.h"

namespace vd {
namespace {

// A clock the test moves.
struct FakeClock {
  int64_t now_us = 1'000'000;
  MonotonicClock fn() {
    return [this] { return now_us; };
  }
};

class GateTest : public ::testing::Test {
 protected:
  void SetUp() override {
    SyntheticOptions so;
    so.noise = false;
    so.width = 160;
    so.height = 120;
    auto scene = MakeSyntheticScene("tube", so);
    ASSERT_TRUE(scene.ok()) << scene.status().ToString();
    frame_ = (*scene)->Render(0);
  }
  // A frame message of `source`; signed under `key` unless it is empty.
  vdeform::rgbd_frame_t Message(const std::string& source, int64_t seq, int64_t utime, int64_t epoch = 1,
                                const std::string& key = "") {
    RgbdFrame f = frame_;
    f.source_id = source;
    f.seq = seq;
    f.utime = utime;
    auto m = FrameToMessage(f, FrameEncodeOptions());
    EXPECT_TRUE(m.ok());
    m->epoch = epoch;
    if (!key.empty()) {
      EXPECT_TRUE(SignFrame(key, &*m).ok());
    }
    return *m;
  }
  static std::vector<uint8_t> Wire(const vdeform::rgbd_frame_t& m) {
    std::vector<uint8_t> b(m.getEncodedSize());
    m.encode(b.data(), 0, int(b.size()));
    return b;
  }
  std::vector<uint8_t> Bytes(const std::string& source, int64_t seq, int64_t utime, bool corrupt = false) {
    vdeform::rgbd_frame_t m = Message(source, seq, utime);
    if (corrupt) m.width = 7;
    return Wire(m);
  }
  static FrameDecision Decide(FrameGate* g, const vdeform::rgbd_frame_t& m) {
    const auto b = Wire(m);
    FrameDecision d = g->OnFrame(b.data(), b.size());
    EXPECT_EQ(d.verdict == FrameVerdict::kAccept, d.frame.has_value());
    EXPECT_EQ(d.verdict == FrameVerdict::kRejected, !d.reason.empty()) << d.reason;
    return d;
  }
  FrameVerdict Send(FrameGate* g, const std::string& source, int64_t seq, int64_t utime, bool corrupt = false) {
    const auto b = Bytes(source, seq, utime, corrupt);
    FrameDecision d = g->OnFrame(b.data(), b.size());
    EXPECT_EQ(d.verdict == FrameVerdict::kAccept, d.frame.has_value());
    if (d.frame) {
      EXPECT_EQ(d.frame->seq, seq);
    }
    return d.verdict;
  }
  RgbdFrame frame_;
  FakeClock clock_;
};

TEST_F(GateTest, SequenceNumbersCountDuplicatesReordersLossesAndRestarts) {
  FrameGate g(GateOptions{});
  EXPECT_EQ(Send(&g, "cam", 0, 1000), FrameVerdict::kAccept);
  EXPECT_EQ(Send(&g, "cam", 1, 2000), FrameVerdict::kAccept);
  EXPECT_EQ(Send(&g, "cam", 1, 2000), FrameVerdict::kStale) << "duplicate";
  EXPECT_EQ(Send(&g, "cam", 4, 5000), FrameVerdict::kAccept) << "2 and 3 lost";
  EXPECT_EQ(Send(&g, "cam", 3, 4000), FrameVerdict::kStale) << "3 arrives late";
  EXPECT_EQ(Send(&g, "cam", 2, 3000), FrameVerdict::kStale);
  // Another source has its own sequence.
  EXPECT_EQ(Send(&g, "other", 0, 1500), FrameVerdict::kAccept);
  // The client restarts: seq from 0 again with a newer capture time.
  EXPECT_EQ(Send(&g, "cam", 0, 9000), FrameVerdict::kAccept);
  EXPECT_EQ(Send(&g, "cam", 1, 9100), FrameVerdict::kAccept);
  // A corrupt frame with a high seq is rejected and does not move the sequence.
  EXPECT_EQ(Send(&g, "cam", 100, 9200, true), FrameVerdict::kRejected);
  EXPECT_EQ(Send(&g, "cam", 2, 9300), FrameVerdict::kAccept);
  const GateCounters& c = g.counters();
  EXPECT_EQ(c.received, 11);
  EXPECT_EQ(c.duplicates, 1);
  EXPECT_EQ(c.reordered, 2);
  EXPECT_EQ(c.lost, 0) << "2 and 3 were skipped, then arrived late: not lost";
  EXPECT_EQ(c.source_restarts, 1);
  EXPECT_EQ(c.rejected, 1);
  EXPECT_EQ(c.foreign, 0);
}

// Found by fuzz_server_gate: extreme sequence numbers and times must not overflow the counters.
TEST_F(GateTest, ExtremeSequenceNumbersAndTimesAreHandled) {
  FrameGate g(GateOptions{});
  EXPECT_EQ(Send(&g, "cam", 5, 1000), FrameVerdict::kAccept);
  EXPECT_EQ(Send(&g, "cam", INT64_MIN, 2000), FrameVerdict::kRejected);
  EXPECT_EQ(Send(&g, "cam", 6, -1), FrameVerdict::kRejected);
  EXPECT_EQ(Send(&g, "cam", INT64_MAX, 3000), FrameVerdict::kHeld);
  EXPECT_EQ(Send(&g, "cam", INT64_MAX, 3000), FrameVerdict::kHeld) << "the same number never confirms itself";
  EXPECT_EQ(g.counters().lost, 0) << "a jump beyond max_jump counts no lost frames";
  EXPECT_EQ(g.counters().held, 2);
  EXPECT_EQ(Send(&g, "cam", 6, 3100), FrameVerdict::kAccept);
  GateOptions o;
  o.control_key = "a-sixteen-byte-key!!";
  FrameGate c(o);
  for (int64_t t : {INT64_MIN, INT64_MAX, int64_t(0)}) {
    vdeform::control_t m{};
    m.utime = t;
    m.command = vdeform::control_t::COMMAND_RESET;
    m.sender = "x";
    m.auth_size = 0;
    SignControl(o.control_key, &m);
    std::vector<uint8_t> b(m.getEncodedSize());
    m.encode(b.data(), 0, int(b.size()));
    EXPECT_FALSE(c.OnControl(b.data(), b.size(), INT64_MAX / 2).status.ok()) << t;
  }
}

TEST_F(GateTest, FramesAboveThePixelLimitAreRefusedBeforeDecoding) {
  GateOptions o;
  o.params.max_frame_pixels = 160 * 120 - 1;
  FrameGate g(o);
  const auto b = Bytes("cam", 0, 1);
  FrameDecision d = g.OnFrame(b.data(), b.size());
  EXPECT_EQ(d.verdict, FrameVerdict::kRejected);
  EXPECT_EQ(d.reason, "oversized");
  o.params.max_frame_pixels = 160 * 120;
  FrameGate ok(o);
  EXPECT_EQ(ok.OnFrame(b.data(), b.size()).verdict, FrameVerdict::kAccept);
}

TEST_F(GateTest, OnlyAcceptedSourcesPass) {
  GateOptions o;
  o.accept_sources = {"left", "right"};
  FrameGate g(o);
  EXPECT_EQ(Send(&g, "left", 0, 1), FrameVerdict::kAccept);
  EXPECT_EQ(Send(&g, "right", 0, 1), FrameVerdict::kAccept);
  EXPECT_EQ(Send(&g, "intruder", 0, 1), FrameVerdict::kForeign);
  EXPECT_EQ(Send(&g, "lef", 1, 2), FrameVerdict::kForeign) << "exact ids, not prefixes";
  EXPECT_EQ(g.counters().foreign, 2);
  const std::vector<uint8_t> junk(64, 0x5a);
  EXPECT_EQ(g.OnFrame(junk.data(), junk.size()).verdict, FrameVerdict::kRejected);
}

const std::string kKeyA(32, 'a'), kKeyB(32, 'b');

FrameKeys Keys(const std::string& text) {
  auto keys = FrameKeys::Parse(text, "test");
  EXPECT_TRUE(keys.ok()) << keys.status().ToString();
  return *keys;
}
std::string Hex(const std::string& key) {
  static const char* kHex = "0123456789abcdef";
  std::string s;
  for (unsigned char c : key) s += std::string{kHex[c >> 4], kHex[c & 15]};
  return s;
}

TEST_F(GateTest, WithAFrameKeyOnlyFramesSignedUnderItPass) {
  GateOptions o;
  o.frame_keys = Keys(Hex(kKeyA));
  FrameGate g(o);
  EXPECT_TRUE(g.authenticated_frames());
  const int64_t t = 1764633600000000;
  EXPECT_EQ(Decide(&g, Message("cam", 0, t)).reason, "unsigned");
  EXPECT_EQ(Decide(&g, Message("cam", 0, t, 1, kKeyB)).reason, "bad_signature") << "another key";
  vdeform::rgbd_frame_t altered = Message("cam", 0, t, 1, kKeyA);
  altered.depth_data[100] ^= 1;
  EXPECT_EQ(Decide(&g, altered).reason, "bad_signature") << "payload changed after signing";
  altered = Message("cam", 0, t, 1, kKeyA);
  altered.seq = 1000;
  EXPECT_EQ(Decide(&g, altered).reason, "bad_signature") << "sequence number changed after signing";
  EXPECT_EQ(Decide(&g, Message("cam", 0, t, 1, kKeyA)).verdict, FrameVerdict::kAccept);
  // One key for every source: any id signed under it passes.
  EXPECT_EQ(Decide(&g, Message("other", 0, t, 9, kKeyA)).verdict, FrameVerdict::kAccept);
  const GateCounters& c = g.counters();
  EXPECT_EQ(c.received, 6);
  EXPECT_EQ(c.rejected, 4);
  EXPECT_EQ(c.lost + c.duplicates + c.reordered + c.source_restarts, 0) << "refused frames move no sequence";
}

TEST_F(GateTest, PerSourceKeysBindEachSourceToItsKey) {
  GateOptions o;
  o.frame_keys = Keys("left " + Hex(kKeyA) + "\nright " + Hex(kKeyB) + "\n");
  FrameGate g(o);
  const int64_t t = 1764633600000000;
  EXPECT_EQ(Decide(&g, Message("left", 0, t, 1, kKeyA)).verdict, FrameVerdict::kAccept);
  EXPECT_EQ(Decide(&g, Message("right", 0, t, 2, kKeyB)).verdict, FrameVerdict::kAccept);
  EXPECT_EQ(Decide(&g, Message("right", 1, t + 1, 2, kKeyA)).reason, "bad_signature") << "left's key for right";
  EXPECT_EQ(Decide(&g, Message("intruder", 0, t, 3, kKeyA)).reason, "no_frame_key");
  EXPECT_EQ(g.counters().rejected, 2);
}

// A recorded frame played back: the same (epoch, seq) is a duplicate, and a whole earlier run
// (another epoch with older capture times) is refused as replayed; a real restart (a new epoch
// with newer times) is taken.
TEST_F(GateTest, ReplayedSignedFramesAreRefused) {
  GateOptions o;
  o.frame_keys = Keys(Hex(kKeyA));
  FrameGate g(o);
  const int64_t t = 1764633600000000;
  const vdeform::rgbd_frame_t first_run[] = {Message("cam", 0, t, 11, kKeyA), Message("cam", 1, t + 33000, 11, kKeyA),
                                             Message("cam", 2, t + 66000, 11, kKeyA)};
  for (const auto& m : first_run) EXPECT_EQ(Decide(&g, m).verdict, FrameVerdict::kAccept);
  EXPECT_EQ(Decide(&g, first_run[2]).verdict, FrameVerdict::kStale) << "the same frame again";
  EXPECT_EQ(Decide(&g, first_run[1]).verdict, FrameVerdict::kStale);
  // The client restarts: a new epoch, seq from 0, later capture times.
  EXPECT_EQ(Decide(&g, Message("cam", 0, t + 5'000'000, 22, kKeyA)).verdict, FrameVerdict::kAccept);
  EXPECT_EQ(Decide(&g, Message("cam", 1, t + 5'033'000, 22, kKeyA)).verdict, FrameVerdict::kAccept);
  // The first run played back: every frame refused, the second run goes on.
  for (const auto& m : first_run) {
    const FrameDecision d = Decide(&g, m);
    EXPECT_EQ(d.reason, "replayed") << m.seq;
    EXPECT_NE(d.status.message().find("earlier run"), std::string::npos) << d.status.message();
  }
  EXPECT_EQ(Decide(&g, Message("cam", 2, t + 5'066'000, 22, kKeyA)).verdict, FrameVerdict::kAccept);
  const GateCounters& c = g.counters();
  EXPECT_EQ(c.received, 11);
  EXPECT_EQ(c.duplicates, 2) << "both frames of the current run sent again were received before";
  EXPECT_EQ(c.reordered, 0);
  EXPECT_EQ(c.rejected, 3);
  EXPECT_EQ(c.source_restarts, 1);
  EXPECT_EQ(c.lost, 0);
}

// The finding: one forged frame numbered near 2^62 under the accepted id made every later
// real frame "reordered", and the loss counter grew to ~5e8. Now it is held and dropped when the
// real stream goes on; a real jump (a 20 s outage of a 30 Hz source) is taken after 3 frames.
TEST_F(GateTest, AForgedHugeSequenceNumberNeitherStallsNorInflates) {
  GateOptions o;
  o.accept_sources = {"cam"};
  FrameGate g(o);
  for (int64_t s = 0; s < 5; ++s) EXPECT_EQ(Send(&g, "cam", s, 1000 + s), FrameVerdict::kAccept);
  EXPECT_EQ(Send(&g, "cam", int64_t(1) << 62, 2000), FrameVerdict::kHeld);
  for (int64_t s = 5; s < 10; ++s) EXPECT_EQ(Send(&g, "cam", s, 1000 + s), FrameVerdict::kAccept) << s;
  // A corrupt frame cannot start a held jump either.
  EXPECT_EQ(Send(&g, "cam", 5000, 3000, true), FrameVerdict::kRejected);
  for (int64_t s = 610; s < 613; ++s)
    EXPECT_EQ(Send(&g, "cam", s, 5000 + s), s < 612 ? FrameVerdict::kHeld : FrameVerdict::kAccept) << s;
  EXPECT_EQ(Send(&g, "cam", 613, 5613), FrameVerdict::kAccept);
  const GateCounters& c = g.counters();
  EXPECT_EQ(c.received, 16);
  EXPECT_EQ(c.held, 3);
  EXPECT_EQ(c.jumps, 1);
  EXPECT_EQ(c.lost, 0);
  EXPECT_EQ(c.reordered + c.duplicates, 0);
  EXPECT_EQ(c.rejected, 1);
}

TEST_F(GateTest, FramesAboveTheSourceRateAreDroppedAndNotCountedLost) {
  GateOptions o;
  o.params.max_frame_rate = 10.0;
  o.clock = clock_.fn();
  FrameGate g(o);
  // The first frame spends the limiter new sources share; the source then has its own burst of 10.
  int accepted = 0, limited = 0;
  for (int64_t s = 0; s < 15; ++s) {
    const FrameVerdict v = Send(&g, "cam", s, 1000 + s);
    accepted += v == FrameVerdict::kAccept;
    limited += v == FrameVerdict::kRateLimited;
  }
  EXPECT_EQ(accepted, 11);
  EXPECT_EQ(limited, 4);
  clock_.now_us += 100'000;  // one more frame's worth
  EXPECT_EQ(Send(&g, "cam", 15, 1015), FrameVerdict::kAccept);
  EXPECT_EQ(Send(&g, "cam", 16, 1016), FrameVerdict::kRateLimited);
  EXPECT_EQ(Send(&g, "cam", 12, 1012), FrameVerdict::kStale) << "dropped for its rate, received all the same";
  const GateCounters& c = g.counters();
  EXPECT_EQ(c.received, 18);
  EXPECT_EQ(c.rate_limited, 5);
  EXPECT_EQ(c.lost, 0) << "11..14 arrived: not lost";
  EXPECT_EQ(c.duplicates, 1);
  // Stale frames spend no rate: they are never decoded.
  clock_.now_us += 100'000;
  EXPECT_EQ(Send(&g, "cam", 17, 1017), FrameVerdict::kAccept);
}

TEST_F(GateTest, SourcesBeyondTheBoundAreRefused) {
  GateOptions o;
  o.params.max_sources = 2;
  o.clock = clock_.fn();
  FrameGate g(o);
  EXPECT_EQ(Send(&g, "a", 0, 1000), FrameVerdict::kAccept);
  EXPECT_EQ(Send(&g, "b", 0, 1000), FrameVerdict::kAccept);
  EXPECT_EQ(Send(&g, "c", 0, 1000), FrameVerdict::kRejected);
  EXPECT_EQ(Send(&g, "a", 1, 1001), FrameVerdict::kAccept) << "known sources go on";
  EXPECT_EQ(g.counters().rejected, 1);
}

TEST(GateParamsTest, FlagsBindAndBoundsAreChecked) {
  GateParams p;
  FlagParser flags("test");
  p.Bind(&flags);
  bool help = false;
  ASSERT_TRUE(
      flags.Parse({"--max-seq-jump", "900", "--seq-jump-confirm", "5", "--max-frame-pixels", "100"}, &help).ok());
  EXPECT_EQ(p.sequence.max_jump, 900);
  EXPECT_EQ(p.sequence.confirm_frames, 5);
  EXPECT_EQ(p.max_frame_pixels, 100);
  EXPECT_TRUE(p.Validate().ok());
  p.sequence.max_jump = 0;
  EXPECT_NE(p.Validate().message().find("--max-seq-jump"), std::string::npos) << p.Validate().message();
  p.sequence.max_jump = 300;
  p.max_frame_pixels = -1;
  EXPECT_NE(p.Validate().message().find("--max-frame-pixels"), std::string::npos) << p.Validate().message();
  const std::string help_text = flags.Help();
  for (const char* f : {"--max-seq-jump N", "--seq-jump-confirm N", "--max-frame-pixels"})
    EXPECT_NE(help_text.find(f), std::string::npos) << f;
}

std::vector<uint8_t> Encode(const vdeform::control_t& m) {
  std::vector<uint8_t> b(m.getEncodedSize());
  m.encode(b.data(), 0, int(b.size()));
  return b;
}

vdeform::control_t Control(int8_t command, int64_t utime, const std::string& path = "") {
  vdeform::control_t m{};
  m.utime = utime;
  m.command = command;
  m.path = path;
  m.sender = "test";
  m.auth_size = 0;
  return m;
}

// An unsigned command from `sender`, at the gate's clock.
Status SendControl(FrameGate* g, int8_t command, const std::string& sender) {
  vdeform::control_t m = Control(command, 1);
  m.sender = sender;
  const auto b = Encode(m);
  return g->OnControl(b.data(), b.size(), 0).status;
}

TEST(GateControlTest, WithoutAKeyEveryKnownCommandIsTaken) {
  FrameGate g(GateOptions{});
  for (int8_t c : {vdeform::control_t::COMMAND_RESET, vdeform::control_t::COMMAND_SAVE_SNAPSHOT,
                   vdeform::control_t::COMMAND_REQUEST_MESH}) {
    const auto b = Encode(Control(c, 5, "x"));
    EXPECT_TRUE(g.OnControl(b.data(), b.size(), 0).status.ok());
  }
  const auto unknown = Encode(Control(17, 5));
  EXPECT_FALSE(g.OnControl(unknown.data(), unknown.size(), 0).status.ok());
  const std::vector<uint8_t> junk(30, 1);
  EXPECT_FALSE(g.OnControl(junk.data(), junk.size(), 0).status.ok());
  EXPECT_EQ(g.counters().control_accepted, 3);
  EXPECT_EQ(g.counters().control_refused, 2);
}

TEST(GateControlTest, WithAKeyStateChangesNeedAFreshValidHmac) {
  GateOptions o;
  o.control_key = "a-sixteen-byte-key!!";
  FrameGate g(o);
  const int64_t now = 1764633600000000;
  auto send = [&](const vdeform::control_t& m) {
    const auto b = Encode(m);
    return g.OnControl(b.data(), b.size(), now).status;
  };
  // Viewers stay read-only and keyless: REQUEST_MESH needs no HMAC.
  EXPECT_TRUE(send(Control(vdeform::control_t::COMMAND_REQUEST_MESH, now)).ok());
  EXPECT_EQ(send(Control(vdeform::control_t::COMMAND_RESET, now)).code(), StatusCode::kPermissionDenied);
  vdeform::control_t reset = Control(vdeform::control_t::COMMAND_RESET, now);
  SignControl(o.control_key, &reset);
  EXPECT_TRUE(send(reset).ok());
  EXPECT_FALSE(send(reset).ok()) << "replayed";
  vdeform::control_t wrong = Control(vdeform::control_t::COMMAND_SAVE_SNAPSHOT, now + 10, "snap");
  SignControl("another-sixteen-byte-key", &wrong);
  EXPECT_FALSE(send(wrong).ok());
  vdeform::control_t old = Control(vdeform::control_t::COMMAND_SAVE_SNAPSHOT, now - 60'000'000, "snap");
  SignControl(o.control_key, &old);
  EXPECT_FALSE(send(old).ok()) << "a minute old";
  vdeform::control_t snap = Control(vdeform::control_t::COMMAND_SAVE_SNAPSHOT, now + 20, "snap");
  SignControl(o.control_key, &snap);
  snap.path = "../../etc";
  EXPECT_FALSE(send(snap).ok()) << "path changed after signing";
  snap.path = "snap";
  EXPECT_TRUE(send(snap).ok());
  EXPECT_EQ(g.counters().control_accepted, 3);
  EXPECT_EQ(g.counters().control_refused, 5);
}

TEST(GateControlTest, ControlMessagesAboveTheSenderRateAreRefusedAndCounted) {
  FakeClock clock_;
  GateOptions o;
  o.params.max_control_rate = 2.0;
  o.clock = clock_.fn();
  FrameGate g(o);
  const int8_t reset = vdeform::control_t::COMMAND_RESET;
  // First message of a sender: the shared limiter (burst 2); then the sender's own (burst 2).
  EXPECT_TRUE(SendControl(&g, reset, "ops").ok());
  EXPECT_TRUE(SendControl(&g, reset, "ops").ok());
  EXPECT_TRUE(SendControl(&g, reset, "ops").ok());
  const Status limited = SendControl(&g, reset, "ops");
  EXPECT_FALSE(limited.ok());
  EXPECT_NE(limited.message().find("--max-control-rate"), std::string::npos) << limited.message();
  EXPECT_TRUE(SendControl(&g, reset, "viewer").ok()) << "another sender has its own rate";
  clock_.now_us += 500'000;
  EXPECT_TRUE(SendControl(&g, reset, "ops").ok());
  EXPECT_FALSE(SendControl(&g, reset, "ops").ok());
  const GateCounters& c = g.counters();
  EXPECT_EQ(c.control_accepted, 5);
  EXPECT_EQ(c.control_refused, 2);
  EXPECT_EQ(c.control_rate_limited, 2);
}

TEST(GateControlTest, MeshRequestsAreServedAtMostOnceASecondInAll) {
  FakeClock clock_;
  GateOptions o;
  o.clock = clock_.fn();
  FrameGate g(o);
  const int8_t request = vdeform::control_t::COMMAND_REQUEST_MESH;
  EXPECT_FALSE(g.TakeMeshRequest()) << "nothing asked";
  EXPECT_TRUE(SendControl(&g, request, "viewer-1").ok());
  EXPECT_TRUE(g.TakeMeshRequest()) << "the first request is served at once";
  EXPECT_FALSE(g.TakeMeshRequest());
  // 50 requests from 5 viewers within the next second (each within its sender's rate): one
  // republication when the second ends.
  for (int i = 0; i < 50; ++i) EXPECT_TRUE(SendControl(&g, request, "viewer-" + std::to_string(i % 5)).ok()) << i;
  clock_.now_us += 999'999;
  EXPECT_FALSE(g.TakeMeshRequest());
  clock_.now_us += 1;
  EXPECT_TRUE(g.TakeMeshRequest());
  EXPECT_FALSE(g.TakeMeshRequest());
  clock_.now_us += 10'000'000;
  EXPECT_FALSE(g.TakeMeshRequest()) << "no request waiting";
  const GateCounters& c = g.counters();
  EXPECT_EQ(c.mesh_requests_served, 2);
  EXPECT_EQ(c.control_accepted, 51);
  EXPECT_EQ(c.mesh_requests_merged, 49) << "all but the first of the flood waited for the one served";
}

}  // namespace
}  // namespace vd
