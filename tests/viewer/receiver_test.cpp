// MeshReceiver on LCM's in-process memq:// provider: the test publishes mesh_t / server_status_t
// (and garbage) on the same lcm::LCM instance and dispatches with handleTimeout.
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "vd/common/auth.h"
#include "vd/common/codecs.h"
#include "vd/common/messages.h"
#include "vd/viewer/receiver.h"
#include "vd/viewer/status_text.h"

namespace vd {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// A unique empty directory, removed at the end of the test.
class ScratchDir {
 public:
  ScratchDir() {
    std::string tmpl = (fs::temp_directory_path() / "vd_viewer_test_XXXXXX").string();
    path_ = mkdtemp(tmpl.data());
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string path() const { return path_; }
  std::string operator/(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

// A grid surface of (n+1)^2 vertices at depth ~1 m in front of the camera, one colour; `bend`
// curves it (a stand-in for the live deformation of the same canonical surface).
TriangleMesh Grid(int n, float bend, uint8_t r, uint8_t g, uint8_t b) {
  TriangleMesh m;
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) {
      const float u = -0.3f + 0.6f * x / n, v = -0.2f + 0.4f * y / n;
      m.positions.insert(m.positions.end(), {u, v, 1.0f + bend * u * u});
      m.colors.insert(m.colors.end(), {r, g, b});
    }
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const int a = y * (n + 1) + x, c = a + n + 1;
      m.triangles.insert(m.triangles.end(), {a, c, a + 1, a + 1, c, c + 1});
    }
  return m;
}

std::vector<uint8_t> Encode(const vdeform::mesh_t& msg) {
  std::vector<uint8_t> bytes(msg.getEncodedSize());
  msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

vdeform::server_status_t Status(int8_t state, int64_t processed) {
  vdeform::server_status_t s{};
  s.state = state;
  s.message = "device pthread-cpu";
  s.frames_received = processed + 2;
  s.frames_processed = processed;
  s.frames_dropped = 2;
  s.last_processed_seq = processed - 1;
  s.last_source_id = "cam0";
  s.num_stages = 2;
  s.stage_name = {"icp", "fuse"};
  s.stage_ms_last = {4.5f, 2.25f};
  s.stage_ms_mean = {4.f, 2.f};
  s.fps = 29.5f;
  return s;
}

class ReceiverTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(lcm_.good()); }

  void PublishMesh(const TriangleMesh& mesh, int64_t seq, int8_t kind) {
    auto msg = MeshToMessage(mesh, 1000 + seq, seq, kind);
    ASSERT_TRUE(msg.ok()) << msg.status().ToString();
    ASSERT_EQ(lcm_.publish(kMeshChannel, &*msg), 0);
  }
  // Dispatches everything queued.
  void Drain() {
    while (lcm_.handleTimeout(0) > 0) {
    }
  }
  std::unique_ptr<MeshReceiver> Make(const ReceiverOptions& options) {
    auto created = MeshReceiver::Create(&lcm_, options);
    EXPECT_TRUE(created.ok()) << created.status().ToString();
    return created.ok() ? std::move(created).value() : nullptr;
  }

  lcm::LCM lcm_{"memq://"};
};

// Pixels of a PNG that are not the render background.
int64_t CoveredPixels(const std::string& path) {
  const cv::Mat image = cv::imread(path, cv::IMREAD_COLOR);
  if (image.empty()) return -1;
  const cv::Vec3b background = RenderOptions{}.background;
  int64_t n = 0;
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x) n += image.at<cv::Vec3b>(y, x) != background;
  return n;
}

struct ControlLog {
  void OnControl(const lcm::ReceiveBuffer* buffer, const std::string&) {
    auto msg = DecodeLcm<vdeform::control_t>(buffer->data, buffer->data_size);
    ASSERT_TRUE(msg.ok()) << msg.status().ToString();
    commands.push_back(msg->command);
    senders.push_back(msg->sender);
  }
  std::vector<int8_t> commands;
  std::vector<std::string> senders;
};

