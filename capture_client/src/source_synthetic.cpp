// "synthetic:NAME": a SyntheticScene rendered frame by frame as Next() asks.
#include <sstream>

#include "source_internal.h"
#include "vd/capture/synthetic.h"

namespace vd {
namespace {

class SyntheticSource : public FrameSource {
 public:
  SyntheticSource(std::unique_ptr<SyntheticScene> scene, FrameSelection selection, std::optional<Intrinsics> intrinsics,
                  float depth_scale)
      : scene_(std::move(scene)), selection_(selection), intrinsics_(intrinsics), depth_scale_(depth_scale) {}

  StatusOr<std::optional<RgbdFrame>> Next() override {
    const std::optional<int64_t> raw = selection_.Advance();
    if (!raw) return std::optional<RgbdFrame>();
    RgbdFrame frame;
    try {
      frame = scene_->Render(static_cast<int>(*raw));
    } catch (const std::exception& e) {
      return Internal("synthetic:" + scene_->name() + ": rendering frame " + std::to_string(*raw) + ": " + e.what());
    }
    frame.seq = selection_.delivered() - 1;
    // Monotonic across passes of a looping source.
    const double t = (static_cast<double>(*raw) + selection_.pass() * scene_->num_frames()) / scene_->fps();
    frame.utime = static_cast<int64_t>(t * 1e6);
    if (intrinsics_) frame.intrinsics = *intrinsics_;
    if (depth_scale_ > 0.f) frame.depth_scale = depth_scale_;
    return std::optional<RgbdFrame>(std::move(frame));
  }

  double NominalFps() const override { return scene_->fps(); }
  int64_t NumFrames() const override { return selection_.NumFrames(); }

  std::string Describe() const override {
    const Intrinsics& k = intrinsics_ ? *intrinsics_ : scene_->intrinsics();
    std::ostringstream os;
    os << "synthetic:" << scene_->name() << " frames=" << selection_.per_pass() << "/" << scene_->num_frames()
       << (selection_.NumFrames() < 0 ? " (looping)" : "") << " " << k.ToString() << " fps=" << scene_->fps()
       << (scene_->rigid() ? " rigid" : " non-rigid");
    return os.str();
  }

 private:
  std::unique_ptr<SyntheticScene> scene_;
  FrameSelection selection_;
  // Set only when --intrinsics overrides the scene's (the rendering itself is unchanged).
  std::optional<Intrinsics> intrinsics_;
  // 0: the scene's own.
  float depth_scale_;
};

}  // namespace

StatusOr<std::unique_ptr<FrameSource>> OpenSyntheticSource(const std::string& name, const SourceOptions& options) {
  VD_RETURN_IF_ERROR(options.Validate());
  SyntheticOptions synthetic;
  synthetic.noise = options.synthetic_noise;
  if (options.synthetic_frames > 0) synthetic.num_frames = static_cast<int>(options.synthetic_frames);
  VD_ASSIGN_OR_RETURN(std::unique_ptr<SyntheticScene> scene, MakeSyntheticScene(name, synthetic));
  VD_ASSIGN_OR_RETURN(FrameSelection selection,
                      FrameSelection::Make(scene->num_frames(), options, "synthetic:" + name));
  std::optional<Intrinsics> intrinsics;
  if (!options.intrinsics.empty()) {
    const Intrinsics& own = scene->intrinsics();
    VD_ASSIGN_OR_RETURN(Intrinsics k, ResolveIntrinsics(own, options, own.width, own.height, "synthetic:" + name));
    intrinsics = k;
  }
  return std::unique_ptr<FrameSource>(
      std::make_unique<SyntheticSource>(std::move(scene), selection, intrinsics, options.depth_scale));
}

}  // namespace vd
