// The server node driven in-process over LCM's memq:// provider: bad frames are rejected with a
// reason and never reach the model, good frames are processed and answered with meshes and
// status, stale frames are ignored, snapshot paths stay inside the snapshot directory and the
// snapshot's model is a checkpoint, a signal stops serving without an error.
#include "node.h"

#include <gtest/gtest.h>
#include <pthread.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <set>
#include <thread>

#include "../support/temp_dir.h"
#include "core/checkpoint.h"
#include "ocl/ocl.h"
#include "snapshot.h"
#include "vd/capture/synthetic.h"
#include "vd/common/output_auth.h"

namespace vd {
namespace {

struct Inbox {
  std::vector<vdeform::server_status_t> status;
  std::vector<vdeform::mesh_t> meshes;
  void OnStatus(const lcm::ReceiveBuffer*, const std::string&, const vdeform::server_status_t* m) { status.push_back(*m); }
  void OnMesh(const lcm::ReceiveBuffer*, const std::string&, const vdeform::mesh_t* m) { meshes.push_back(*m); }
};

int64_t RejectCount(const vdeform::server_status_t& s, const std::string& reason) {
  for (int i = 0; i < s.num_reject_reasons; ++i)
    if (s.reject_reason[i] == reason) return s.reject_count[i];
  return 0;
}

class NodeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto devices = ocl::ListDevices();
    if (!devices.ok() || devices->empty()) GTEST_SKIP() << "no OpenCL device";
    ASSERT_TRUE(lcm_.good());
    options_.engine.voxel_size = 0.008f;
    options_.snapshot_dir = test::TestTempDir("vd_node_snapshots");
    std::filesystem::remove_all(options_.snapshot_dir);
    ASSERT_TRUE(options_.Validate().ok());
    auto engine = Engine::Create(options_.engine, "");
    ASSERT_TRUE(engine.ok()) << engine.status().ToString();
    ASSERT_TRUE(ApplyTrackMesh(options_, engine->get()).ok());
    node_ = std::make_unique<Node>(options_, &lcm_, std::move(engine).value(), gate_, output_key_);
    lcm_.subscribe(kFrameChannel, &Node::OnFrame, node_.get());
    lcm_.subscribe(kControlChannel, &Node::OnControl, node_.get());
    lcm_.subscribe(kStatusChannel, &Inbox::OnStatus, &inbox_);
    lcm_.subscribe(kMeshChannel, &Inbox::OnMesh, &inbox_);
    SyntheticOptions so;
    so.noise = false;
    auto scene = MakeSyntheticScene("tube", so);
    ASSERT_TRUE(scene.ok());
    frame_ = (*scene)->Render(0);
    frame_.source_id = "test";
  }
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(options_.snapshot_dir, ec);
  }
  void Pump() {
    while (lcm_.handleTimeout(0) > 0) {
    }
  }
  // An unsigned REQUEST_MESH, as a viewer that joined late sends it, served by one Tick.
  void RequestMeshes() {
    vdeform::control_t c{};
    c.command = vdeform::control_t::COMMAND_REQUEST_MESH;
    c.auth_size = 0;
    lcm_.publish(kControlChannel, &c);
    Pump();
    node_->Tick();
    Pump();
  }
  vdeform::rgbd_frame_t Message(int64_t seq) {
    RgbdFrame f = frame_;
    f.seq = seq;
    auto m = FrameToMessage(f, FrameEncodeOptions());
    EXPECT_TRUE(m.ok()) << m.status().ToString();
    return *m;
  }
  // Publishes `f` as frame `seq` of source "test", lets the node process it, and takes its output.
  void SendAndProcess(RgbdFrame f, int64_t seq) {
    f.seq = seq;
    f.source_id = "test";
    auto m = FrameToMessage(f, FrameEncodeOptions());
    ASSERT_TRUE(m.ok());
    lcm_.publish(kFrameChannel, &*m);
    Pump();
    ASSERT_TRUE(node_->RunOnce());
    Pump();
  }
  const vdeform::server_status_t& Status() {
    node_->PublishStatusNow();
    Pump();
    return inbox_.status.back();
  }

  lcm::LCM lcm_{"memq://"};
  ServerOptions options_;
  // What the node's gate is built with (a derived fixture sets keys before SetUp).
  GateOptions gate_;
  // The node's output key (a derived fixture sets it before SetUp; empty: unsigned output).
  std::string output_key_;
  std::unique_ptr<Node> node_;
  Inbox inbox_;
  RgbdFrame frame_;
};