TEST_F(ReceiverTest, SendsRequestMeshAtStartUpAndOnceMoreWhenTheServerAppears) {
  ControlLog log;
  lcm::Subscription* sub = lcm_.subscribe(kControlChannel, &ControlLog::OnControl, &log);
  ReceiverOptions options;
  options.sender = "viewer-test";
  auto receiver = Make(options);
  ASSERT_TRUE(receiver);
  Drain();
  ASSERT_EQ(log.commands.size(), 1u);
  EXPECT_EQ(log.commands[0], +vdeform::control_t::COMMAND_REQUEST_MESH);
  EXPECT_EQ(log.senders[0], "viewer-test");
  // The first status shows the server is up; no mesh yet, so ask again (once).
  for (int i = 0; i < 3; ++i) {
    auto status = Status(vdeform::server_status_t::STATE_IDLE, 0);
    lcm_.publish(kStatusChannel, &status);
  }
  Drain();
  EXPECT_EQ(log.commands.size(), 2u);
  EXPECT_EQ(receiver->stats().requests_sent, 2);
  EXPECT_EQ(receiver->stats().status_messages, 3);
  ASSERT_TRUE(receiver->last_status().has_value());
  EXPECT_EQ(receiver->last_status()->fps, 29.5f);
  lcm_.unsubscribe(sub);
}

TEST_F(ReceiverTest, NoRequestWhenDisabled) {
  ControlLog log;
  lcm::Subscription* sub = lcm_.subscribe(kControlChannel, &ControlLog::OnControl, &log);
  ReceiverOptions options;
  options.request_mesh = false;
  auto receiver = Make(options);
  auto status = Status(vdeform::server_status_t::STATE_IDLE, 0);
  lcm_.publish(kStatusChannel, &status);
  Drain();
  EXPECT_TRUE(log.commands.empty());
  lcm_.unsubscribe(sub);
}

// Tracked meshes (a --track-mesh server) are counted and saved as frame-%06d.tracked.ply; they
// never replace the live mesh on show.
TEST_F(ReceiverTest, TrackedMeshesAreSavedNotShown) {
  ScratchDir dir;
  ReceiverOptions options;
  options.save_dir = dir / "out";
  auto receiver = Make(options);
  ASSERT_TRUE(receiver);
  PublishMesh(Grid(8, 1.0f, 30, 60, 220), 5, vdeform::mesh_t::KIND_LIVE);
  PublishMesh(Grid(4, 1.2f, 200, 60, 20), 5, vdeform::mesh_t::KIND_TRACKED);
  PublishMesh(Grid(4, 1.3f, 200, 60, 20), 6, vdeform::mesh_t::KIND_TRACKED);
  Drain();
  const ReceiverStats& stats = receiver->stats();
  EXPECT_EQ(stats.meshes_decoded, 3);
  EXPECT_EQ(stats.meshes_failed, 0);
  EXPECT_EQ(stats.live_meshes, 1);
  EXPECT_EQ(stats.tracked_meshes, 2);
  EXPECT_EQ(stats.last_tracked_vertices, 25);
  EXPECT_EQ(stats.last_live_vertices, 81);
  EXPECT_EQ(receiver->live_seq(), 5);
  EXPECT_EQ(receiver->version(), 1);
  auto saved = ReadPly(options.save_dir + "/frame-000006.tracked.ply");
  ASSERT_TRUE(saved.ok()) << saved.status().ToString();
  EXPECT_EQ(saved->num_vertices(), 25u);
  EXPECT_TRUE(fs::exists(options.save_dir + "/frame-000005.tracked.ply"));
  EXPECT_NE(StatusLine(stats, std::nullopt).find("+2 tracked"), std::string::npos);
}

