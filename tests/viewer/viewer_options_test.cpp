#include <string>
#include <vector>

#include <algorithm>

#include <gtest/gtest.h>

#include "vd/viewer/display.h"
#include "vd/viewer/status_text.h"
#include "vd/viewer/viewer_options.h"

namespace vd {
namespace {

TEST(ViewerOptionsTest, DefaultsAndEveryFlag) {
  auto defaults = ParseViewerArgs({});
  ASSERT_TRUE(defaults.ok());
  EXPECT_FALSE(defaults->headless);
  EXPECT_EQ(defaults->image_width, 640);
  EXPECT_EQ(defaults->image_height, 480);
  EXPECT_EQ(defaults->count, 0);
  EXPECT_EQ(defaults->timeout_s, 0.0);
  EXPECT_EQ(defaults->color_mode, ColorMode::kCanonical);

  auto all = ParseViewerArgs({"--lcm-url", "memq://", "--headless", "--save-dir", "/tmp/x", "--png", "--png-size",
                              "320x200", "--count", "12", "--timeout=2.5", "--quiet", "--color", "vertex",
                              "--no-request"});
  ASSERT_TRUE(all.ok()) << all.status().ToString();
  EXPECT_EQ(all->lcm_url, "memq://");
  EXPECT_TRUE(all->headless);
  EXPECT_EQ(all->save_dir, "/tmp/x");
  EXPECT_TRUE(all->png);
  EXPECT_EQ(all->image_width, 320);
  EXPECT_EQ(all->image_height, 200);
  EXPECT_EQ(all->count, 12);
  EXPECT_DOUBLE_EQ(all->timeout_s, 2.5);
  EXPECT_TRUE(all->quiet);
  EXPECT_EQ(all->color_mode, ColorMode::kVertex);
  EXPECT_TRUE(all->no_request);
  EXPECT_FALSE(all->help);

  auto help = ParseViewerArgs({"--help"});
  ASSERT_TRUE(help.ok());
  EXPECT_TRUE(help->help);
}

TEST(ViewerOptionsTest, BadFlagsNameTheFlag) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--bogus"}, "--bogus"},
      {{"--count"}, "--count needs a value"},
      {{"--count", "abc"}, "--count"},
      {{"--count", "-3"}, "--count"},
      {{"--timeout", "-1"}, "--timeout"},
      {{"--timeout", "nan"}, "--timeout"},
      {{"--png-size", "640"}, "--png-size"},
      {{"--png-size", "8x8"}, "--png-size"},
      {{"--png-size", "640x48000"}, "--png-size"},
      {{"--png"}, "--png needs --save-dir"},
      {{"--color", "rainbow"}, "rainbow"},
      {{"--headless=yes"}, "takes no value"},
      {{"--save-dir", ""}, "--save-dir"},
  };
  for (const auto& [args, expected] : cases) {
    auto parsed = ParseViewerArgs(args);
    ASSERT_FALSE(parsed.ok()) << args[0];
    EXPECT_NE(parsed.status().message().find(expected), std::string::npos) << parsed.status().message();
  }
}

TEST(ViewerOptionsTest, HelpDocumentsEveryFlag) {
  const std::string help = ViewerHelpText();
  for (const char* flag : {"--lcm-url URL", "--headless", "--save-dir DIR", "--png", "--png-size WxH", "--color MODE",
                           "--count N", "--timeout S", "--quiet", "--no-request", "--help"}) {
    // Each flag starts a line of its own.
    const bool listed = help.find(std::string("\n  ") + flag + "\n") != std::string::npos ||
                        help.find(std::string("\n  ") + flag + ",") != std::string::npos;
    EXPECT_TRUE(listed) << flag;
  }
  for (const char* text : {"frame-%06d.mesh.ply", "frame-%06d.canonical.ply", "final.png", "SIGINT", "(default: 640x480)",
                           "(default: canonical)"})
    EXPECT_NE(help.find(text), std::string::npos) << text;
}

TEST(DisplayTest, ParsesDisplayNames) {
  auto local = ParseX11Display(":0");
  ASSERT_TRUE(local.ok());
  EXPECT_EQ(local->host, "");
  EXPECT_EQ(local->number, 0);
  auto screen = ParseX11Display(":99.1");
  ASSERT_TRUE(screen.ok());
  EXPECT_EQ(screen->number, 99);
  auto remote = ParseX11Display("localhost:10.0");
  ASSERT_TRUE(remote.ok());
  EXPECT_EQ(remote->host, "localhost");
  EXPECT_EQ(remote->number, 10);
  EXPECT_FALSE(ParseX11Display("").ok());
  EXPECT_FALSE(ParseX11Display("nohost").ok());
  EXPECT_FALSE(ParseX11Display(":").ok());
  EXPECT_FALSE(ParseX11Display(":x").ok());
  EXPECT_FALSE(ParseX11Display(":123456789").ok());
}

