// Sparse features (section 5.2): SIFT detection + description on synthetic 640x480 frames, and
// matching against a synthetic history of 10 .. 5000 earlier frames (150 features each) with the
// history policy (FeatureParams: recent frames + spread keyframes) and, for comparison, against
// every earlier frame; the matching kernels on the OpenCL device against their CPU references on
// the same candidate set, in one run so the ratio survives a noisy machine.
//   vd_feature_bench [--reps N] [--device SPEC]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "core/features.h"
#include "cpu_ref/features_ref.h"
#include "ocl/device_ops.h"
#include "vd/capture/synthetic.h"
#include "sphere_volume.h"

namespace vd {
namespace {

double MedianMs(int reps, const std::function<void()>& f) {
  std::vector<double> wall;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    wall.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::nth_element(wall.begin(), wall.begin() + reps / 2, wall.end());
  return wall[reps / 2];
}

void Check(const Status& s) {
  if (!s.ok()) {
    std::fprintf(stderr, "vd_feature_bench: %s\n", s.ToString().c_str());
    std::exit(1);
  }
}

// A frame of 150 features with random descriptors and canonical points in the grid.
FrameFeatures RandomFrame(int64_t index, std::mt19937* rng, const VdVolume& vol) {
  FrameFeatures f;
  f.frame_index = index;
  std::uniform_int_distribution<int> byte(0, 90);
  std::uniform_real_distribution<float> gx(1.f, vol.dim_x - 2.f), gy(1.f, vol.dim_y - 2.f), gz(1.f, vol.dim_z - 2.f);
  const int n = 150;
  f.u.assign(n, 320.f);
  f.v.assign(n, 240.f);
  f.size.assign(n, 4.f);
  f.angle.assign(n, 0.f);
  f.desc.resize(size_t(n) * VD_DESC_BYTES);
  for (auto& b : f.desc) b = uint8_t(byte(*rng));
  for (int i = 0; i < n; ++i) {
    f.camera_points.push_back(VD_F4(0.f, 0.f, 0.8f, 1.f));
    f.canonical.push_back(VD_F4(gx(*rng), gy(*rng), gz(*rng), 1.f));
  }
  return f;
}

}  // namespace
}  // namespace vd

int main(int argc, char** argv) {
  using namespace vd;
  int reps = 5;
  std::string device;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--reps") && i + 1 < argc) {
      reps = std::max(1, std::atoi(argv[++i]));
    } else if (!std::strcmp(argv[i], "--device") && i + 1 < argc) {
      device = argv[++i];
    } else if (!std::strcmp(argv[i], "--help") || !std::strcmp(argv[i], "-h")) {
      std::printf("vd_feature_bench [--reps N] [--device SPEC]: SIFT extraction and history matching times\n");
      return 0;
    } else {
      std::fprintf(stderr, "vd_feature_bench: unknown argument '%s' (see --help)\n", argv[i]);
      return 2;
    }
  }
  auto ctx = ocl::Context::Create(device);
  Check(ctx.status());
  std::printf("device: %s\n", (*ctx)->Describe().c_str());

  // Detection + description on the synthetic scenes' frames.
  const FeatureParams params;
  for (const char* name : {"tube", "cloth"}) {
    SyntheticOptions so;
    auto scene = MakeSyntheticScene(name, so);
    Check(scene.status());
    std::vector<RgbdFrame> frames;
    for (int k = 0; k < reps; ++k) frames.push_back((*scene)->Render(k * 7));
    size_t kps = 0;
    int k = 0;
    const double ms = MedianMs(reps, [&] {
      auto f = ExtractFeatures(frames[k++ % frames.size()], params, 0.2f, 3.5f);
      Check(f.status());
      kps = f->size_keypoints();
    });
    std::printf("extract %-5s 640x480: %.1f ms (median of %d), %zu keypoints\n", name, ms, reps, kps);
  }

  // Matching against synthetic histories.
  DeviceOps ops(ctx->get());
  Check(ops.Init());
  const VdVolume vol = test::TestVolume(64, 64, 64, 0.004f, VD_F4(-0.128f, -0.128f, 0.7f, 1.f));
  DeviceVolume dv;
  Check(ops.AllocVolume(vol, true, &dv));
  FeatureMatcher matcher(ctx->get(), params);
  std::mt19937 rng(3);
  const FrameFeatures cur = RandomFrame(-1, &rng, vol);
  FeatureHistory history;
  VdCamera cam{};
  cam.fx = cam.fy = 525.f;
  cam.cx = 319.5f;
  cam.cy = 239.5f;
  cam.width = 640;
  cam.height = 480;
  VdPose identity{};
  identity.r0 = VD_F4(1.f, 0.f, 0.f, 0.f);
  identity.r1 = VD_F4(0.f, 1.f, 0.f, 0.f);
  identity.r2 = VD_F4(0.f, 0.f, 1.f, 0.f);
  std::printf("%-8s %-7s %8s %10s %12s %12s %8s\n", "history", "policy", "frames", "features", "device ms",
              "cpu ref ms", "ratio");
  int64_t added = 0;
  for (int h : {10, 100, 1000, 5000}) {
    while (added < h) history.Add(RandomFrame(added++, &rng, vol), params.keyframe_interval);
    for (bool all : {false, true}) {
      // Every earlier frame: quadratic growth; measured up to 1000 frames (5000 takes seconds).
      if (all && h > 1000) continue;
      std::vector<int> cand;
      if (all) {
        for (int i = 0; i < h; ++i) cand.push_back(i);
      } else {
        cand = history.Candidates(params);
      }
      std::vector<SparseMatch> out;
      MatchStats stats;
      const double dev = MedianMs(reps, [&] {
        out.clear();
        Check(matcher.Match(cur, history, cand, DeviceField::Dense(dv), identity, cam, &out, &stats));
      });
      // The CPU reference of the same three kernels on the same candidates.
      std::vector<uint8_t> cd;
      std::vector<int32_t> fr;
      for (int f : cand) {
        fr.push_back(int32_t(cd.size() / VD_DESC_BYTES));
        cd.insert(cd.end(), history.frame(f).desc.begin(), history.frame(f).desc.end());
        fr.push_back(int32_t(cd.size() / VD_DESC_BYTES));
      }
      const int n_cand = int(cd.size() / VD_DESC_BYTES), n_cur = int(cur.size_keypoints());
      std::vector<uint8_t> cd_t(cd.size());
      vd_desc_transpose(cd.data(), n_cand, cd_t.data());
      std::vector<float> dist(size_t(n_cur) * n_cand);
      std::vector<VdMatchBest> rows(size_t(n_cur) * cand.size()), cols(n_cand);
      const double ref = MedianMs(reps, [&] {
        cpu::MatchDistances(cur.desc.data(), n_cur, cd_t.data(), n_cand, dist.data());
        cpu::MatchRows(dist.data(), n_cur, n_cand, fr.data(), int(cand.size()), rows.data());
        cpu::MatchColumns(dist.data(), n_cur, n_cand, cols.data());
      });
      std::printf("%-8d %-7s %8zu %10d %12.2f %12.2f %8.2f\n", h, all ? "all" : "policy", cand.size(), n_cand, dev, ref,
                  ref / dev);
    }
  }
  return 0;
}
