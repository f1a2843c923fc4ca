// Runs the vdeform-viewer executable headless: flags, exit codes, and a replayed LCM log
// (file:// provider, so no network) saved as PLY and PNG files. Never opens a window.
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>
#include <opencv2/imgcodecs.hpp>

#include "vd/common/codecs.h"
#include "vd/common/messages.h"
#include "vd/viewer/render.h"

namespace vd {
namespace {

namespace fs = std::filesystem;

const std::string kViewer = std::string(VD_BINARY_DIR) + "/viewer_client/vdeform-viewer";

struct ViewerRun {
  int exit_code = -1;
  std::string output;
};

// Runs the viewer with `args` (shell words), stdout and stderr together, no display.
ViewerRun RunViewer(const std::string& args) {
  ViewerRun run;
  const std::string command = "env -u DISPLAY -u WAYLAND_DISPLAY " + kViewer + " " + args + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return run;
  char buffer[4096];
  size_t n = 0;
  while ((n = fread(buffer, 1, sizeof buffer, pipe)) > 0) run.output.append(buffer, n);
  const int status = pclose(pipe);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return run;
}

class ViewerCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(kViewer)) GTEST_SKIP() << kViewer << " is not built";
    std::string tmpl = (fs::temp_directory_path() / "vd_viewer_cli_XXXXXX").string();
    dir_ = mkdtemp(tmpl.data());
  }
  void TearDown() override {
    std::error_code ec;
    if (!dir_.empty()) fs::remove_all(dir_, ec);
  }
  std::string dir_;
};

TriangleMesh Quad(float z) {
  TriangleMesh m;
  m.positions = {-0.2f, -0.2f, z, 0.2f, -0.2f, z, 0.2f, 0.2f, z, -0.2f, 0.2f, z};
  m.colors = {250, 10, 10, 10, 250, 10, 10, 10, 250, 250, 250, 10};
  m.triangles = {0, 1, 2, 0, 2, 3};
  return m;
}

// Writes an LCM log: live meshes for seq 0..2 (a canonical one for seq 1), a status, and one
// corrupt mesh message.
void WriteLog(const std::string& path) {
  lcm::LogFile log(path, "w");
  ASSERT_TRUE(log.good());
  int64_t event = 0;
  auto write = [&](const char* channel, const std::vector<uint8_t>& bytes) {
    lcm::LogEvent ev;
    ev.eventnum = event;
    ev.timestamp = 1000 * event++;
    ev.channel = channel;
    ev.datalen = static_cast<int32_t>(bytes.size());
    ev.data = const_cast<uint8_t*>(bytes.data());
    ASSERT_EQ(log.writeEvent(&ev), 0);
  };
  auto encode = [](const auto& msg) {
    std::vector<uint8_t> bytes(msg.getEncodedSize());
    msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    return bytes;
  };
  for (int seq = 0; seq < 3; ++seq) {
    auto live = MeshToMessage(Quad(1.0f + 0.1f * seq), seq, seq, vdeform::mesh_t::KIND_LIVE);
    ASSERT_TRUE(live.ok());
    write(kMeshChannel, encode(*live));
    if (seq == 1) {
      auto canonical = MeshToMessage(Quad(1.0f), seq, seq, vdeform::mesh_t::KIND_CANONICAL);
      ASSERT_TRUE(canonical.ok());
      write(kMeshChannel, encode(*canonical));
      write(kMeshChannel, std::vector<uint8_t>(40, 0xab));
    }
  }
  vdeform::server_status_t status{};
  status.state = vdeform::server_status_t::STATE_TRACKING;
  status.frames_processed = 3;
  status.last_processed_seq = 2;
  status.fps = 30.f;
  write(kStatusChannel, encode(status));
}

TEST_F(ViewerCliTest, HelpAndBadFlags) {
  const ViewerRun help = RunViewer("--help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.output.find("--save-dir DIR"), std::string::npos) << help.output;
  const ViewerRun bad = RunViewer("--frobnicate");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.output.find("unknown flag --frobnicate"), std::string::npos) << bad.output;
  const ViewerRun png_only = RunViewer("--headless --png");
  EXPECT_EQ(png_only.exit_code, 2);
  EXPECT_NE(png_only.output.find("--png needs --save-dir"), std::string::npos) << png_only.output;
}

TEST_F(ViewerCliTest, TimesOutWithAClearMessageWhenNothingArrives) {
  const ViewerRun run = RunViewer("--headless --lcm-url memq:// --timeout 0.3");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.output.find("no mesh or status message arrived for 0.3 s"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("vdeform-viewer summary"), std::string::npos) << run.output;
}