TEST_F(NodeTest, RejectsBadFramesByReasonAndKeepsServing) {
  // Random bytes, a truncated message, NaN intrinsics, an unknown encoding, a wrong size.
  const std::vector<uint8_t> junk(1000, 0xAB);
  lcm_.publish(kFrameChannel, junk.data(), int(junk.size()));
  auto good = Message(0);
  std::vector<uint8_t> bytes(good.getEncodedSize());
  good.encode(bytes.data(), 0, int(bytes.size()));
  lcm_.publish(kFrameChannel, bytes.data(), int(bytes.size() / 2));
  auto nan = Message(1);
  nan.fx = NAN;
  lcm_.publish(kFrameChannel, &nan);
  auto enc = Message(2);
  enc.depth_encoding = 42;
  lcm_.publish(kFrameChannel, &enc);
  auto size = Message(3);
  size.width = 320;
  lcm_.publish(kFrameChannel, &size);
  Pump();
  EXPECT_FALSE(node_->RunOnce()) << "no frame may reach the engine";
  const auto& st = Status();
  EXPECT_EQ(st.frames_received, 5);
  EXPECT_EQ(st.frames_rejected, 5);
  EXPECT_EQ(st.frames_processed, 0);
  EXPECT_EQ(RejectCount(st, "malformed_message"), 2);
  EXPECT_EQ(RejectCount(st, "bad_intrinsics"), 1);
  EXPECT_EQ(RejectCount(st, "unknown_encoding"), 1);
  EXPECT_EQ(RejectCount(st, "wrong_size"), 1);
  EXPECT_EQ(int(st.state), int(vdeform::server_status_t::STATE_IDLE));

  // A good frame is then processed and answered with a mesh and a status naming it.
  auto ok = Message(7);
  lcm_.publish(kFrameChannel, &ok);
  Pump();
  EXPECT_TRUE(node_->RunOnce());
  Pump();
  ASSERT_FALSE(inbox_.meshes.empty());
  EXPECT_EQ(inbox_.meshes.back().seq, 7);
  EXPECT_GT(inbox_.meshes.back().num_triangles, 1000);
  const auto& after = inbox_.status.back();
  EXPECT_EQ(after.frames_processed, 1);
  EXPECT_EQ(after.last_processed_seq, 7);
  EXPECT_EQ(after.last_source_id, "test");
  EXPECT_EQ(int(after.state), int(vdeform::server_status_t::STATE_TRACKING));

  // The same or an older sequence number again is ignored (a re-send), not processed twice.
  lcm_.publish(kFrameChannel, &ok);
  auto old = Message(6);
  lcm_.publish(kFrameChannel, &old);
  Pump();
  EXPECT_FALSE(node_->RunOnce());
  EXPECT_EQ(Status().frames_processed, 1);
}

TEST_F(NodeTest, NewestFrameWinsAndDropsAreCounted) {
  for (int64_t s = 0; s < 3; ++s) {
    auto m = Message(s);
    lcm_.publish(kFrameChannel, &m);
  }
  Pump();
  EXPECT_TRUE(node_->RunOnce());
  const auto& st = Status();
  EXPECT_EQ(st.frames_dropped, 2);
  EXPECT_EQ(st.frames_processed, 1);
  EXPECT_EQ(st.last_processed_seq, 2);
}

// A frame numbered near 2^62 under the same source is held, not processed, and the real stream
// goes on; the status says so (frames_held) and counts no losses for it.
TEST_F(NodeTest, SequenceJumpsAreHeldAndReported) {
  for (int64_t seq : {int64_t(0), int64_t(1) << 62, int64_t(1)}) {
    auto m = Message(seq);
    lcm_.publish(kFrameChannel, &m);
    Pump();
    node_->RunOnce();
  }
  const auto& st = Status();
  EXPECT_EQ(st.frames_received, 3);
  EXPECT_EQ(st.frames_processed, 2);
  EXPECT_EQ(st.frames_held, 1);
  EXPECT_EQ(st.sequence_jumps, 0);
  EXPECT_EQ(st.frames_lost, 0);
  EXPECT_EQ(st.frames_reordered, 0);
  EXPECT_EQ(st.last_processed_seq, 1);
}

