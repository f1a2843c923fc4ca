// The engine's parameters bound to flags once: every field reachable from the command line, the
// in-class defaults shown by --help, and one validation that names the field.
#include "core/engine.h"

#include <gtest/gtest.h>

#include "vd/common/flags.h"

namespace vd {
namespace {

TEST(EngineParamsTest, EveryFieldHasAFlag) {
  EngineParams p;
  FlagParser f("u");
  p.Bind(&f);
  bool help = false;
  const Status s = f.Parse(
      {"--voxel-size", "0.006", "--truncation-voxels", "5", "--max-weight", "32", "--min-depth", "0.3", "--max-depth",
       "2.5", "--max-grid-mb", "300", "--volume-margin", "0.2", "--rigid-only", "--k-min", "2", "--no-bilateral",
       "--bilateral-radius", "3", "--bilateral-sigma-space", "4", "--bilateral-sigma-depth", "0.03", "--normal-max-jump",
       "0.06", "--icp-iterations", "7,6,5", "--icp-degeneracy", "1e-4", "--icp-max-distance", "0.05", "--icp-min-step", "2e-6",
       "--icp-max-normal-angle", "20", "--min-inlier-fraction", "0.2", "--max-frame-translation", "0.1",
       "--max-frame-rotation", "15", "--outer-iterations", "2", "--corr-eps-d", "0.01", "--corr-eps-n", "0.4",
       "--corr-eps-v", "0.7", "--w-dense", "1.5", "--w-reg", "3", "--damping", "1e-3", "--levels", "2",
       "--flip-flop-iterations", "3", "--coarse-iterations", "5", "--pcg-iterations", "12", "--pcg-tolerance", "1e-3",
       "--no-btb-cache-coarse", "--no-btb-cache-fine", "--no-sift", "--w-sparse", "16", "--sift-max-keypoints", "100",
       "--sift-octaves", "3", "--sift-octave-layers", "2", "--sift-contrast-threshold", "0.04", "--sift-max-orientations",
       "1", "--sift-max-depth-spread", "0.03", "--match-max-pair", "64", "--match-keep-per-pair", "32",
       "--match-max-descriptor-distance", "200", "--match-max-ratio", "0.7", "--match-max-screen-distance", "50",
       "--match-max-world-distance", "0.05", "--history-recent-frames", "3", "--history-max-keyframes", "8",
       "--history-keyframe-interval", "4", "--history-max-stored-keyframes", "64", "--sparse-pose-huber", "0.02",
       "--lift-max-depth-gap", "0.02", "--lift-tolerance", "1e-3", "--lift-iterations", "5"},
      &help);
  ASSERT_TRUE(s.ok()) << s.ToString();
  EXPECT_FLOAT_EQ(p.voxel_size, 0.006f);
  EXPECT_FLOAT_EQ(p.truncation_voxels, 5.f);
  EXPECT_FLOAT_EQ(p.max_weight, 32.f);
  EXPECT_FLOAT_EQ(p.min_depth, 0.3f);
  EXPECT_FLOAT_EQ(p.max_depth, 2.5f);
  EXPECT_DOUBLE_EQ(p.max_grid_mb, 300.0);
  EXPECT_FLOAT_EQ(p.volume_margin, 0.2f);
  EXPECT_TRUE(p.rigid_only);
  EXPECT_FLOAT_EQ(p.k_min, 2.f);
  EXPECT_FALSE(p.bilateral);
  EXPECT_EQ(p.bilateral_radius, 3);
  EXPECT_FLOAT_EQ(p.bilateral_sigma_space_px, 4.f);
  EXPECT_FLOAT_EQ(p.bilateral_sigma_depth_m, 0.03f);
  EXPECT_FLOAT_EQ(p.normal_max_jump, 0.06f);
  EXPECT_EQ(p.icp_iterations, (std::array<int, 3>{7, 6, 5}));
  EXPECT_FLOAT_EQ(p.icp_degeneracy, 1e-4f);
  EXPECT_FLOAT_EQ(p.icp_max_distance, 0.05f);
  EXPECT_FLOAT_EQ(p.icp_min_step, 2e-6f);
  EXPECT_FLOAT_EQ(p.icp_max_normal_angle_deg, 20.f);
  EXPECT_FLOAT_EQ(p.min_inlier_fraction, 0.2f);
  EXPECT_FLOAT_EQ(p.max_frame_translation, 0.1f);
  EXPECT_FLOAT_EQ(p.max_frame_rotation_deg, 15.f);
  EXPECT_EQ(p.nonrigid_outer_iterations, 2);
  EXPECT_FLOAT_EQ(p.corr_eps_d, 0.01f);
  EXPECT_FLOAT_EQ(p.corr_eps_n, 0.4f);
  EXPECT_FLOAT_EQ(p.corr_eps_v, 0.7f);
  EXPECT_FLOAT_EQ(p.solver.w_dense, 1.5f);
  EXPECT_FLOAT_EQ(p.solver.w_reg, 3.f);
  EXPECT_FLOAT_EQ(p.solver.damping, 1e-3f);
  EXPECT_EQ(p.solver.levels, 2);
  EXPECT_EQ(p.solver.flip_flop_iterations, 3);
  EXPECT_EQ(p.solver.coarse_flip_flop_iterations, 5);
  EXPECT_EQ(p.solver.pcg_iterations, 12);
  EXPECT_FLOAT_EQ(p.solver.pcg_tolerance, 1e-3f);
  EXPECT_FALSE(p.solver.cache_btb_coarse);
  EXPECT_FALSE(p.solver.cache_btb_fine);
  EXPECT_FALSE(p.features.enabled);
  EXPECT_FLOAT_EQ(p.features.w_sparse, 16.f);
  EXPECT_EQ(p.features.max_keypoints, 100);
  EXPECT_EQ(p.features.octaves, 3);
  EXPECT_EQ(p.features.octave_layers, 2);
  EXPECT_FLOAT_EQ(p.features.contrast_threshold, 0.04f);
  EXPECT_EQ(p.features.max_orientations, 1);
  EXPECT_FLOAT_EQ(p.features.max_depth_spread, 0.03f);
  EXPECT_EQ(p.features.max_pair_matches, 64);
  EXPECT_EQ(p.features.keep_per_pair, 32);
  EXPECT_FLOAT_EQ(p.features.prune.max_descriptor_distance, 200.f);
  EXPECT_FLOAT_EQ(p.features.prune.max_ratio, 0.7f);
  EXPECT_FLOAT_EQ(p.features.prune.max_screen_distance, 50.f);
  EXPECT_FLOAT_EQ(p.features.prune.max_world_distance, 0.05f);
  EXPECT_EQ(p.features.recent_frames, 3);
  EXPECT_EQ(p.features.max_keyframes, 8);
  EXPECT_EQ(p.features.keyframe_interval, 4);
  EXPECT_EQ(p.features.max_stored_keyframes, 64);
  EXPECT_FLOAT_EQ(p.features.pose_huber, 0.02f);
  EXPECT_FLOAT_EQ(p.features.lift_max_depth_gap, 0.02f);
  EXPECT_FLOAT_EQ(p.features.lift_tolerance, 1e-3f);
  EXPECT_EQ(p.features.lift_iterations, 5);
  EXPECT_TRUE(p.Validate().ok()) << p.Validate().ToString();
}

TEST(EngineParamsTest, HelpShowsTheInClassDefaults) {
  EngineParams p;
  FlagParser f("u");
  p.Bind(&f);
  const std::string help = f.Help();
  const EngineParams d;
  EXPECT_NE(help.find("(default: 0.004)"), std::string::npos);
  EXPECT_NE(help.find("(default: 10,5,4)"), std::string::npos);
  EXPECT_NE(help.find("(default: " + std::to_string(d.solver.pcg_iterations) + ")"), std::string::npos);
  EXPECT_NE(help.find("--no-sift"), std::string::npos);
}

TEST(EngineParamsTest, BadValuesFailValidationNamingTheField) {
  auto parse = [](const std::vector<std::string>& args) {
    EngineParams p;
    FlagParser f("u");
    p.Bind(&f);
    bool help = false;
    Status s = f.Parse(args, &help);
    return s.ok() ? p.Validate() : s;
  };
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--voxel-size", "0.5"}, "EngineParams.voxel_size = 0.5 violates"},
      {{"--levels", "9"}, "SolverParams.levels = 9 violates"},
      {{"--match-keep-per-pair", "500"}, "FeatureParams.keep_per_pair = 500"},
      {{"--icp-iterations", "1,2"}, "three counts"},
      {{"--icp-iterations", "1,2,3,4"}, "three counts"},
      {{"--icp-iterations", "1,x,3"}, "--icp-iterations expects an integer"},
      {{"--icp-iterations", "1,200,3"}, "out of range"},
      {{"--icp-min-step", "0.01"}, "EngineParams.icp_min_step = 0.01 violates"},
      {{"--icp-min-step", "-1"}, "EngineParams.icp_min_step = -1 violates"},
  };
  for (const auto& [args, expected] : cases) {
    const Status s = parse(args);
    EXPECT_NE(s.message().find(expected), std::string::npos) << args[0] << " " << args[1] << ": " << s.message();
  }
  EXPECT_TRUE(parse({"--icp-iterations", "0,0,1"}).ok());
}

}  // namespace
}  // namespace vd