TEST_F(ReceiverTest, DecodesSavesPlyAndPngWithCanonicalColouring) {
  ScratchDir dir;
  ReceiverOptions options;
  options.save_dir = dir / "out";  // created by the receiver
  options.write_png = true;
  options.render.width = 320;
  options.render.height = 240;
  auto receiver = Make(options);
  ASSERT_TRUE(receiver);
  // Uniformly blue live meshes; the canonical mesh of frame 3 has the same connectivity, flat.
  const TriangleMesh live3 = Grid(12, 1.5f, 30, 60, 220);
  const TriangleMesh canonical3 = Grid(12, 0.f, 128, 128, 128);
  const TriangleMesh live4 = Grid(10, 1.0f, 30, 60, 220);
  PublishMesh(live3, 3, vdeform::mesh_t::KIND_LIVE);
  PublishMesh(canonical3, 3, vdeform::mesh_t::KIND_CANONICAL);
  PublishMesh(live4, 4, vdeform::mesh_t::KIND_LIVE);
  auto status = Status(vdeform::server_status_t::STATE_TRACKING, 5);
  lcm_.publish(kStatusChannel, &status);
  Drain();

  const ReceiverStats& stats = receiver->stats();
  EXPECT_EQ(stats.mesh_messages, 3);
  EXPECT_EQ(stats.meshes_decoded, 3);
  EXPECT_EQ(stats.meshes_failed, 0);
  EXPECT_EQ(stats.live_meshes, 2);
  EXPECT_EQ(stats.canonical_meshes, 1);
  EXPECT_EQ(stats.last_live_seq, 4);
  EXPECT_EQ(stats.last_live_vertices, 121);
  EXPECT_EQ(stats.last_live_triangles, 200);
  EXPECT_GT(stats.mesh_bytes, 3 * 100);
  EXPECT_EQ(receiver->live_seq(), 4);
  EXPECT_EQ(receiver->canonical_seq(), 3);
  EXPECT_EQ(receiver->version(), 3);

  // Before Finish: both PLYs of frame 3, the live PLY of frame 4, and frame 3's PNG (written as
  // soon as its canonical mesh arrived); frame 4's PNG still waits for a canonical mesh.
  const std::string out = options.save_dir;
  EXPECT_TRUE(fs::exists(out + "/frame-000003.mesh.ply"));
  EXPECT_TRUE(fs::exists(out + "/frame-000003.canonical.ply"));
  EXPECT_TRUE(fs::exists(out + "/frame-000004.mesh.ply"));
  EXPECT_TRUE(fs::exists(out + "/frame-000003.png"));
  EXPECT_FALSE(fs::exists(out + "/frame-000004.png"));
  ASSERT_TRUE(receiver->Finish().ok());
  EXPECT_TRUE(fs::exists(out + "/frame-000004.png"));
  EXPECT_TRUE(fs::exists(out + "/final.png"));
  EXPECT_EQ(receiver->written_paths().size(), 6u);
  EXPECT_EQ(stats.files_written, 6);
  EXPECT_EQ(stats.write_failures, 0);

  // PLYs read back with the counts sent.
  auto ply3 = ReadPly(out + "/frame-000003.mesh.ply");
  auto canon3 = ReadPly(out + "/frame-000003.canonical.ply");
  auto ply4 = ReadPly(out + "/frame-000004.mesh.ply");
  ASSERT_TRUE(ply3.ok() && canon3.ok() && ply4.ok()) << ply3.status().ToString();
  EXPECT_EQ(ply3->num_vertices(), 169u);
  EXPECT_EQ(ply3->num_triangles(), 288u);
  EXPECT_EQ(canon3->num_vertices(), 169u);
  EXPECT_EQ(ply4->num_vertices(), 121u);
  EXPECT_EQ(ply4->num_triangles(), 200u);
  EXPECT_EQ(ply4->colors[2], 220);

  // PNGs are not blank: the grid fills most of the fitted view.
  for (const char* name : {"frame-000003.png", "frame-000004.png", "final.png"}) {
    const int64_t covered = CoveredPixels(out + "/" + name);
    EXPECT_GT(covered, 320 * 240 / 3) << name;
  }
  // Frame 3 is coloured by canonical position (red follows canonical x: a ramp across the
  // image); frame 4 had no canonical mesh and shows its own blue.
  const cv::Mat png3 = cv::imread(out + "/frame-000003.png");
  const cv::Mat png4 = cv::imread(out + "/frame-000004.png");
  ASSERT_FALSE(png3.empty());
  ASSERT_FALSE(png4.empty());
  const cv::Vec3b left3 = png3.at<cv::Vec3b>(120, 30), right3 = png3.at<cv::Vec3b>(120, 290);
  EXPECT_GT(right3[2], left3[2] + 120);
  for (int x = 30; x <= 290; x += 20) {
    const cv::Vec3b px = png4.at<cv::Vec3b>(120, x);
    EXPECT_GT(px[0], 2 * px[2]) << x;
  }
}

