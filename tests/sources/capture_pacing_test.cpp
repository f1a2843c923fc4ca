// FramePacer on LCM's in-process memq:// provider: one lcm::LCM shared by the pacer and a fake
// server thread. The pacer dispatches incoming frames (to the fake server's handler) while it waits;
// the fake server thread publishes the status acknowledgements.
#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <atomic>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "vd/capture/pacing.h"
#include "vd/common/auth.h"
#include "vd/common/messages.h"

namespace vd {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Receives frames (handler runs on whichever thread dispatches, here the pacer's) and acknowledges
// them from its own thread after `work` seconds, following a per-frame policy.
class FakeServer {
 public:
  // ack(seq, copy): whether to acknowledge the copy-th reception (0-based) of frame seq.
  using Policy = std::function<bool(int64_t seq, int copy)>;

  // `output_key`: acknowledgements are signed under it, numbered like a real server's (empty: unsigned).
  FakeServer(lcm::LCM* lcm, std::string ack_source_id, double work_s, Policy policy, std::string output_key = "")
      : lcm_(lcm),
        ack_source_id_(std::move(ack_source_id)),
        work_s_(work_s),
        policy_(std::move(policy)),
        output_key_(std::move(output_key)) {
    sub_ = lcm_->subscribe(kFrameChannel, &FakeServer::OnFrame, this);
    thread_ = std::thread([this] { Run(); });
  }
  ~FakeServer() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_ = true;
    }
    cv_.notify_all();
    thread_.join();
    lcm_->unsubscribe(sub_);
  }

  std::vector<int64_t> received() {
    std::lock_guard<std::mutex> lock(mutex_);
    return received_;
  }
  // Time each frame was received, and time each acknowledgement was published.
  std::vector<Clock::time_point> receive_times() {
    std::lock_guard<std::mutex> lock(mutex_);
    return receive_times_;
  }
  std::vector<Clock::time_point> ack_times() {
    std::lock_guard<std::mutex> lock(mutex_);
    return ack_times_;
  }

 private:
  void OnFrame(const lcm::ReceiveBuffer*, const std::string&, const vdeform::rgbd_frame_t* msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    int copy = 0;
    for (int64_t s : received_) copy += s == msg->seq;
    received_.push_back(msg->seq);
    receive_times_.push_back(Clock::now());
    if (policy_(msg->seq, copy)) queue_.push_back(msg->seq);
    cv_.notify_all();
  }

  void Run() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (true) {
      cv_.wait(lock, [this] { return done_ || !queue_.empty(); });
      if (done_) return;
      const int64_t seq = queue_.front();
      queue_.pop_front();
      lock.unlock();
      std::this_thread::sleep_for(std::chrono::duration<double>(work_s_));
      vdeform::server_status_t status{};
      status.state = vdeform::server_status_t::STATE_TRACKING;
      status.last_processed_seq = seq;
      status.last_source_id = ack_source_id_;
      status.epoch = 42;
      status.out_seq = ++out_seq_;
      if (!output_key_.empty()) {
        EXPECT_TRUE(SignStatus(output_key_, &status).ok());
      }
      const auto t = Clock::now();
      lcm_->publish(kStatusChannel, &status);
      lock.lock();
      ack_times_.push_back(t);
    }
  }

  lcm::LCM* lcm_;
  std::string ack_source_id_;
  double work_s_;
  Policy policy_;
  std::string output_key_;
  int64_t out_seq_ = 0;
  lcm::Subscription* sub_ = nullptr;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<int64_t> queue_;
  std::vector<int64_t> received_;
  std::vector<Clock::time_point> receive_times_;
  std::vector<Clock::time_point> ack_times_;
  bool done_ = false;
  std::thread thread_;
};

vdeform::rgbd_frame_t Frame(int64_t seq) {
  vdeform::rgbd_frame_t msg{};
  msg.seq = seq;
  msg.source_id = "test-source";
  msg.width = 4;
  msg.height = 2;
  msg.depth_encoding = vdeform::rgbd_frame_t::DEPTH_RAW16;
  msg.depth_size = 16;
  msg.depth_data.assign(16, 7);
  msg.color_encoding = vdeform::rgbd_frame_t::COLOR_NONE;
  return msg;
}

PacingOptions Lockstep(double timeout_s, int retries) {
  PacingOptions o;
  o.fps = 0.0;
  o.lockstep = true;
  o.lockstep_timeout_s = timeout_s;
  o.lockstep_retries = retries;
  o.source_id = "test-source";
  return o;
}

