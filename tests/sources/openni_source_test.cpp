// OpenNI2 sources without a sensor: the Dummy device for the live path, a Dummy recording for
// .oni playback (which must time out, not hang: STACK.md), and the errors for absent devices/files.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <thread>

// OpenNI2's headers live in include/openni2 and include each other by quoted name.
#include <openni2/OpenNI.h>

#include "vd/capture/source.h"

namespace vd {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr double kPi = 3.14159265358979323846;

TEST(OpenNiSource, DummyDeviceDeliversFrames) {
  SourceOptions o;
  o.count = 3;
  auto source = OpenSource("openni2:Dummy", o);
  if (!source.ok()) GTEST_SKIP() << "OpenNI2 Dummy device unavailable: " << source.status().ToString();
  EXPECT_EQ((*source)->NumFrames(), 3);
  EXPECT_DOUBLE_EQ((*source)->NominalFps(), 30.0);
  int64_t last_utime = -1;
  for (int k = 0; k < 3; ++k) {
    auto f = (*source)->Next();
    ASSERT_TRUE(f.ok()) << f.status().ToString();
    ASSERT_TRUE(f->has_value());
    const RgbdFrame& frame = **f;
    ASSERT_TRUE(frame.Validate().ok()) << frame.Validate().ToString();
    EXPECT_EQ(frame.seq, k);
    EXPECT_GT(frame.utime, last_utime);
    last_utime = frame.utime;
    // The Dummy device: 320x240 depth in millimetres plus RGB colour.
    EXPECT_EQ(frame.depth.cols, 320);
    EXPECT_EQ(frame.depth.rows, 240);
    EXPECT_EQ(frame.color.size(), frame.depth.size());
    EXPECT_FLOAT_EQ(frame.depth_scale, 1000.f);
    EXPECT_GT(cv::countNonZero(frame.depth), 0);
    // It reports no field of view: the nominal Kinect v1 58.5 degrees applies.
    EXPECT_NEAR(frame.intrinsics.fx, 320.0 / (2.0 * std::tan(58.5 * kPi / 360.0)), 1e-3);
    EXPECT_FLOAT_EQ(frame.intrinsics.cx, 160.f);
  }
  auto end = (*source)->Next();
  ASSERT_TRUE(end.ok());
  EXPECT_FALSE(end->has_value());
}

TEST(OpenNiSource, DummyDeviceHonoursIntrinsicsOverride) {
  SourceOptions o;
  o.intrinsics = "300,300,160,120";
  o.count = 1;
  auto source = OpenSource("openni2:Dummy", o);
  if (!source.ok()) GTEST_SKIP() << "OpenNI2 Dummy device unavailable: " << source.status().ToString();
  auto f = (*source)->Next();
  ASSERT_TRUE(f.ok() && f->has_value()) << f.status().ToString();
  EXPECT_FLOAT_EQ((*f)->intrinsics.fx, 300.f);
  EXPECT_NE((*source)->Describe().find("--intrinsics"), std::string::npos) << (*source)->Describe();
}

TEST(OpenNiSource, UnknownDeviceListsTheDevicesFound) {
  auto s = OpenSource("openni2:no-such-device-uri", {});
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), StatusCode::kNotFound);
  EXPECT_NE(s.status().message().find("no-such-device-uri"), std::string::npos) << s.status().message();
  EXPECT_NE(s.status().message().find("devices found"), std::string::npos) << s.status().message();
}

TEST(OpenNiSource, NoSensorIsAClearError) {
  auto s = OpenSource("openni2", {});
  if (s.ok()) GTEST_SKIP() << "a real sensor is connected: " << (*s)->Describe();
  EXPECT_EQ(s.status().code(), StatusCode::kNotFound) << s.status().ToString();
  EXPECT_NE(s.status().message().find("devices found: "), std::string::npos) << s.status().message();
  EXPECT_NE(s.status().message().find("openni2:Dummy"), std::string::npos) << s.status().message();
}

TEST(OniSource, MissingFileIsNotFound) {
  auto s = OpenSource("oni:/nonexistent/vd_recording.oni", {});
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), StatusCode::kNotFound);
  EXPECT_NE(s.status().message().find("/nonexistent/vd_recording.oni"), std::string::npos);
}