TEST_F(ReceiverTest, CanonicalVertexOrderSurvivesDracoSoColoursFollowTheSurface) {
  // The premise of canonical colouring: live and canonical meshes of one frame share
  // connectivity, so after Draco (which reorders vertices) vertex i still matches vertex i.
  ReceiverOptions options;
  auto receiver = Make(options);
  const TriangleMesh canonical = Grid(20, 0.f, 1, 2, 3);
  TriangleMesh live = canonical;
  // The live surface: the canonical one bent and shifted.
  for (size_t i = 0; i < live.positions.size(); i += 3) {
    live.positions[i + 2] += 0.5f * live.positions[i] * live.positions[i] + 0.1f;
    live.positions[i + 1] += 0.05f;
  }
  PublishMesh(canonical, 9, vdeform::mesh_t::KIND_CANONICAL);
  PublishMesh(live, 9, vdeform::mesh_t::KIND_LIVE);
  Drain();
  ASSERT_NE(receiver->live_mesh(), nullptr);
  ASSERT_NE(receiver->canonical_mesh(), nullptr);
  const TriangleMesh& l = *receiver->live_mesh();
  const TriangleMesh& c = *receiver->canonical_mesh();
  ASSERT_EQ(l.num_vertices(), c.num_vertices());
  EXPECT_EQ(l.triangles, c.triangles);
  double worst = 0;
  for (size_t i = 0; i < l.positions.size(); i += 3) {
    const double expect_z = c.positions[i + 2] + 0.5 * c.positions[i] * c.positions[i] + 0.1;
    worst = std::max({worst, static_cast<double>(std::abs(l.positions[i] - c.positions[i])), std::abs(l.positions[i + 1] - c.positions[i + 1] - 0.05),
                      std::abs(l.positions[i + 2] - expect_z)});
  }
  EXPECT_LT(worst, 1e-3);
  const VertexColors colors = SelectVertexColors(l, receiver->live_seq(), &c, receiver->canonical_seq(), ColorMode::kCanonical);
  EXPECT_EQ(colors.used, ColorMode::kCanonical);
}

TEST_F(ReceiverTest, RepeatedMeshesAreCountedNotSavedTwice) {
  ScratchDir dir;
  ReceiverOptions options;
  options.save_dir = dir.path();
  auto receiver = Make(options);
  const TriangleMesh mesh = Grid(4, 0.5f, 9, 9, 9);
  PublishMesh(mesh, 7, vdeform::mesh_t::KIND_LIVE);
  PublishMesh(mesh, 7, vdeform::mesh_t::KIND_LIVE);
  PublishMesh(mesh, 7, vdeform::mesh_t::KIND_CANONICAL);
  PublishMesh(mesh, 7, vdeform::mesh_t::KIND_CANONICAL);
  Drain();
  EXPECT_EQ(receiver->stats().meshes_decoded, 4);
  EXPECT_EQ(receiver->stats().live_meshes, 1);
  EXPECT_EQ(receiver->stats().canonical_meshes, 1);
  EXPECT_EQ(receiver->stats().repeated_meshes, 2);
  EXPECT_EQ(receiver->written_paths().size(), 2u);
  ASSERT_TRUE(receiver->Finish().ok());
  EXPECT_EQ(receiver->written_paths().size(), 2u);  // no PNGs without write_png
}