TEST(DisplayTest, UnsetOrUnreachableDisplayIsRefused) {
  // A display number no X server uses, and no Wayland socket.
  const char* old_display = std::getenv("DISPLAY");
  const char* old_wayland = std::getenv("WAYLAND_DISPLAY");
  const std::string saved_display = old_display ? old_display : "";
  const std::string saved_wayland = old_wayland ? old_wayland : "";
  unsetenv("WAYLAND_DISPLAY");
  unsetenv("DISPLAY");
  Status none = CheckDisplay();
  EXPECT_EQ(none.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(none.message().find("$DISPLAY"), std::string::npos);
  setenv("DISPLAY", ":54321", 1);
  Status unreachable = CheckDisplay();
  EXPECT_EQ(unreachable.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(unreachable.message().find("/tmp/.X11-unix/X54321"), std::string::npos) << unreachable.message();
  if (old_display) setenv("DISPLAY", saved_display.c_str(), 1); else unsetenv("DISPLAY");
  if (old_wayland) setenv("WAYLAND_DISPLAY", saved_wayland.c_str(), 1);
}

vdeform::server_status_t TrackingStatus() {
  vdeform::server_status_t s{};
  s.state = vdeform::server_status_t::STATE_TRACKING;
  s.message = "ok";
  s.frames_received = 130;
  s.frames_processed = 120;
  s.frames_dropped = 7;
  s.frames_rejected = 3;
  s.last_processed_seq = 119;
  s.num_stages = 3;
  s.stage_name = {"preprocess", "icp", "fuse"};
  s.stage_ms_last = {1.25f, 8.5f, 3.f};
  s.stage_ms_mean = {1.f, 8.f, 3.f};
  s.fps = 28.75f;
  return s;
}

TEST(StatusTextTest, StatusLineShowsCountersStateAndStages) {
  ReceiverStats stats;
  stats.live_meshes = 120;
  stats.canonical_meshes = 4;
  stats.meshes_failed = 2;
  stats.last_live_seq = 119;
  stats.last_live_triangles = 5000;
  stats.mesh_bytes = 3 * 1024 * 1024;
  EXPECT_EQ(StatusLine(stats, std::nullopt),
            "meshes 120 +4 canon failed 2 seq 119 (5000 tri) 3.0 MB | server: no status yet");
  EXPECT_EQ(StatusLine(stats, TrackingStatus()),
            "meshes 120 +4 canon failed 2 seq 119 (5000 tri) 3.0 MB | TRACKING proc 120 drop 7 rej 3 28.8 fps | "
            "ms: preprocess 1.2 icp 8.5 fuse 3.0");
  // Arrays shorter than num_stages (never from DecodeLcm, but possible in memory) are bounded.
  vdeform::server_status_t odd = TrackingStatus();
  odd.num_stages = 9;
  EXPECT_NE(StatusLine(stats, odd).find("fuse 3.0"), std::string::npos);
  EXPECT_EQ(ServerStateName(vdeform::server_status_t::STATE_TRACKING_LOST), "TRACKING_LOST");
  EXPECT_EQ(ServerStateName(42), "INVALID(42)");
  // Latency appears once the server measured one.
  vdeform::server_status_t timed = TrackingStatus();
  timed.latency_ms_p50 = 41.4f;
  timed.latency_ms_p95 = 88.6f;
  EXPECT_NE(StatusLine(stats, timed).find("28.8 fps lat 41/89 ms | ms:"), std::string::npos) << StatusLine(stats, timed);
  const auto timed_lines = StatusOverlayLines(stats, timed, ColorMode::kVertex, ColorMode::kVertex);
  EXPECT_NE(std::find(timed_lines.begin(), timed_lines.end(), "latency p50 41 ms  p95 89 ms"), timed_lines.end());
  EXPECT_EQ(FormatBytes(812), "812 B");
  EXPECT_EQ(FormatBytes(3584), "3.5 KB");
}

TEST(StatusTextTest, OverlayAndSummary) {
  ReceiverStats stats;
  stats.mesh_messages = 10;
  stats.meshes_decoded = 9;
  stats.meshes_failed = 1;
  stats.live_meshes = 8;
  stats.canonical_meshes = 1;
  stats.last_live_seq = 41;
  stats.last_live_vertices = 100;
  stats.last_live_triangles = 180;
  stats.mesh_bytes = 2048;
  const auto lines = StatusOverlayLines(stats, TrackingStatus(), ColorMode::kCanonical, ColorMode::kVertex);
  ASSERT_GE(lines.size(), 4u);
  EXPECT_EQ(lines[0], "server TRACKING: ok");
  EXPECT_EQ(lines[1], "frames processed 120  dropped 7  rejected 3  28.8 fps");
  EXPECT_NE(lines[2].find("icp 8.5 ms"), std::string::npos);
  EXPECT_EQ(lines[lines.size() - 2], "colour canonical (showing vertex: no canonical mesh of this frame)");
  cv::Mat image(240, 320, CV_8UC3, cv::Scalar(0, 0, 0));
  DrawOverlay(image, lines);
  EXPECT_GT(cv::countNonZero(image.reshape(1)), 200);

  std::vector<std::string> paths;
  for (int i = 0; i < 30; ++i) paths.push_back("/out/frame-" + std::to_string(i) + ".mesh.ply");
  const std::string summary = SummaryText(stats, TrackingStatus(), paths, 20);
  EXPECT_NE(summary.find("meshes received 10: decoded 9 (live 8, canonical 1, tracked 0, repeats 0), failed 1"),
            std::string::npos)
      << summary;
  EXPECT_NE(summary.find("bytes 2048 (2.0 KB)"), std::string::npos);
  EXPECT_NE(summary.find("last live seq 41"), std::string::npos);
  EXPECT_NE(summary.find("last status: TRACKING \"ok\", received 130, processed 120, dropped 7"), std::string::npos);
  EXPECT_NE(summary.find("files written 30"), std::string::npos);
  EXPECT_NE(summary.find("/out/frame-0.mesh.ply"), std::string::npos);
  EXPECT_NE(summary.find("/out/frame-29.mesh.ply"), std::string::npos);
  EXPECT_EQ(summary.find("/out/frame-15.mesh.ply"), std::string::npos);
  EXPECT_NE(summary.find("... 10 more"), std::string::npos);
  const std::string nothing = SummaryText(ReceiverStats{}, std::nullopt, {});
  EXPECT_NE(nothing.find("last live seq: none"), std::string::npos);
  EXPECT_NE(nothing.find("last status: none"), std::string::npos);
}

}  // namespace
}  // namespace vd