TEST(OniSource, NotARecordingIsRefused) {
  const fs::path path = fs::temp_directory_path() / ("vd_not_a_recording_" + std::to_string(::getpid()) + ".oni");
  std::ofstream(path) << "plain text, not an ONI recording";
  auto s = OpenSource("oni:" + path.string(), {});
  fs::remove(path);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find(path.string()), std::string::npos) << s.status().message();
}

// Records ~0.2 s of the Dummy device; false when the Dummy device or the recorder is unavailable.
bool RecordDummy(const std::string& path) {
  if (openni::OpenNI::initialize() != openni::STATUS_OK) return false;
  openni::Device device;
  if (device.open("Dummy") != openni::STATUS_OK) return false;
  openni::VideoStream depth, color;
  bool ok = depth.create(device, openni::SENSOR_DEPTH) == openni::STATUS_OK &&
            color.create(device, openni::SENSOR_COLOR) == openni::STATUS_OK && depth.start() == openni::STATUS_OK &&
            color.start() == openni::STATUS_OK;
  if (ok) {
    openni::Recorder recorder;
    ok = recorder.create(path.c_str()) == openni::STATUS_OK && recorder.attach(depth) == openni::STATUS_OK &&
         recorder.attach(color) == openni::STATUS_OK && recorder.start() == openni::STATUS_OK;
    if (ok) std::this_thread::sleep_for(std::chrono::milliseconds(200));
    recorder.stop();
    recorder.destroy();
  }
  depth.stop();
  color.stop();
  // The Dummy device crashes when its streams are destroyed right after stop() (STACK.md).
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  depth.destroy();
  color.destroy();
  device.close();
  return ok;
}

enum class Recorded { kOk, kUnavailable, kHung };

// RecordDummy in a child process, given up after 20 s. The recording is the test's fixture, made
// by OpenNI2's own recorder on its Dummy device, which once hung a parallel suite run until
// ctest's time-out (2026-12-07; 40 runs beside two busy cores did not repeat it). A hang there is
// OpenNI2's, not the source's under test, so it skips the test instead of stalling the suite.
Recorded RecordDummyIsolated(const std::string& path) {
  const pid_t pid = ::fork();
  if (pid < 0) return RecordDummy(path) ? Recorded::kOk : Recorded::kUnavailable;
  if (pid == 0) ::_exit(RecordDummy(path) ? 0 : 1);
  const auto deadline = Clock::now() + std::chrono::seconds(20);
  int status = 0;
  while (::waitpid(pid, &status, WNOHANG) == 0) {
    if (Clock::now() > deadline) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      return Recorded::kHung;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return WIFEXITED(status) && WEXITSTATUS(status) == 0 ? Recorded::kOk : Recorded::kUnavailable;
}

TEST(OniSource, DummyRecordingOpensAndEveryReadTimesOut) {
  const fs::path path = fs::temp_directory_path() / ("vd_dummy_" + std::to_string(::getpid()) + ".oni");
  const Recorded recorded = RecordDummyIsolated(path.string());
  if (recorded == Recorded::kHung) {
    fs::remove(path);
    GTEST_SKIP() << "OpenNI2's recorder hung on the Dummy device for 20 s (the fixture, not the source)";
  }
  if (recorded == Recorded::kUnavailable) GTEST_SKIP() << "cannot record from the OpenNI2 Dummy device";
  SourceOptions o;
  o.read_timeout_s = 0.3;
  auto source = OpenSource("oni:" + path.string(), o);
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  EXPECT_GT((*source)->NumFrames(), 0);
  EXPECT_NE((*source)->Describe().find("oni:"), std::string::npos);
  // Recordings of the Dummy device deliver no frame in playback (STACK.md): the read must give up
  // after the time-out with a clear error; should a future OpenNI2 play it, a frame is fine too.
  const auto t0 = Clock::now();
  auto f = (*source)->Next();
  const double elapsed = std::chrono::duration<double>(Clock::now() - t0).count();
  EXPECT_LT(elapsed, 2.0);
  if (!f.ok()) {
    EXPECT_EQ(f.status().code(), StatusCode::kDeadlineExceeded) << f.status().ToString();
    EXPECT_NE(f.status().message().find("within 0.3 s"), std::string::npos) << f.status().message();
    EXPECT_GE(elapsed, 0.25);
  } else {
    ASSERT_TRUE(f->has_value());
    EXPECT_TRUE((*f)->Validate().ok());
  }
  source->reset();
  fs::remove(path);
}

}  // namespace
}  // namespace vd
