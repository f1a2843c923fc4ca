// The offline mode: --save-dir names its files by the frame's index in the source, so that with
// --start and --stride they match the input frames.
#include <gtest/gtest.h>

#include <optional>

#include <filesystem>
#include <set>
#include <string>

#include "offline.h"
#include "vd/common/codecs.h"
#include "ocl/ocl.h"
#include "../support/temp_dir.h"

namespace vd {
namespace {

namespace fs = std::filesystem;

TEST(OfflineTest, SourceFrameIndexFollowsStartAndStride) {
  SourceOptions o;
  EXPECT_EQ(SourceFrameIndex(o, 0), 0);
  EXPECT_EQ(SourceFrameIndex(o, 4), 4);
  o.start = 3;
  o.stride = 2;
  EXPECT_EQ(SourceFrameIndex(o, 0), 3);
  EXPECT_EQ(SourceFrameIndex(o, 1), 5);
  EXPECT_EQ(SourceFrameIndex(o, 2), 7);
}

TEST(OfflineTest, SaveDirNamesFilesBySourceFrameIndex) {
  auto devices = ocl::ListDevices();
  if (!devices.ok() || devices->empty()) GTEST_SKIP() << "no OpenCL device";
  ServerOptions options;
  options.input = "synthetic:tube";
  options.engine.voxel_size = 0.008f;
  options.start = 3;
  options.stride = 2;
  options.count = 3;
  options.quiet = true;
  options.save_dir = test::TestTempDir("vd_offline_save");
  fs::remove_all(options.save_dir);
  ASSERT_EQ(RunOffline(options), 0);
  std::set<std::string> files;
  for (const auto& e : fs::directory_iterator(options.save_dir)) files.insert(e.path().filename().string());
  std::set<std::string> expected;
  for (const char* index : {"000003", "000005", "000007"})
    for (const char* suffix : {"mesh.ply", "canonical.ply", "pose.txt"})
      expected.insert(std::string("frame-") + index + "." + suffix);
  EXPECT_EQ(files, expected);
}

// --track-mesh: frame-%06d.tracked.ply beside the others, the same vertex count and faces in
// every frame; --track-mesh-from a missing file is a clear error before any frame.
TEST(OfflineTest, TrackMeshWritesAFixedTopologyMeshPerFrame) {
  auto devices = ocl::ListDevices();
  if (!devices.ok() || devices->empty()) GTEST_SKIP() << "no OpenCL device";
  ServerOptions options;
  options.input = "synthetic:tube";
  options.engine.voxel_size = 0.008f;
  options.count = 4;
  options.quiet = true;
  options.track_mesh = true;
  options.save_dir = test::TestTempDir("vd_offline_tracked");
  fs::remove_all(options.save_dir);
  ASSERT_EQ(RunOffline(options), 0);
  std::optional<TriangleMesh> first;
  for (const char* index : {"000000", "000001", "000002", "000003"}) {
    auto m = ReadPly(options.save_dir + "/frame-" + index + ".tracked.ply");
    ASSERT_TRUE(m.ok()) << index << ": " << m.status().ToString();
    if (!first) {
      first = *m;
      EXPECT_GT(first->num_vertices(), 100u);
      continue;
    }
    EXPECT_EQ(m->num_vertices(), first->num_vertices()) << index;
    EXPECT_EQ(m->triangles, first->triangles) << index;
  }
  options.track_mesh = false;
  options.track_mesh_from = options.save_dir + "/no-such.ply";
  EXPECT_EQ(RunOffline(options), 1);
}

}  // namespace
}  // namespace vd