TEST_F(NodeTest, StatusReportsCaptureToMeshLatency) {
  // A frame without a capture time is not counted.
  auto untimed = Message(0);
  untimed.utime = 0;
  lcm_.publish(kFrameChannel, &untimed);
  Pump();
  ASSERT_TRUE(node_->RunOnce());
  EXPECT_EQ(Status().latency_ms_p50, 0.f);
  // Frames captured 200 ms before they arrive: the latency is that plus the processing.
  double slowest_ms = 0;
  for (int64_t seq = 1; seq <= 3; ++seq) {
    auto m = Message(seq);
    const auto sent = std::chrono::system_clock::now();
    m.utime = std::chrono::duration_cast<std::chrono::microseconds>(sent.time_since_epoch()).count() - 200000;
    lcm_.publish(kFrameChannel, &m);
    Pump();
    ASSERT_TRUE(node_->RunOnce());
    slowest_ms = std::max(
        slowest_ms, std::chrono::duration<double, std::milli>(std::chrono::system_clock::now() - sent).count());
  }
  const auto& st = Status();
  EXPECT_GE(st.latency_ms_p50, 200.f);
  EXPECT_GE(st.latency_ms_p95, st.latency_ms_p50);
  EXPECT_LE(st.latency_ms_p95, 200.f + slowest_ms + 1.f);
  EXPECT_GE(st.latency_ms_last, 200.f);
}

TEST_F(NodeTest, SnapshotStaysInsideItsDirectoryAndMeshRequestRepublishes) {
  auto m = Message(0);
  lcm_.publish(kFrameChannel, &m);
  Pump();
  ASSERT_TRUE(node_->RunOnce());
  vdeform::control_t c;
  c.utime = 0;
  c.command = vdeform::control_t::COMMAND_SAVE_SNAPSHOT;
  c.auth_size = 0;
  for (const char* path : {"../escape", "/tmp/abs", "snap1"}) {
    c.path = path;
    lcm_.publish(kControlChannel, &c);
  }
  Pump();
  node_->RunOnce();
  EXPECT_FALSE(std::filesystem::exists(options_.snapshot_dir + "/../escape"));
  const std::string snap = options_.snapshot_dir + "/snap1/";
  EXPECT_TRUE(std::filesystem::exists(snap + kSnapshotLiveFile));
  EXPECT_TRUE(std::filesystem::exists(snap + kSnapshotCanonicalFile));
  // The model in the checkpoint format (versioned, SHA-256), read by the checkpoint reader.
  auto model = ReadCheckpoint(snap + kCheckpointFile);
  ASSERT_TRUE(model.ok()) << model.status().ToString();
  EXPECT_EQ(model->frames_fused, 1);
  EXPECT_EQ(model->last_seq, 0);
  EXPECT_EQ(model->source_id, "test");
  EXPECT_GT(model->tsdf.size(), 0u);
  EXPECT_FALSE(std::filesystem::exists(snap + kCheckpointFile + ".tmp"));

  const size_t before = inbox_.meshes.size();
  c.command = vdeform::control_t::COMMAND_REQUEST_MESH;
  c.path = "";
  lcm_.publish(kControlChannel, &c);
  Pump();
  node_->Tick();
  Pump();
  // Live and canonical meshes are sent again for a viewer that joined late.
  ASSERT_GE(inbox_.meshes.size(), before + 2);
  EXPECT_EQ(int(inbox_.meshes.back().kind), int(vdeform::mesh_t::KIND_CANONICAL));
}

// A node given a frame key: only frames signed under it reach the engine; the refused ones are
// counted by reason in the status (vdeform-control prints them as rejected_<reason>).
class SignedNodeTest : public NodeTest {
 protected:
  void SetUp() override {
    auto keys = FrameKeys::Parse(std::string(64, '7'), "test");
    ASSERT_TRUE(keys.ok());
    gate_.frame_keys = *keys;
    key_ = *gate_.frame_keys.For("test");
    NodeTest::SetUp();
  }
  vdeform::rgbd_frame_t Signed(int64_t seq, int64_t epoch, int64_t utime) {
    vdeform::rgbd_frame_t m = Message(seq);
    m.epoch = epoch;
    m.utime = utime;
    EXPECT_TRUE(SignFrame(key_, &m).ok());
    return m;
  }
  std::string key_;
};