TEST_F(ViewerCliTest, ReplayedLogIsSavedAsPlyAndPng) {
  const std::string log = dir_ + "/session.lcm";
  WriteLog(log);
  const std::string out = dir_ + "/out";
  const ViewerRun run = RunViewer("--headless --lcm-url 'file://" + log + "?speed=0' --save-dir " + out +
                            " --png --png-size 160x120 --timeout 5");
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("meshes received 5: decoded 4 (live 3, canonical 1, tracked 0, repeats 0), failed 1"),
            std::string::npos)
      << run.output;
  EXPECT_NE(run.output.find("last live seq 2 (4 vertices, 2 triangles)"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("last status: TRACKING"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("files written 8"), std::string::npos) << run.output;
  for (int seq = 0; seq < 3; ++seq) {
    char name[32];
    std::snprintf(name, sizeof name, "/frame-%06d.mesh.ply", seq);
    auto mesh = ReadPly(out + name);
    ASSERT_TRUE(mesh.ok()) << name << ": " << mesh.status().ToString();
    EXPECT_EQ(mesh->num_vertices(), 4u);
    EXPECT_EQ(mesh->num_triangles(), 2u);
    std::snprintf(name, sizeof name, "/frame-%06d.png", seq);
    const cv::Mat png = cv::imread(out + name);
    ASSERT_FALSE(png.empty()) << name;
    EXPECT_EQ(png.cols, 160);
    EXPECT_EQ(png.rows, 120);
    // The quad fills the fitted view (90% by 90% of the image, less where it is not square).
    cv::Mat differs;
    cv::Mat background(png.size(), CV_8UC3, cv::Scalar(RenderOptions{}.background));
    cv::compare(png.reshape(1), background.reshape(1), differs, cv::CMP_NE);
    EXPECT_GT(cv::countNonZero(differs.reshape(3, png.rows).reshape(1)) / 3, 120 * 108 / 2) << name;
  }
  EXPECT_TRUE(fs::exists(out + "/frame-000001.canonical.ply"));
  EXPECT_TRUE(fs::exists(out + "/final.png"));
}

// --key-file: an unusable key file is a usage error naming the file; with a good one, the unsigned
// meshes and status of the log are refused by reason and nothing is saved.
TEST_F(ViewerCliTest, KeyFileRefusesUnsignedOutput) {
  const std::string hex = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff";
  const std::string key = dir_ + "/output.key";
  std::ofstream(key) << hex << "\n";
  fs::permissions(key, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  const ViewerRun readable = RunViewer("--headless --lcm-url memq:// --key-file " + key);
  EXPECT_EQ(readable.exit_code, 2) << readable.output;
  EXPECT_NE(readable.output.find("output key file '" + key + "' is readable by group or others"), std::string::npos)
      << readable.output;
  std::ofstream(key, std::ios::trunc) << "camA " << hex << "\n";
  fs::permissions(key, fs::perms::owner_read | fs::perms::owner_write);
  const ViewerRun per_source = RunViewer("--headless --lcm-url memq:// --key-file " + key);
  EXPECT_EQ(per_source.exit_code, 2) << per_source.output;
  EXPECT_NE(per_source.output.find("has SOURCE_ID KEY lines"), std::string::npos) << per_source.output;

  std::ofstream(key, std::ios::trunc) << hex << "\n";
  const std::string log = dir_ + "/session.lcm";
  WriteLog(log);
  const std::string out = dir_ + "/out";
  const ViewerRun run = RunViewer("--headless --quiet --lcm-url 'file://" + log + "?speed=0' --save-dir " + out +
                                  " --key-file " + key + " --timeout 5");
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("meshes received 5: decoded 0 (live 0, canonical 0, tracked 0, repeats 0), failed 1"),
            std::string::npos)
      << run.output;
  EXPECT_NE(run.output.find("refused under --key-file: meshes 4 unsigned, 0 bad signature, 0 replayed; status 1 "
                            "unsigned, 0 bad signature, 0 replayed"),
            std::string::npos)
      << run.output;
  EXPECT_NE(run.output.find("last status: none"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("files written 0"), std::string::npos) << run.output;
}

TEST_F(ViewerCliTest, ReplayShorterThanCountFails) {
  const std::string log = dir_ + "/session.lcm";
  WriteLog(log);
  const ViewerRun run = RunViewer("--headless --quiet --lcm-url 'file://" + log + "?speed=0' --count 10 --timeout 5");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_NE(run.output.find("the log ended after 3 of the 10 live meshes"), std::string::npos) << run.output;
}

}  // namespace
}  // namespace vd