TEST_F(ReceiverTest, CorruptMessagesAreCountedAndDoNotStopDecoding) {
  ReceiverOptions options;
  auto receiver = Make(options);
  const TriangleMesh mesh = Grid(6, 0.5f, 9, 9, 9);
  auto good = MeshToMessage(mesh, 1, 1, vdeform::mesh_t::KIND_LIVE);
  ASSERT_TRUE(good.ok());
  const std::vector<uint8_t> wire = Encode(*good);

  // 1. Random bytes.
  std::vector<uint8_t> garbage(300);
  for (size_t i = 0; i < garbage.size(); ++i) garbage[i] = static_cast<uint8_t>(i * 37 + 11);
  lcm_.publish(kMeshChannel, garbage.data(), static_cast<unsigned>(garbage.size()));
  // 2. Truncated message.
  lcm_.publish(kMeshChannel, wire.data(), static_cast<unsigned>(wire.size() / 2));
  // 3. Well-formed message whose Draco payload is damaged.
  vdeform::mesh_t damaged = *good;
  for (size_t i = damaged.data.size() / 3; i < damaged.data.size(); i += 3) damaged.data[i] ^= 0x5a;
  lcm_.publish(kMeshChannel, &damaged);
  // 4. Counts that disagree with the payload.
  vdeform::mesh_t wrong_counts = *good;
  wrong_counts.num_vertices += 1;
  lcm_.publish(kMeshChannel, &wrong_counts);
  // 5. Unknown kind; 6. a declared data size of 2^31-1 bytes in a short message.
  vdeform::mesh_t bad_kind = *good;
  bad_kind.kind = 7;
  lcm_.publish(kMeshChannel, &bad_kind);
  std::vector<uint8_t> huge = wire;
  const size_t size_at = 8 + 8 + 8 + 1 + 4 + 4 + 1;
  huge[size_at] = 0x7f;
  huge[size_at + 1] = huge[size_at + 2] = huge[size_at + 3] = 0xff;
  lcm_.publish(kMeshChannel, huge.data(), static_cast<unsigned>(huge.size()));
  // A broken status message as well.
  lcm_.publish(kStatusChannel, garbage.data(), 40);
  // Then a good one still decodes.
  lcm_.publish(kMeshChannel, &*good);
  Drain();

  const ReceiverStats& stats = receiver->stats();
  EXPECT_EQ(stats.mesh_messages, 7);
  // The damaged Draco payload may or may not decode to 49 vertices: either way it is no crash,
  // and a decodable one counts as the live mesh of seq 1 (then the good copy is a repeat).
  EXPECT_GE(stats.meshes_failed, 5);
  EXPECT_EQ(stats.meshes_failed + stats.meshes_decoded, 7);
  EXPECT_EQ(stats.live_meshes, 1);
  EXPECT_EQ(stats.status_failed, 1);
  EXPECT_EQ(stats.internal_errors, 0);
  ASSERT_NE(receiver->live_mesh(), nullptr);
  EXPECT_EQ(receiver->live_mesh()->num_vertices(), 49u);
  const std::string summary = SummaryText(stats, receiver->last_status(), receiver->written_paths());
  EXPECT_NE(summary.find("failed " + std::to_string(stats.meshes_failed)), std::string::npos) << summary;
}