TEST_F(SignedNodeTest, OnlySignedFramesReachTheModel) {
  const int64_t t = 1764633600000000;
  auto unsigned_frame = Message(0);
  lcm_.publish(kFrameChannel, &unsigned_frame);
  auto forged = Message(0);
  forged.epoch = 5;
  ASSERT_TRUE(SignFrame(std::string(32, 'x'), &forged).ok());
  lcm_.publish(kFrameChannel, &forged);
  Pump();
  EXPECT_FALSE(node_->RunOnce()) << "no unsigned or forged frame may reach the engine";
  auto first = Signed(0, 5, t);
  lcm_.publish(kFrameChannel, &first);
  Pump();
  ASSERT_TRUE(node_->RunOnce());
  // A restart of the client (new epoch, later times), then its first run played back.
  auto restarted = Signed(0, 6, t + 1'000'000);
  lcm_.publish(kFrameChannel, &restarted);
  Pump();
  ASSERT_TRUE(node_->RunOnce());
  lcm_.publish(kFrameChannel, &first);
  Pump();
  EXPECT_FALSE(node_->RunOnce()) << "a replayed frame of the earlier run";
  const auto& st = Status();
  EXPECT_EQ(st.frames_received, 5);
  EXPECT_EQ(st.frames_processed, 2);
  EXPECT_EQ(st.frames_rejected, 3);
  EXPECT_EQ(RejectCount(st, "unsigned"), 1);
  EXPECT_EQ(RejectCount(st, "bad_signature"), 1);
  EXPECT_EQ(RejectCount(st, "replayed"), 1);
  EXPECT_EQ(st.source_restarts, 1);
  EXPECT_EQ(st.model_frames, 2);
}

// Without an output key, meshes and status go out unsigned but stamped with the run and a count
// (receivers without a key ignore both).
TEST_F(NodeTest, OutputIsStampedAndUnsignedWithoutAKey) {
  auto m = Message(0);
  lcm_.publish(kFrameChannel, &m);
  Pump();
  ASSERT_TRUE(node_->RunOnce());
  Pump();
  const auto& st = Status();
  ASSERT_FALSE(inbox_.meshes.empty());
  EXPECT_EQ(st.auth_size, 0);
  EXPECT_EQ(inbox_.meshes.front().auth_size, 0);
  EXPECT_NE(st.epoch, 0);
  EXPECT_EQ(inbox_.meshes.front().epoch, st.epoch);
  EXPECT_GT(st.out_seq, inbox_.meshes.front().out_seq);
}

// Draco's header byte naming the connectivity coding (after "DRACO", the version and the
// geometry type): 0 sequential, 1 edgebreaker.
int DracoMethod(const vdeform::mesh_t& msg) { return msg.data.size() > 8 ? msg.data[8] : -1; }

// By default (--draco-speed 10) every published mesh is coded sequentially: the fastest to encode
// on the output thread, and vertices keep the engine's order.
TEST_F(NodeTest, MeshesAreCodedSequentiallyByDefault) {
  SendAndProcess(frame_, 0);
  node_->PublishStatusNow();
  RequestMeshes();
  ASSERT_GE(inbox_.meshes.size(), 2u);
  std::set<int> kinds;
  for (const auto& msg : inbox_.meshes) {
    kinds.insert(msg.kind);
    EXPECT_EQ(DracoMethod(msg), 0) << "kind " << int(msg.kind);
    EXPECT_TRUE(MessageToMesh(msg).ok());
  }
  EXPECT_EQ(kinds, (std::set<int>{int(vdeform::mesh_t::KIND_LIVE), int(vdeform::mesh_t::KIND_CANONICAL)}));
}

