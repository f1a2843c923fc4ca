// OpenSource dispatch: synthetic scenes, unknown schemes, option validation.
#include <gtest/gtest.h>

#include "vd/capture/source.h"
#include "vd/capture/synthetic.h"

namespace vd {
namespace {

bool SameImage(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && (a.empty() || cv::norm(a, b, cv::NORM_INF) == 0.0);
}

TEST(OpenSource, SyntheticSceneRendersLazilyWithSelection) {
  SourceOptions o;
  o.start = 2;
  o.stride = 3;
  o.count = 4;
  auto source = OpenSource("synthetic:tube", o);
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  auto scene = MakeSyntheticScene("tube", SyntheticOptions());
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  EXPECT_EQ((*source)->NumFrames(), 4);
  EXPECT_DOUBLE_EQ((*source)->NominalFps(), (*scene)->fps());
  EXPECT_NE((*source)->Describe().find("synthetic:tube"), std::string::npos);
  for (int i = 0; i < 4; ++i) {
    auto f = (*source)->Next();
    ASSERT_TRUE(f.ok()) << f.status().ToString();
    ASSERT_TRUE(f->has_value());
    ASSERT_TRUE((*f)->Validate().ok()) << (*f)->Validate().ToString();
    EXPECT_EQ((*f)->seq, i);
    // The same frame the scene renders for raw index 2 + 3 i (noise is seeded, so deterministic).
    const RgbdFrame expected = (*scene)->Render(2 + 3 * i);
    EXPECT_TRUE(SameImage((*f)->depth, expected.depth)) << "frame " << i;
    EXPECT_TRUE(SameImage((*f)->color, expected.color)) << "frame " << i;
    EXPECT_NEAR(static_cast<double>((*f)->utime), (2 + 3 * i) / (*scene)->fps() * 1e6, 1.0);
  }
  auto end = (*source)->Next();
  ASSERT_TRUE(end.ok());
  EXPECT_FALSE(end->has_value());
}

TEST(OpenSource, SyntheticNoiseFlagReachesTheScene) {
  SourceOptions o;
  o.synthetic_noise = false;
  o.count = 1;
  auto source = OpenSource("synthetic:tube", o);
  ASSERT_TRUE(source.ok());
  SyntheticOptions clean;
  clean.noise = false;
  auto scene = MakeSyntheticScene("tube", clean);
  ASSERT_TRUE(scene.ok());
  auto f = (*source)->Next();
  ASSERT_TRUE(f.ok() && f->has_value());
  EXPECT_TRUE(SameImage((*f)->depth, (*scene)->Render(0).depth));
}

// --frames: the same motion over more frames, so less of it per frame.
TEST(OpenSource, SyntheticFramesMakeALongTakeOfTheSameMotion) {
  SourceOptions o;
  o.synthetic_noise = false;
  o.synthetic_frames = 120;
  auto source = OpenSource("synthetic:tube", o);
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  EXPECT_EQ((*source)->NumFrames(), 120);
  SyntheticOptions short_take, long_take;
  short_take.noise = long_take.noise = false;
  long_take.num_frames = 120;
  auto a = MakeSyntheticScene("tube", short_take);
  auto b = MakeSyntheticScene("tube", long_take);
  ASSERT_TRUE(a.ok() && b.ok());
  const auto tip = [](const TriangleMesh& m) { return Eigen::Vector3f(m.positions[m.positions.size() - 3],
                                                                        m.positions[m.positions.size() - 2],
                                                                        m.positions.back()); };
  const Eigen::Vector3f s1 = tip((*a)->GroundTruthMesh(1)), l1 = tip((*b)->GroundTruthMesh(1));
  const Eigen::Vector3f s0 = tip((*a)->GroundTruthMesh(0));
  EXPECT_GT((s1 - s0).norm(), 1e-4f) << "the tube's end moves between frames";
  EXPECT_LT((l1 - s0).norm(), 0.75f * (s1 - s0).norm()) << "less motion per frame in the long take";
  o.synthetic_frames = -1;
  EXPECT_FALSE(OpenSource("synthetic:tube", o).ok());
}

TEST(OpenSource, SyntheticLoopIsEndless) {
  SourceOptions o;
  o.loop = true;
  auto source = OpenSource("synthetic:tube", o);
  ASSERT_TRUE(source.ok());
  EXPECT_EQ((*source)->NumFrames(), -1);
}

TEST(OpenSource, UnknownSceneIsAnError) {
  auto s = OpenSource("synthetic:no-such-scene", {});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find("no-such-scene"), std::string::npos) << s.status().message();
}

TEST(OpenSource, UnknownSchemeListsTheValidOnes) {
  for (const char* spec : {"kinect:0", "", "/data/seq", "folderx:abc"}) {
    auto s = OpenSource(spec, {});
    ASSERT_FALSE(s.ok()) << spec;
    EXPECT_EQ(s.status().code(), StatusCode::kInvalidArgument) << spec;
    const std::string& m = s.status().message();
    for (const char* scheme : {"openni2", "oni:", "folder:", "synthetic:"})
      EXPECT_NE(m.find(scheme), std::string::npos) << spec << ": " << m;
  }
}

TEST(OpenSource, EmptyArgumentsAreRejected) {
  for (const char* spec : {"folder:", "synthetic:", "oni:", "openni2:"}) {
    auto s = OpenSource(spec, {});
    ASSERT_FALSE(s.ok()) << spec;
    EXPECT_EQ(s.status().code(), StatusCode::kInvalidArgument) << spec;
  }
}

TEST(SourceOptions, ValidateNamesTheField) {
  SourceOptions o;
  EXPECT_TRUE(o.Validate().ok());
  o.stride = 0;
  EXPECT_NE(o.Validate().message().find("stride"), std::string::npos);
  o = SourceOptions();
  o.count = 0;
  EXPECT_NE(o.Validate().message().find("count"), std::string::npos);
  o = SourceOptions();
  o.start = -1;
  EXPECT_NE(o.Validate().message().find("start"), std::string::npos);
  o = SourceOptions();
  o.depth_scale = -5.f;
  EXPECT_NE(o.Validate().message().find("depth_scale"), std::string::npos);
  o = SourceOptions();
  o.read_timeout_s = 0.0;
  EXPECT_NE(o.Validate().message().find("read_timeout_s"), std::string::npos);
  o = SourceOptions();
  o.intrinsics = "1,2,3";
  EXPECT_FALSE(o.Validate().ok());
  // OpenSource refuses bad options before touching the source.
  o = SourceOptions();
  o.stride = -2;
  auto s = OpenSource("synthetic:tube", o);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find("stride"), std::string::npos);
}

}  // namespace
}  // namespace vd