TEST(FramePacer, LockstepSendsNextFrameOnlyAfterAcknowledgement) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  FakeServer server(&lcm, "test-source", 0.05, [](int64_t, int) { return true; });
  auto pacer = FramePacer::Create(&lcm, Lockstep(2.0, 3));
  ASSERT_TRUE(pacer.ok()) << pacer.status().ToString();
  const auto t0 = Clock::now();
  for (int64_t k = 0; k < 5; ++k) {
    const auto before = Clock::now();
    ASSERT_TRUE((*pacer)->Send(Frame(k)).ok());
    // Each Send covers the server's 50 ms of work.
    EXPECT_GE(SecondsSince(before), 0.045) << "frame " << k;
  }
  EXPECT_LT(SecondsSince(t0), 1.5);
  EXPECT_EQ(server.received(), (std::vector<int64_t>{0, 1, 2, 3, 4}));
  const auto received = server.receive_times();
  const auto acked = server.ack_times();
  ASSERT_EQ(received.size(), 5u);
  ASSERT_GE(acked.size(), 4u);
  // Frame k+1 reached the server only after frame k was acknowledged.
  for (size_t k = 0; k + 1 < received.size(); ++k) EXPECT_GE(received[k + 1], acked[k]) << "frame " << k + 1;
  EXPECT_EQ((*pacer)->stats().published, 5);
  EXPECT_EQ((*pacer)->stats().resends, 0);
  EXPECT_EQ((*pacer)->stats().last_acked_seq, 4);
}

TEST(FramePacer, LockstepResendsAfterTimeout) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  // The first copy of frame 1 is "lost": never acknowledged.
  FakeServer server(&lcm, "test-source", 0.0, [](int64_t seq, int copy) { return !(seq == 1 && copy == 0); });
  auto pacer = FramePacer::Create(&lcm, Lockstep(0.2, 3));
  ASSERT_TRUE(pacer.ok());
  const auto t0 = Clock::now();
  for (int64_t k = 0; k < 3; ++k) ASSERT_TRUE((*pacer)->Send(Frame(k)).ok()) << "frame " << k;
  const double elapsed = SecondsSince(t0);
  EXPECT_GE(elapsed, 0.19);
  EXPECT_LT(elapsed, 1.0);
  EXPECT_EQ(server.received(), (std::vector<int64_t>{0, 1, 1, 2}));
  EXPECT_EQ((*pacer)->stats().published, 4);
  EXPECT_EQ((*pacer)->stats().resends, 1);
}

TEST(FramePacer, LockstepGivesUpAfterRetries) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  FakeServer server(&lcm, "test-source", 0.0, [](int64_t, int) { return false; });
  auto pacer = FramePacer::Create(&lcm, Lockstep(0.1, 2));
  ASSERT_TRUE(pacer.ok());
  const auto t0 = Clock::now();
  const Status s = (*pacer)->Send(Frame(0));
  const double elapsed = SecondsSince(t0);
  EXPECT_EQ(s.code(), StatusCode::kDeadlineExceeded) << s.ToString();
  EXPECT_NE(s.message().find("frame 0"), std::string::npos) << s.message();
  // One send plus two re-sends, 0.1 s each.
  EXPECT_GE(elapsed, 0.29);
  EXPECT_LT(elapsed, 1.0);
  EXPECT_EQ(server.received(), (std::vector<int64_t>{0, 0, 0}));
  EXPECT_EQ((*pacer)->stats().resends, 2);
}

TEST(FramePacer, LockstepIgnoresAcknowledgementsForOtherSources) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  FakeServer server(&lcm, "someone-else", 0.0, [](int64_t, int) { return true; });
  auto pacer = FramePacer::Create(&lcm, Lockstep(0.1, 0));
  ASSERT_TRUE(pacer.ok());
  EXPECT_EQ((*pacer)->Send(Frame(0)).code(), StatusCode::kDeadlineExceeded);
  EXPECT_EQ((*pacer)->stats().last_acked_seq, -1);
}

TEST(FramePacer, StopEndsALockstepWaitEarly) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  std::atomic<bool> stop{false};
  auto pacer = FramePacer::Create(&lcm, Lockstep(10.0, 3), &stop);
  ASSERT_TRUE(pacer.ok());
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    stop = true;
  });
  const auto t0 = Clock::now();
  EXPECT_TRUE((*pacer)->Send(Frame(0)).ok());
  stopper.join();
  EXPECT_LT(SecondsSince(t0), 1.0);
}