// --draco-speed applies up to kSequentialMaxTriangles; a larger (room-scale) mesh takes
// edgebreaker at speed 7 at most, so its message stays inside the receivers' buffers.
TEST(PublishedMeshDracoTest, LargeMeshesTakeEdgebreaker) {
  ServerOptions o;
  EXPECT_EQ(PublishedMeshDraco(o, 30000).speed, 10);
  EXPECT_EQ(PublishedMeshDraco(o, kSequentialMaxTriangles).speed, 10);
  EXPECT_EQ(PublishedMeshDraco(o, kSequentialMaxTriangles + 1).speed, 7);
  o.draco_speed = 3;
  EXPECT_EQ(PublishedMeshDraco(o, 30000).speed, 3);
  EXPECT_EQ(PublishedMeshDraco(o, 1000000).speed, 3);
}

// --draco-speed 7: the node's meshes decode with the counts they name (edgebreaker, or sequential
// where it would change the marching-cubes mesh: DracoCodecTest covers both); out of 0..10 the
// speed is refused.
class EdgebreakerNodeTest : public NodeTest {
 protected:
  void SetUp() override {
    options_.draco_speed = 7;
    NodeTest::SetUp();
  }
};

TEST_F(EdgebreakerNodeTest, MeshesDecodeAndTheSpeedIsBounded) {
  SendAndProcess(frame_, 0);
  RequestMeshes();
  ASSERT_GE(inbox_.meshes.size(), 2u);
  for (const auto& msg : inbox_.meshes) {
    auto mesh = MessageToMesh(msg);
    ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
    EXPECT_EQ(int64_t(mesh->num_vertices()), int64_t(msg.num_vertices));
    EXPECT_GT(mesh->num_triangles(), 1000u);
  }
  ServerOptions bad = options_;
  for (int64_t speed : {-1, 11}) {
    bad.draco_speed = speed;
    EXPECT_NE(bad.Validate().ToString().find("--draco-speed"), std::string::npos) << speed;
  }
}

// A node given an output key signs every mesh and status under it: each verifies, all carry the
// run's epoch, and out_seq grows with every message of either kind, also across a republished
// mesh (REQUEST_MESH), so a receiver's replay check takes each of them once.
class SignedOutputNodeTest : public NodeTest {
 protected:
  void SetUp() override {
    output_key_ = std::string(32, '\x42');
    NodeTest::SetUp();
  }
};

TEST_F(SignedOutputNodeTest, EveryMeshAndStatusIsSignedAndNumbered) {
  auto m = Message(0);
  lcm_.publish(kFrameChannel, &m);
  Pump();
  ASSERT_TRUE(node_->RunOnce());
  Pump();
  RequestMeshes();
  Status();
  ASSERT_GE(inbox_.meshes.size(), 4u) << "live and canonical, then both again on request";
  ASSERT_GE(inbox_.status.size(), 2u);
  std::vector<int64_t> out_seqs;
  OutputVerifier verifier(output_key_);
  for (const auto& mesh : inbox_.meshes) {
    EXPECT_TRUE(VerifyMesh(output_key_, mesh).ok());
    EXPECT_TRUE(verifier.Check(mesh).ok()) << "mesh out_seq " << mesh.out_seq;
    EXPECT_EQ(mesh.epoch, inbox_.meshes.front().epoch);
    out_seqs.push_back(mesh.out_seq);
  }
  for (const auto& st : inbox_.status) {
    EXPECT_TRUE(VerifyStatus(output_key_, st).ok());
    EXPECT_TRUE(verifier.Check(st).ok()) << "status out_seq " << st.out_seq;
    EXPECT_EQ(st.epoch, inbox_.meshes.front().epoch);
    out_seqs.push_back(st.out_seq);
  }
  std::sort(out_seqs.begin(), out_seqs.end());
  EXPECT_EQ(std::adjacent_find(out_seqs.begin(), out_seqs.end()), out_seqs.end()) << "no out_seq twice";
  EXPECT_FALSE(VerifyMesh(std::string(32, '\x43'), inbox_.meshes.front()).ok());
}

// The node with the gate's clock in the test's hand: REQUEST_MESH republishes the meshes at most
// once a second however many viewers ask, and frames above a source's rate are counted and dropped.
class ClockedNodeTest : public NodeTest {
 protected:
  void SetUp() override {
    gate_.clock = [this] { return now_us_; };
    gate_.params.max_frame_rate = 1.0;
    NodeTest::SetUp();
  }
  int64_t now_us_ = 1'000'000;
};