// With the server's output key (--key-file): a forged unsigned mesh and one signed under another
// key are neither shown nor saved, and are counted by reason; a real mesh replayed (an out_seq not
// after the last taken) is refused; a restarted server (new epoch, later utime) is taken; status
// messages are checked alike (a forged one does not become last_status).
TEST_F(ReceiverTest, WithAKeyOnlyTheServersSignedOutputIsShownAndSaved) {
  const std::string key(32, '\x51');
  ScratchDir dir;
  ReceiverOptions options;
  options.save_dir = dir.path();
  options.output_key = key;
  options.request_mesh = false;
  auto receiver = Make(options);
  const TriangleMesh mesh = Grid(4, 0.5f, 9, 9, 9);
  // The server's run 5; each message signed under `signer` (empty: unsigned) with its out_seq.
  auto mesh_msg = [&](int64_t seq, int64_t epoch, int64_t out_seq, int64_t utime, const std::string& signer) {
    auto msg = MeshToMessage(mesh, utime, seq, vdeform::mesh_t::KIND_LIVE);
    EXPECT_TRUE(msg.ok());
    msg->epoch = epoch;
    msg->out_seq = out_seq;
    if (!signer.empty()) {
      EXPECT_TRUE(SignMesh(signer, &*msg).ok());
    }
    return *msg;
  };
  auto publish_mesh = [&](int64_t seq, int64_t epoch, int64_t out_seq, int64_t utime, const std::string& signer) {
    const vdeform::mesh_t msg = mesh_msg(seq, epoch, out_seq, utime, signer);
    lcm_.publish(kMeshChannel, &msg);
  };
  const vdeform::mesh_t real = mesh_msg(1, 5, 10, 1000, key);
  lcm_.publish(kMeshChannel, &real);
  publish_mesh(900, 5, 11, 1000, "");
  publish_mesh(901, 5, 12, 1000, std::string(32, '\x52'));
  publish_mesh(2, 5, 13, 1001, key);
  // The first real mesh again, recorded and played back: its out_seq 10 is not after 13.
  lcm_.publish(kMeshChannel, &real);
  // A forged status naming frame 900, then a real one.
  vdeform::server_status_t forged_status = Status(vdeform::server_status_t::STATE_TRACKING, 901);
  forged_status.epoch = 5;
  forged_status.out_seq = 14;
  lcm_.publish(kStatusChannel, &forged_status);
  vdeform::server_status_t real_status = Status(vdeform::server_status_t::STATE_TRACKING, 3);
  real_status.epoch = 5;
  real_status.out_seq = 15;
  ASSERT_TRUE(SignStatus(key, &real_status).ok());
  lcm_.publish(kStatusChannel, &real_status);
  Drain();
  ReceiverStats stats = receiver->stats();
  EXPECT_TRUE(stats.verifying);
  EXPECT_EQ(stats.mesh_messages, 5);
  EXPECT_EQ(stats.meshes_decoded, 2);
  EXPECT_EQ(stats.live_meshes, 2);
  EXPECT_EQ(stats.last_live_seq, 2);
  EXPECT_EQ(stats.meshes_refused.unsigned_messages, 1);
  EXPECT_EQ(stats.meshes_refused.bad_signature, 1);
  EXPECT_EQ(stats.meshes_refused.replayed, 1);
  EXPECT_EQ(stats.status_refused.unsigned_messages, 1);
  EXPECT_EQ(stats.status_messages, 1);
  ASSERT_TRUE(receiver->last_status().has_value());
  EXPECT_EQ(receiver->last_status()->frames_processed, 3) << "the forged status is not shown";
  EXPECT_FALSE(fs::exists(dir / "frame-000900.mesh.ply"));
  EXPECT_FALSE(fs::exists(dir / "frame-000901.mesh.ply"));
  EXPECT_EQ(receiver->written_paths(),
            (std::vector<std::string>{dir / "frame-000001.mesh.ply", dir / "frame-000002.mesh.ply"}));

  // The server restarted: a new epoch counting from 1 again, with later times, is taken; its
  // earlier run is then a replay even with a higher out_seq.
  publish_mesh(0, 6, 1, 2000, key);
  publish_mesh(3, 5, 99, 1500, key);
  Drain();
  stats = receiver->stats();
  EXPECT_EQ(stats.live_meshes, 3);
  EXPECT_EQ(stats.last_live_seq, 0);
  EXPECT_EQ(stats.meshes_refused.replayed, 2);
  EXPECT_FALSE(fs::exists(dir / "frame-000003.mesh.ply"));
  // The status line and the summary say what was refused.
  EXPECT_NE(StatusLine(stats, receiver->last_status()).find("refused 5 (not signed by the server)"),
            std::string::npos)
      << StatusLine(stats, receiver->last_status());
  const std::string summary = SummaryText(stats, receiver->last_status(), receiver->written_paths());
  EXPECT_NE(summary.find("refused under --key-file: meshes 1 unsigned, 1 bad signature, 2 replayed; status 1 "
                         "unsigned, 0 bad signature, 0 replayed"),
            std::string::npos)
      << summary;
}

// Without a key the same forged mesh is shown and saved, as before signing existed.
TEST_F(ReceiverTest, WithoutAKeyUnsignedMeshesAreShown) {
  ScratchDir dir;
  ReceiverOptions options;
  options.save_dir = dir.path();
  options.request_mesh = false;
  auto receiver = Make(options);
  PublishMesh(Grid(4, 0.5f, 9, 9, 9), 900, vdeform::mesh_t::KIND_LIVE);
  Drain();
  EXPECT_FALSE(receiver->stats().verifying);
  EXPECT_EQ(receiver->stats().live_meshes, 1);
  EXPECT_TRUE(fs::exists(dir / "frame-000900.mesh.ply"));
  EXPECT_EQ(SummaryText(receiver->stats(), receiver->last_status(), receiver->written_paths()).find("--key-file"),
            std::string::npos);
}

