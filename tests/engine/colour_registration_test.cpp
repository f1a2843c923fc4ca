// Whether a source's colour is registered to its depth (core/colour_registration.h), which decides
// whether the dense colour term runs: the synthetic scenes (rendered colour and depth share the
// pixel grid) and their colour moved by a few pixels; 7-Scenes (a second, uncalibrated colour
// sensor) and KillingFusion's Snoopy (registered) from ../shared/data when present; and the engine
// turning the term on or off by the verdict and by --colour-registered.
#include "core/colour_registration.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "scene_eval.h"

namespace vd {
namespace {

using Verdict = ColourRegistration::Verdict;

ColourRegistration MakeCheck() { return ColourRegistration(ColourRegistrationParams(), 0.2f, 3.5f); }

// The colour moved by (dx, dy) pixels against the depth (the border repeated).
RgbdFrame Shifted(const RgbdFrame& f, int dx, int dy) {
  RgbdFrame out = f;
  out.color = cv::Mat();
  const cv::Mat m = (cv::Mat_<double>(2, 3) << 1, 0, dx, 0, 1, dy);
  cv::warpAffine(f.color, out.color, m, f.color.size(), cv::INTER_NEAREST, cv::BORDER_REPLICATE);
  return out;
}

StatusOr<std::unique_ptr<SyntheticScene>> Scene(const std::string& name) {
  SyntheticOptions so;
  so.noise = true;
  return MakeSyntheticScene(name, so);
}

TEST(ColourRegistrationTest, SyntheticScenesAreRegisteredWithinTwoFrames) {
  for (const std::string name : {"tube", "cloth", "rigid", "bend"}) {
    auto scene = Scene(name);
    ASSERT_TRUE(scene.ok()) << scene.status().ToString();
    ColourRegistration check = MakeCheck();
    Verdict v = check.Add((*scene)->Render(0));
    if (v == Verdict::kUndecided) v = check.Add((*scene)->Render(1));
    std::printf("%s: edge alignment %.2f over %lld crossings in %d frames\n", name.c_str(), check.ratio(),
                static_cast<long long>(check.samples()), check.frames());
    EXPECT_EQ(v, Verdict::kRegistered) << name;
    // Measured 1.78-2.62 on the first two frames (1.61 at the lowest over 60), against 1.45.
    EXPECT_GE(check.ratio(), 1.7) << name;
    // The step at the edge itself stands above both sides' texture.
    for (int axis = 0; axis < 2; ++axis) {
      const auto& p = check.profile(axis);
      EXPECT_GT(p[ColourRegistration::kReach], p[0]) << name << ", axis " << axis;
    }
  }
}

TEST(ColourRegistrationTest, ColourMovedByAFewPixelsIsNotRegistered) {
  auto scene = Scene("tube");
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  for (const auto& [dx, dy] : {std::pair{10, 0}, std::pair{0, -10}, std::pair{7, 7}}) {
    ColourRegistration check = MakeCheck();
    Verdict v = Verdict::kUndecided;
    for (int k = 0; k < 4 && v == Verdict::kUndecided; ++k) v = check.Add(Shifted((*scene)->Render(k), dx, dy));
    std::printf("tube, colour moved by (%d, %d) px: edge alignment %.2f\n", dx, dy, check.ratio());
    EXPECT_EQ(v, Verdict::kUnregistered);
    EXPECT_LT(check.ratio(), 1.1);
  }
  // A shift within the peak's reach (a sensor's usual residual misregistration) still passes.
  ColourRegistration check = MakeCheck();
  Verdict v = Verdict::kUndecided;
  for (int k = 0; k < 4 && v == Verdict::kUndecided; ++k) v = check.Add(Shifted((*scene)->Render(k), 2, 0));
  EXPECT_EQ(v, Verdict::kRegistered) << check.ratio();
}

TEST(ColourRegistrationTest, WithoutColourOrEdgesItWaitsThenRulesTheTermOut) {
  auto scene = Scene("tube");
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  ColourRegistration check = MakeCheck();
  RgbdFrame grey = (*scene)->Render(0);
  grey.color = cv::Mat();
  const int max_frames = ColourRegistrationParams().max_frames;
  for (int k = 1; k < max_frames; ++k) ASSERT_EQ(check.Add(grey), Verdict::kUndecided) << k;
  EXPECT_EQ(check.Add(grey), Verdict::kUnregistered);
  EXPECT_EQ(check.samples(), 0);
  // Decided stays decided; Clear starts again.
  EXPECT_EQ(check.Add((*scene)->Render(1)), Verdict::kUnregistered);
  check.Clear();
  EXPECT_EQ(check.verdict(), Verdict::kUndecided);
  EXPECT_EQ(check.frames(), 0);

  // Flat depth, no edges: no samples either.
  RgbdFrame flat = (*scene)->Render(0);
  flat.depth.setTo(1000);
  check.Add(flat);
  EXPECT_EQ(check.samples(), 0);
  EXPECT_EQ(check.verdict(), Verdict::kUndecided);
}

// The folder when ../shared/data holds it, else empty.
std::filesystem::path DataDir(const std::string& name) {
  const std::filesystem::path p = std::filesystem::path(VD_SHARED_DATA_DIR) / name;
  return std::filesystem::is_directory(p) ? p : std::filesystem::path();
}

RgbdFrame ReadFrame(const std::filesystem::path& color, const std::filesystem::path& depth) {
  RgbdFrame f;
  f.color = cv::imread(color.string(), cv::IMREAD_COLOR);
  f.depth = cv::imread(depth.string(), cv::IMREAD_UNCHANGED);
  f.depth_scale = 1000.f;
  return f;
}

TEST(ColourRegistrationTest, SevenScenesColourIsNotRegistered) {
  const auto dir = DataDir("7scenes_redkitchen");
  if (dir.empty()) GTEST_SKIP() << "../shared/data/7scenes_redkitchen is absent";
  // Frames from across the take (measured 0.67-1.24 per frame over 100 of them).
  for (int k : {0, 100, 200, 290}) {
    char c[64], d[64];
    std::snprintf(c, sizeof c, "frame-%06d.color.jpg", k);
    std::snprintf(d, sizeof d, "frame-%06d.depth.png", k);
    ColourRegistration check = MakeCheck();
    const RgbdFrame f = ReadFrame(dir / c, dir / d);
    ASSERT_FALSE(f.color.empty());
    EXPECT_EQ(check.Add(f), Verdict::kUnregistered) << k;
    std::printf("7-Scenes frame %d: edge alignment %.2f over %lld crossings\n", k, check.ratio(),
                static_cast<long long>(check.samples()));
    EXPECT_LT(check.ratio(), 1.3) << k;
  }
}

TEST(ColourRegistrationTest, SnoopyColourIsRegistered) {
  const auto dir = DataDir("killingfusion_snoopy");
  if (dir.empty()) GTEST_SKIP() << "../shared/data/killingfusion_snoopy is absent";
  ColourRegistration check = MakeCheck();
  const RgbdFrame f = ReadFrame(dir / "color_000000.png", dir / "depth_000000.png");
  ASSERT_FALSE(f.color.empty());
  EXPECT_EQ(check.Add(f), Verdict::kRegistered);
  std::printf("Snoopy: edge alignment %.2f over %lld crossings\n", check.ratio(),
              static_cast<long long>(check.samples()));
  EXPECT_GE(check.ratio(), 1.6);
}

// The engine runs the colour term by the verdict, or as --colour-registered says.
TEST(ColourRegistrationTest, EngineRunsTheColourTermOnRegisteredColourOnly) {
  if (!test::HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  auto scene = Scene("tube");
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  struct Case {
    std::string registered;
    int shift;
    bool active;
  };
  for (const Case& c : {Case{"auto", 0, true}, Case{"auto", 10, false}, Case{"yes", 10, true}, Case{"no", 0, false}}) {
    EngineParams p;
    p.colour_registered = c.registered;
    p.solver.w_photo = 0.03f;
    auto engine = Engine::Create(p, "");
    ASSERT_TRUE(engine.ok()) << engine.status().ToString();
    for (int k = 0; k < 3; ++k) {
      auto r = (*engine)->Process(Shifted((*scene)->Render(k), c.shift, 0));
      ASSERT_TRUE(r.ok()) << r.status().ToString();
    }
    EXPECT_EQ((*engine)->colour_term_active(), c.active) << c.registered << ", shift " << c.shift;
    if (c.registered == "auto") {
      EXPECT_EQ((*engine)->colour_registration().verdict(), c.active ? Verdict::kRegistered : Verdict::kUnregistered);
    }
    // A new model measures again.
    (*engine)->Reset();
    if (c.registered == "auto") {
      EXPECT_EQ((*engine)->colour_registration().verdict(), Verdict::kUndecided);
    }
  }
  // Rigid-only runs never ask for the term, nor do runs without --w-photo (the default).
  EngineParams plain;
  ASSERT_EQ(plain.solver.w_photo, 0.f);
  auto off = Engine::Create(plain, "");
  ASSERT_TRUE(off.ok());
  ASSERT_TRUE((*off)->Process((*scene)->Render(0)).ok());
  EXPECT_FALSE((*off)->colour_term_active());
  EXPECT_EQ((*off)->colour_registration().frames(), 0);
  EngineParams rigid;
  rigid.rigid_only = true;
  rigid.solver.w_photo = 0.03f;
  auto engine = Engine::Create(rigid, "");
  ASSERT_TRUE(engine.ok());
  ASSERT_TRUE((*engine)->Process((*scene)->Render(0)).ok());
  EXPECT_FALSE((*engine)->colour_term_active());
  EXPECT_EQ((*engine)->colour_registration().frames(), 0);
}

}  // namespace
}  // namespace vd