TEST_F(ClockedNodeTest, MeshRequestsAreServedOnceASecondAndFramesAboveTheRateDropped) {
  auto first = Message(0);
  lcm_.publish(kFrameChannel, &first);
  Pump();
  ASSERT_TRUE(node_->RunOnce());
  Pump();
  auto republished = [&] {
    const size_t before = inbox_.meshes.size();
    node_->Tick();
    Pump();
    return inbox_.meshes.size() - before;
  };
  vdeform::control_t c{};
  c.utime = 0;
  c.command = vdeform::control_t::COMMAND_REQUEST_MESH;
  c.auth_size = 0;
  for (int i = 0; i < 20; ++i) {
    c.sender = "viewer-" + std::to_string(i % 4);
    lcm_.publish(kControlChannel, &c);
  }
  Pump();
  EXPECT_EQ(republished(), 2u) << "live and canonical, once for all 20 requests";
  EXPECT_EQ(republished(), 0u);
  lcm_.publish(kControlChannel, &c);
  Pump();
  now_us_ += 999'999;
  EXPECT_EQ(republished(), 0u) << "within the second";
  now_us_ += 1;
  EXPECT_EQ(republished(), 2u);
  EXPECT_EQ(republished(), 0u);
  // Frames: the source's rate is 1 Hz (a burst of 1 after its first frame): of 3 more frames at
  // once, 1 is taken (it waits for the worker) and 2 are dropped, their numbers not lost.
  for (int64_t seq = 1; seq <= 3; ++seq) {
    auto m = Message(seq);
    lcm_.publish(kFrameChannel, &m);
  }
  Pump();
  const auto& st = Status();
  EXPECT_EQ(st.mesh_requests_merged, 19);
  EXPECT_EQ(st.control_refused, 0);
  EXPECT_EQ(st.control_rate_limited, 0);
  EXPECT_EQ(st.frames_received, 4);
  EXPECT_EQ(st.frames_rate_limited, 2);
  EXPECT_EQ(st.frames_lost, 0);
  EXPECT_EQ(st.frames_processed, 1);
}

// Serving until a signal. select() in the receive returns EINTR for a signal that arrives while it
// waits: that is no error; the signal whose handler sets the stop flag (Ctrl-C) ends serving cleanly.
std::atomic<bool> g_serve_stop{false};
std::atomic<int> g_signals{0};
constexpr int kSignalsToStop = 5;
void OnTestSignal(int) {
  if (++g_signals >= kSignalsToStop) g_serve_stop = true;
}

// --track-mesh on a node: every processed frame publishes a mesh_t KIND_TRACKED with the first
// frame's vertices and faces (moved with the tube), before the status that names the frame, and
// with --save-dir writes it as frame-%06d.tracked.ply.
class TrackedNodeTest : public NodeTest {
 protected:
  void SetUp() override {
    options_.track_mesh = true;
    options_.save_dir = test::TestTempDir("vd_node_tracked");
    std::filesystem::remove_all(options_.save_dir);
    std::filesystem::create_directories(options_.save_dir);
    NodeTest::SetUp();
  }
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(options_.save_dir, ec);
    NodeTest::TearDown();
  }
};