TEST_F(ReceiverTest, RunStopsAfterCountAndTimesOutWhenNothingArrives) {
  auto receiver = Make(ReceiverOptions{});
  for (int seq = 0; seq < 3; ++seq) PublishMesh(Grid(3, 0.2f, 1, 1, 1), seq, vdeform::mesh_t::KIND_LIVE);
  RunOptions run;
  run.count = 2;
  run.timeout_s = 5.0;
  run.poll_ms = 20;
  int ticks = 0;
  auto t0 = Clock::now();
  ASSERT_TRUE(receiver->Run(run, nullptr, [&] { ++ticks; }).ok());
  EXPECT_EQ(receiver->stats().live_meshes, 2);
  EXPECT_EQ(ticks, 2);
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t0).count(), 1.0);

  // Nothing more arrives (after the queued third mesh): the time-out fires after ~0.3 s.
  run.count = 0;
  run.timeout_s = 0.3;
  t0 = Clock::now();
  const vd::Status timed_out = receiver->Run(run, nullptr, {});
  const double waited = std::chrono::duration<double>(Clock::now() - t0).count();
  EXPECT_EQ(timed_out.code(), StatusCode::kDeadlineExceeded);
  EXPECT_NE(timed_out.message().find("no mesh or status message arrived for 0.3 s"), std::string::npos)
      << timed_out.message();
  EXPECT_GE(waited, 0.28);
  EXPECT_LT(waited, 1.0);
  EXPECT_EQ(receiver->stats().live_meshes, 3);

  // A stop request ends the run at once, successfully.
  std::atomic<bool> stop{true};
  run.timeout_s = 0;
  EXPECT_TRUE(receiver->Run(run, &stop, {}).ok());
  RunOptions bad;
  bad.timeout_s = -1;
  EXPECT_FALSE(receiver->Run(bad, &stop, {}).ok());
}

TEST_F(ReceiverTest, RefusesUnusableOptions) {
  ScratchDir dir;
  ReceiverOptions png_without_dir;
  png_without_dir.write_png = true;
  EXPECT_FALSE(MeshReceiver::Create(&lcm_, png_without_dir).ok());
  // save_dir below a regular file cannot be created.
  { std::ofstream(dir / "file") << "x"; }
  ReceiverOptions under_file;
  under_file.save_dir = dir / "file/sub";
  auto created = MeshReceiver::Create(&lcm_, under_file);
  ASSERT_FALSE(created.ok());
  EXPECT_NE(created.status().message().find("save directory"), std::string::npos);
  EXPECT_FALSE(MeshReceiver::Create(nullptr, ReceiverOptions{}).ok());
  // The queue capacity is LCM's per-subscription bound (memq ignores it; udpm applies it).
  ReceiverOptions negative_queue;
  negative_queue.mesh_queue_capacity = -1;
  auto refused = MeshReceiver::Create(&lcm_, negative_queue);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("mesh_queue_capacity = -1"), std::string::npos);
  ReceiverOptions deep_queue;
  deep_queue.mesh_queue_capacity = 240;
  EXPECT_TRUE(MeshReceiver::Create(&lcm_, deep_queue).ok());
}

TEST_F(ReceiverTest, EmptyMeshIsSavedAndRendersBackground) {
  // The server publishes an empty mesh before anything is fused (data_size 0).
  ScratchDir dir;
  ReceiverOptions options;
  options.save_dir = dir.path();
  options.write_png = true;
  auto receiver = Make(options);
  PublishMesh(TriangleMesh{}, 0, vdeform::mesh_t::KIND_LIVE);
  Drain();
  EXPECT_EQ(receiver->stats().meshes_decoded, 1);
  EXPECT_EQ(receiver->stats().last_live_vertices, 0);
  ASSERT_TRUE(receiver->Finish().ok());
  auto ply = ReadPly(dir / "frame-000000.mesh.ply");
  ASSERT_TRUE(ply.ok()) << ply.status().ToString();
  EXPECT_EQ(ply->num_vertices(), 0u);
  EXPECT_EQ(CoveredPixels(dir / "frame-000000.png"), 0);
  EXPECT_EQ(CoveredPixels(dir / "final.png"), 0);
}

TEST_F(ReceiverTest, FinishWithoutMeshesWritesNothing) {
  ScratchDir dir;
  ReceiverOptions options;
  options.save_dir = dir.path();
  options.write_png = true;
  auto receiver = Make(options);
  ASSERT_TRUE(receiver->Finish().ok());
  EXPECT_TRUE(receiver->written_paths().empty());
  EXPECT_TRUE(fs::is_empty(dir.path()));
}

}  // namespace
}  // namespace vd