TEST(FramePacer, RateLimitsAndMaxRateDoesNot) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  PacingOptions o;
  o.fps = 50.0;
  o.source_id = "test-source";
  auto paced = FramePacer::Create(&lcm, o);
  ASSERT_TRUE(paced.ok());
  auto t0 = Clock::now();
  for (int64_t k = 0; k < 11; ++k) ASSERT_TRUE((*paced)->Send(Frame(k)).ok());
  // 11 frames at 50 Hz: the last leaves 10 periods after the first.
  const double paced_s = SecondsSince(t0);
  EXPECT_GE(paced_s, 0.195);
  EXPECT_LT(paced_s, 0.6);

  o.fps = 0.0;
  auto unpaced = FramePacer::Create(&lcm, o);
  ASSERT_TRUE(unpaced.ok());
  t0 = Clock::now();
  for (int64_t k = 0; k < 11; ++k) ASSERT_TRUE((*unpaced)->Send(Frame(k)).ok());
  EXPECT_LT(SecondsSince(t0), 0.1);
  EXPECT_EQ((*unpaced)->stats().published, 11);
}

TEST(FramePacer, ValidateNamesTheField) {
  lcm::LCM lcm("memq://");
  PacingOptions o;
  o.source_id = "x";
  o.fps = -1.0;
  auto bad = FramePacer::Create(&lcm, o);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("fps"), std::string::npos);
  o.fps = 30.0;
  o.lockstep_retries = -2;
  EXPECT_NE(o.Validate().message().find("lockstep_retries"), std::string::npos);
  o.lockstep_retries = 3;
  o.source_id.clear();
  EXPECT_NE(o.Validate().message().find("source_id"), std::string::npos);
}

}  // namespace
}  // namespace vd

namespace vd {
namespace {

TEST(FramePacer, MalformedStatusMessagesAreCountedNotFatal) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  auto pacer = FramePacer::Create(&lcm, Lockstep(0.1, 0));
  ASSERT_TRUE(pacer.ok());
  // Garbage, and a valid header declaring a huge array.
  const std::vector<uint8_t> garbage = {1, 2, 3, 4, 5};
  ASSERT_EQ(lcm.publish(kStatusChannel, garbage.data(), static_cast<unsigned>(garbage.size())), 0);
  vdeform::server_status_t status{};
  status.last_source_id = "test-source";
  status.last_processed_seq = 0;
  std::vector<uint8_t> bytes(static_cast<size_t>(status.getEncodedSize()));
  ASSERT_GT(status.encode(bytes.data(), 0, static_cast<int>(bytes.size())), 0);
  std::vector<uint8_t> truncated(bytes.begin(), bytes.begin() + bytes.size() / 2);
  ASSERT_EQ(lcm.publish(kStatusChannel, truncated.data(), static_cast<unsigned>(truncated.size())), 0);
  EXPECT_EQ((*pacer)->Send(Frame(0)).code(), StatusCode::kDeadlineExceeded);
  EXPECT_EQ((*pacer)->stats().bad_status_messages, 2);
  EXPECT_EQ((*pacer)->stats().last_acked_seq, -1);
}

}  // namespace
}  // namespace vd