TEST_F(TrackedNodeTest, EveryFramePublishesTheTrackedMeshWithOneTopology) {
  SyntheticOptions so;
  so.noise = false;
  auto scene = MakeSyntheticScene("tube", so);
  ASSERT_TRUE(scene.ok());
  const int kFrames = 4;
  for (int64_t seq = 0; seq < kFrames; ++seq) SendAndProcess((*scene)->Render(int(6 * seq)), seq);
  std::vector<TriangleMesh> tracked, live;
  std::vector<int64_t> tracked_seq;
  for (const auto& msg : inbox_.meshes) {
    auto mesh = MessageToMesh(msg);
    ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
    if (msg.kind == vdeform::mesh_t::KIND_TRACKED) {
      tracked.push_back(*mesh);
      tracked_seq.push_back(msg.seq);
      EXPECT_GT(msg.out_seq, 0);  // stamped like every output
    } else if (msg.kind == vdeform::mesh_t::KIND_LIVE) {
      live.push_back(*mesh);
    }
  }
  ASSERT_EQ(tracked.size(), size_t(kFrames));
  ASSERT_EQ(live.size(), size_t(kFrames));
  EXPECT_EQ(tracked_seq, (std::vector<int64_t>{0, 1, 2, 3}));
  // The first frame's mesh: as many vertices as its live mesh.
  EXPECT_EQ(tracked[0].num_vertices(), live[0].num_vertices());
  ASSERT_GT(tracked[0].num_vertices(), 100u);
  double moved = 0;
  for (int k = 1; k < kFrames; ++k) {
    ASSERT_EQ(tracked[k].num_vertices(), tracked[0].num_vertices()) << k;
    EXPECT_EQ(tracked[k].triangles, tracked[0].triangles) << k;
  }
  for (size_t i = 0; i < tracked[0].positions.size(); ++i)
    moved = std::max(moved, double(std::abs(tracked[kFrames - 1].positions[i] - tracked[0].positions[i])));
  // The tube bends: the last frame's tracked vertices are not the first frame's (Draco's 14-bit
  // quantisation is ~0.06 mm).
  EXPECT_GT(moved, 0.002);
  for (int seq = 0; seq < kFrames; ++seq) {
    char name[64];
    std::snprintf(name, sizeof name, "/frame-%06d.tracked.ply", seq);
    auto read = ReadPly(options_.save_dir + name);
    ASSERT_TRUE(read.ok()) << name;
    EXPECT_EQ(read->num_vertices(), tracked[0].num_vertices());
  }

  // A viewer that joins late asks for the meshes: the newest tracked one comes again with them.
  inbox_.meshes.clear();
  RequestMeshes();
  std::vector<int> kinds;
  for (const auto& msg : inbox_.meshes) {
    kinds.push_back(msg.kind);
    if (msg.kind != vdeform::mesh_t::KIND_TRACKED) continue;
    EXPECT_EQ(msg.seq, kFrames - 1);
    auto mesh = MessageToMesh(msg);
    ASSERT_TRUE(mesh.ok());
    EXPECT_EQ(mesh->triangles, tracked[0].triangles);
  }
  EXPECT_EQ(std::count(kinds.begin(), kinds.end(), int(vdeform::mesh_t::KIND_TRACKED)), 1);
  EXPECT_EQ(std::count(kinds.begin(), kinds.end(), int(vdeform::mesh_t::KIND_LIVE)), 1);
}

TEST_F(NodeTest, SignalsStopServingWithoutAnError) {
  g_serve_stop = false;
  g_signals = 0;
  struct sigaction action {}, previous {};
  action.sa_handler = OnTestSignal;
  sigemptyset(&action.sa_mask);
  ASSERT_EQ(sigaction(SIGINT, &action, &previous), 0);
  const pthread_t serving = pthread_self();
  std::thread ctrl_c([&] {
    for (;;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(40));
      if (g_serve_stop) break;
      pthread_kill(serving, SIGINT);
    }
  });
  testing::internal::CaptureStderr();
  const vd::Status served = node_->Serve(&g_serve_stop);
  const std::string log = testing::internal::GetCapturedStderr();
  ctrl_c.join();
  sigaction(SIGINT, &previous, nullptr);
  Pump();
  EXPECT_TRUE(served.ok()) << served.ToString();
  EXPECT_GE(g_signals, kSignalsToStop);
  // Log lines start with their level: "E <time> file:line] ..." for an error.
  EXPECT_FALSE(log.rfind("E ", 0) == 0 || log.find("\nE ") != std::string::npos) << log;
  EXPECT_GE(inbox_.status.size(), 1u) << "the loop published status while it served";
}

// A node on the sparse volume (--rigid-only --sparse-volume) with a pool smaller than one view:
// the status names the pool's use and that it is full, the node keeps serving, and a snapshot
// (meshes and a checkpoint by brick key) is written.
class SparseNodeTest : public NodeTest {
 protected:
  void SetUp() override {
    options_.engine.rigid_only = true;
    options_.engine.sparse_volume = true;
    options_.engine.max_grid_mb = 1.0;
    NodeTest::SetUp();
  }
};

TEST_F(SparseNodeTest, AFullBrickPoolIsInTheStatusAndTheNodeGoesOn) {
  SyntheticOptions so;
  so.noise = false;
  auto tube = MakeSyntheticScene("tube", so);
  ASSERT_TRUE(tube.ok());
  for (int k = 0; k < 3; ++k) SendAndProcess((*tube)->Render(k), k);
  auto st = Status();
  EXPECT_EQ(int(st.state), int(vdeform::server_status_t::STATE_TRACKING)) << st.message;
  EXPECT_EQ(st.frames_processed, 3);
  EXPECT_EQ(st.message.rfind("bricks ", 0), 0u) << "the pool's use leads the message: " << st.message;
  EXPECT_NE(st.message.substr(0, 60).find("BRICK POOL FULL"), std::string::npos) << st.message;
  EXPECT_FALSE(inbox_.meshes.empty());
  // SAVE_SNAPSHOT: the meshes and the model by brick key.
  vdeform::control_t c{};
  c.command = vdeform::control_t::COMMAND_SAVE_SNAPSHOT;
  c.path = "sparse";
  c.auth_size = 0;
  lcm_.publish(kControlChannel, &c);
  Pump();
  node_->RunOnce();
  const std::string snap = options_.snapshot_dir + "/sparse/";
  EXPECT_TRUE(std::filesystem::exists(snap + kSnapshotLiveFile));
  auto model = ReadCheckpoint(snap + kCheckpointFile);
  ASSERT_TRUE(model.ok()) << model.status().ToString();
  EXPECT_TRUE(model->sparse);
  EXPECT_EQ(model->frames_fused, 3);
  EXPECT_GT(model->brick_keys.size(), 100u);
  // RESET: a new model in the same table and pool, from the next frame.
  c.command = vdeform::control_t::COMMAND_RESET;
  c.path = "";
  lcm_.publish(kControlChannel, &c);
  Pump();
  EXPECT_FALSE(node_->RunOnce());
  EXPECT_EQ(Status().model_frames, 0);
  SendAndProcess((*tube)->Render(5), 3);
  st = Status();
  EXPECT_EQ(int(st.state), int(vdeform::server_status_t::STATE_TRACKING)) << st.message;
  EXPECT_EQ(st.model_frames, 1);
  EXPECT_EQ(st.message.rfind("bricks ", 0), 0u) << st.message;
}

// A frame of another scene: reported in the status as TRACKING_LOST, not fused (the model's frame
// count does not move), tracking resumes on the scene; RESET then drops the model.
TEST_F(NodeTest, TrackingFailureIsReportedAndResetStartsANewModel) {
  SyntheticOptions so;
  so.noise = false;
  auto tube = MakeSyntheticScene("tube", so);
  auto cloth = MakeSyntheticScene("cloth", so);
  ASSERT_TRUE(tube.ok() && cloth.ok());
  auto send = [&](RgbdFrame f, int64_t seq) { SendAndProcess(std::move(f), seq); };
  for (int k = 0; k < 3; ++k) send((*tube)->Render(k), k);
  EXPECT_EQ(Status().model_frames, 3);
  send((*cloth)->Render(30), 3);
  auto st = Status();
  EXPECT_EQ(int(st.state), int(vdeform::server_status_t::STATE_TRACKING_LOST));
  EXPECT_FALSE(st.message.empty());
  EXPECT_EQ(st.model_frames, 3) << "a frame that failed tracking must not be fused";
  EXPECT_EQ(st.frames_processed, 4);
  send((*tube)->Render(3), 4);
  st = Status();
  EXPECT_EQ(int(st.state), int(vdeform::server_status_t::STATE_TRACKING)) << st.message;
  EXPECT_EQ(st.model_frames, 4);

  vdeform::control_t c{};
  c.utime = 0;
  c.command = vdeform::control_t::COMMAND_RESET;
  c.auth_size = 0;
  lcm_.publish(kControlChannel, &c);
  Pump();
  EXPECT_FALSE(node_->RunOnce()) << "a reset, no frame";
  st = Status();
  EXPECT_EQ(int(st.state), int(vdeform::server_status_t::STATE_IDLE));
  EXPECT_EQ(st.model_frames, 0);
  send((*cloth)->Render(0), 5);
  st = Status();
  EXPECT_EQ(int(st.state), int(vdeform::server_status_t::STATE_TRACKING)) << "the new model is the new scene";
  EXPECT_EQ(st.model_frames, 1);
}

}  // namespace
}  // namespace vd