namespace vd {
namespace {

// A lockstep client restarted under the same source id: the server's status still names the last
// frame of the earlier run (seq 5 of epoch 1), which must not acknowledge frames 0..5 of this one.
TEST(FramePacer, AStatusAboutAnEarlierRunAcknowledgesNothing) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  auto pacer = FramePacer::Create(&lcm, Lockstep(0.2, 0));
  ASSERT_TRUE(pacer.ok());
  auto publish = [&](int64_t epoch, int64_t seq) {
    vdeform::server_status_t status{};
    status.last_source_id = "test-source";
    status.last_processed_seq = seq;
    status.last_epoch = epoch;
    ASSERT_EQ(lcm.publish(kStatusChannel, &status), 0);
  };
  auto frame = [](int64_t epoch, int64_t seq) {
    vdeform::rgbd_frame_t m = Frame(seq);
    m.epoch = epoch;
    return m;
  };
  publish(1, 5);
  EXPECT_EQ((*pacer)->Send(frame(2, 0)).code(), StatusCode::kDeadlineExceeded);
  EXPECT_EQ((*pacer)->stats().last_acked_seq, -1);
  publish(2, 0);
  EXPECT_TRUE((*pacer)->Send(frame(2, 1)).code() == StatusCode::kDeadlineExceeded) << "seq 0 does not ack seq 1";
  EXPECT_EQ((*pacer)->stats().last_acked_seq, 0);
  publish(1, 9);
  publish(2, 2);
  EXPECT_TRUE((*pacer)->Send(frame(2, 2)).ok());
  EXPECT_EQ((*pacer)->stats().last_acked_seq, 2);
}

// A forger on the group publishes, before each frame, an unsigned status and one signed under
// another key, both naming the frame about to be sent. Without the output key they release the
// pacer at once (the server would get frames faster than it works); with it the pacer waits for the
// real server's signed acknowledgement of each frame and counts the forgeries it ignored.
TEST(FramePacer, WithTheOutputKeyOnlyTheServersSignedStatusAcknowledges) {
  const std::string key(32, '\x24');
  for (const bool with_key : {false, true}) {
    SCOPED_TRACE(with_key ? "with the output key" : "without it");
    lcm::LCM lcm("memq://");
    ASSERT_TRUE(lcm.good());
    FakeServer server(&lcm, "test-source", 0.05, [](int64_t, int) { return true; }, key);
    PacingOptions options = Lockstep(2.0, 0);
    if (with_key) options.output_key = key;
    auto pacer = FramePacer::Create(&lcm, options);
    ASSERT_TRUE(pacer.ok());
    int64_t forged_out_seq = 1000;
    auto forge = [&](int64_t seq, const std::string& signer) {
      vdeform::server_status_t status{};
      status.state = vdeform::server_status_t::STATE_TRACKING;
      status.last_processed_seq = seq;
      status.last_source_id = "test-source";
      status.epoch = 42;
      status.out_seq = ++forged_out_seq;
      if (!signer.empty()) {
        ASSERT_TRUE(SignStatus(signer, &status).ok());
      }
      ASSERT_EQ(lcm.publish(kStatusChannel, &status), 0);
    };
    int fast_sends = 0;
    for (int64_t k = 0; k < 4; ++k) {
      forge(k, "");
      forge(k, std::string(32, '\x25'));
      const auto before = Clock::now();
      ASSERT_TRUE((*pacer)->Send(Frame(k)).ok()) << "frame " << k;
      // The server's acknowledgement takes its 50 ms of work.
      fast_sends += SecondsSince(before) < 0.045;
    }
    const OutputRefusals& refused = (*pacer)->stats().status_refused;
    if (with_key) {
      EXPECT_EQ(fast_sends, 0) << "a forged status released the pacer";
      EXPECT_EQ(refused.unsigned_messages, 4);
      EXPECT_EQ(refused.bad_signature, 4);
      // Every frame reached the server only after the real acknowledgement of the one before.
      const auto received = server.receive_times();
      const auto acked = server.ack_times();
      ASSERT_EQ(received.size(), 4u);
      ASSERT_GE(acked.size(), 3u);
      for (size_t k = 0; k + 1 < received.size(); ++k) EXPECT_GE(received[k + 1], acked[k]) << "frame " << k + 1;
    } else {
      EXPECT_EQ(fast_sends, 4) << "the control: unverified status is taken as it comes";
      EXPECT_EQ(refused.total(), 0);
    }
  }
}

// The real server's signed status played back by a recorder (one the pacer took before) is counted
// as a replay and ignored.
TEST(FramePacer, AReplayedSignedStatusIsIgnored) {
  const std::string key(32, '\x24');
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  PacingOptions options = Lockstep(0.2, 0);
  options.output_key = key;
  auto pacer = FramePacer::Create(&lcm, options);
  ASSERT_TRUE(pacer.ok());
  vdeform::server_status_t status{};
  status.last_source_id = "test-source";
  status.last_processed_seq = 0;
  status.epoch = 42;
  status.out_seq = 7;
  ASSERT_TRUE(SignStatus(key, &status).ok());
  ASSERT_EQ(lcm.publish(kStatusChannel, &status), 0);
  EXPECT_TRUE((*pacer)->Send(Frame(0)).ok());
  ASSERT_EQ(lcm.publish(kStatusChannel, &status), 0);
  EXPECT_EQ((*pacer)->Send(Frame(1)).code(), StatusCode::kDeadlineExceeded);
  EXPECT_EQ((*pacer)->stats().status_refused.replayed, 1);
  EXPECT_EQ((*pacer)->stats().last_acked_seq, 0);
}

TEST(FramePacer, ShortStallsKeepTheMeanRate) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  PacingOptions o;
  o.fps = 50.0;
  o.source_id = "test-source";
  auto pacer = FramePacer::Create(&lcm, o);
  ASSERT_TRUE(pacer.ok());
  const auto t0 = Clock::now();
  for (int64_t k = 0; k < 11; ++k) {
    // Frames 1, 5 and 9 take the "source" 50 ms, 2.5 periods; 12.5 ms per frame on average.
    if (k % 4 == 1) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    ASSERT_TRUE((*pacer)->Send(Frame(k)).ok());
  }
  // The schedule catches up after each stall: the last frame leaves 30 ms after its slot at
  // 180 ms (restarting the schedule after each stall would take ~290 ms).
  const double elapsed = SecondsSince(t0);
  EXPECT_GE(elapsed, 0.195);
  EXPECT_LT(elapsed, 0.26);
}

}  // namespace
}  // namespace vd
