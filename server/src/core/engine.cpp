#include "core/engine.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "core/growth.h"
#include "ocl/solver_ocl.h"
#include "vd/common/flags.h"
#include "vd/common/log.h"
#include "vd/common/thread_name.h"

namespace vd {
namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

VdCamera ToVdCamera(const Intrinsics& k) {
  VdCamera c{};
  c.fx = k.fx;
  c.fy = k.fy;
  c.cx = k.cx;
  c.cy = k.cy;
  c.width = k.width;
  c.height = k.height;
  return c;
}

VdCamera ScaledCamera(const VdCamera& c, int level) {
  Intrinsics k{c.fx, c.fy, c.cx, c.cy, c.width, c.height};
  return ToVdCamera(k.Scaled(level));
}


int64_t ProcStatusKb(const char* key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const size_t n = std::strlen(key);
  while (std::getline(in, line))
    if (line.compare(0, n, key) == 0) return std::atoll(line.c_str() + n + 1);
  return 0;
}

}  // namespace

VdPose ToVdPose(const Eigen::Matrix4d& T) {
  VdPose p;
  p.r0 = VD_F4(float(T(0, 0)), float(T(0, 1)), float(T(0, 2)), float(T(0, 3)));
  p.r1 = VD_F4(float(T(1, 0)), float(T(1, 1)), float(T(1, 2)), float(T(1, 3)));
  p.r2 = VD_F4(float(T(2, 0)), float(T(2, 1)), float(T(2, 2)), float(T(2, 3)));
  return p;
}

double DenseGridPointBytes(bool with_field) { return with_field ? 44.0 : 12.0; }
double SparseBrickBytes(bool with_field) {
  return VD_BRICK_VOXELS * DenseGridPointBytes(with_field) + VD_BRICK_NEIGHBOURS * 4.0 + 3 * 4.0 + 4 * 8.0;
}

int64_t ResidentBytes() { return ProcStatusKb("VmRSS:") * 1024; }
int64_t PeakResidentBytes() { return ProcStatusKb("VmHWM:") * 1024; }

void EngineParams::Bind(FlagParser* f) {
  f->Section("Volume and fusion");
  f->Add("voxel-size", &voxel_size, "Grid spacing in metres");
  f->Add("truncation-voxels", &truncation_voxels, "Truncation band of the TSDF, in voxels");
  f->Add("max-weight", &max_weight, "Weight cap of the running TSDF average (higher = smoother, slower to follow change)");
  f->Add("min-depth", &min_depth, "Depth below this many metres is ignored");
  f->Add("max-depth", &max_depth, "Depth beyond this many metres is ignored");
  f->Add("max-grid-mb", &max_grid_mb,
         "Memory the grid may use, MB (12 bytes per point with --rigid-only, 44 with the deformation field); with "
         "--sparse-volume the most the bricks may use (6.3 KB a brick of 512 points with --rigid-only, 22.7 KB with "
         "the field)");
  f->Add("volume-margin", &volume_margin,
         "Space added around the first frame's points when placing the grid, metres (larger for a moving "
         "camera that will see more of the scene)");
  f->AddSwitch("rigid-only", &rigid_only,
               "Rigid tracking and fusion only: no deformation field (12 instead of 44 bytes per grid point), no "
               "non-rigid solve");
  f->AddSwitch("sparse-volume", &sparse_volume,
               "Store the volume (and the deformation field) as 8^3 bricks allocated where the surface is: no box "
               "fixed at the first frame, surface entering the view grows bricks, --max-grid-mb is the brick pool; "
               "when it is full the status says so and the bricks out of view longest are dropped "
               "(non-rigid: at most 4 --levels)");
  f->Add("k-min", &k_min, "Grid points are fused non-rigidly only after taking part in this many optimisations");
  f->Add("field-rigid-threshold", &field_rigid_threshold,
         "Move the field's rigid part into the camera pose once it displaces the active points by this RMS, metres "
         "(0: never)");
  f->Add("static-levels", &static_levels,
         "Levels of the solver's hierarchy while the field is static (its non-rigid part under half a voxel, "
         "measured every 10 frames; 0: always --levels)");
  f->Add("static-solve-every", &static_solve_every,
         "While the field is static (measured as for --static-levels, which must be above 0), solve it on every n-th "
         "frame only; the frames between fuse through it as it stands, track the camera and publish the mesh (1: "
         "every frame)");
  f->Add("k-min-new", &k_min_new,
         "... and grid points never fused before (space seen for the first time) only after this many (at least "
         "--k-min)");
  f->Add("carve-rate", &carve_rate,
         "Share of its weight a fused grid point holding surface loses each frame the depth sees it as free space "
         "(0: no carving)");
  f->Add("carve-radius", &carve_radius,
         "Half-width in pixels of the depth window that must all see free space before a grid point is carved");
  f->Section("Depth preprocessing");
  f->AddNegation("no-bilateral", &bilateral, "Track on the unfiltered depth");
  f->Add("prefetch-preprocess", &prefetch_preprocess,
         "Preprocess the next frame on a second device queue while this one is solved: on, off, or auto (on for a "
         "GPU; on 2 CPU cores it bought nothing)",
         "auto|on|off");
  f->Add("colour-registered", &colour_registered,
         "Whether the colour lies on the depth's pixel grid, which the dense colour term (--w-photo) needs: auto "
         "(measured from the first frames' depth and colour edges), yes, or no (the term stays off)",
         "auto|yes|no");
  f->Add("bilateral-radius", &bilateral_radius, "Radius of the bilateral filter, pixels");
  f->Add("bilateral-sigma-space", &bilateral_sigma_space_px, "Spatial sigma of the bilateral filter, pixels");
  f->Add("bilateral-sigma-depth", &bilateral_sigma_depth_m, "Depth sigma of the bilateral filter, metres");
  f->Add("normal-max-jump", &normal_max_jump, "Normals are dropped across depth jumps above this fraction of the depth");
  f->Section("Rigid tracking (ICP)");
  f->AddCustom("icp-iterations", "L0,L1,L2",
               std::to_string(icp_iterations[0]) + "," + std::to_string(icp_iterations[1]) + "," +
                   std::to_string(icp_iterations[2]),
               "Rigid ICP iterations per pyramid level, finest first", [this](const std::string& v) {
                 const std::string expected = "--icp-iterations expects three counts like 10,5,4, got '" + v + "'";
                 std::array<int, 3> it{};
                 size_t n = 0, begin = 0;
                 for (;;) {
                   const size_t end = std::min(v.find(',', begin), v.size());
                   if (n == it.size()) return InvalidArgument(expected);
                   VD_ASSIGN_OR_RETURN(int64_t x, ParseFlagInteger("icp-iterations", v.substr(begin, end - begin), 0, 100));
                   it[n++] = int(x);
                   if (end == v.size()) break;
                   begin = end + 1;
                 }
                 if (n != it.size()) return InvalidArgument(expected);
                 icp_iterations = it;
                 return Status::Ok();
               });
  f->Add("icp-degeneracy", &icp_degeneracy,
         "ICP information ratio below which a pose direction is held at the last pose (0 = off)");
  f->Add("icp-max-distance", &icp_max_distance, "ICP correspondences farther apart than this are rejected, metres");
  f->Add("icp-min-step", &icp_min_step,
         "An ICP pyramid level stops when a pose step |xi| (radians and metres) is below this");
  f->Add("icp-max-normal-angle", &icp_max_normal_angle_deg,
         "ICP correspondences whose normals differ by more than this are rejected, degrees");
  f->Add("min-inlier-fraction", &min_inlier_fraction,
         "Tracking fails when fewer than this fraction of the valid pixels are ICP inliers");
  f->Add("max-frame-translation", &max_frame_translation, "Tracking fails when the pose moves more than this per frame, metres");
  f->Add("max-frame-rotation", &max_frame_rotation_deg, "Tracking fails when the pose turns more than this per frame, degrees");
  f->Section("Non-rigid tracking (sections 5-7)");
  f->Add("outer-iterations", &nonrigid_outer_iterations,
         "Non-rigid outer iterations per frame (new correspondences each; 0 = rigid tracking with the field kept)");
  f->Add("solve-view-margin", &solve_view_margin,
         "Solve only for the surface points in the view widened by this fraction of the image on each side "
         "(negative = all of them)");
  f->Add("corr-eps-d", &corr_eps_d, "Dense correspondences farther apart than this are rejected, metres");
  f->Add("corr-eps-n", &corr_eps_n, "Dense correspondences whose normals deviate more (1 - cos) are rejected");
  f->Add("corr-eps-v", &corr_eps_v, "Dense correspondences seen more obliquely (1 - cos) are rejected");
  solver.Bind(f);
  features.Bind(f);
}

Status EngineParams::Validate() const {
  if (!(voxel_size >= 0.0005f && voxel_size <= 0.1f)) return ParamOutOfBounds("EngineParams", "voxel_size", voxel_size, "0.0005 <= voxel_size <= 0.1 m");
  if (!(truncation_voxels >= 1.f && truncation_voxels <= 50.f))
    return ParamOutOfBounds("EngineParams", "truncation_voxels", truncation_voxels, "1 <= truncation_voxels <= 50");
  if (!(max_weight >= 1.f && max_weight <= 1e4f)) return ParamOutOfBounds("EngineParams", "max_weight", max_weight, "1 <= max_weight <= 1e4");
  if (!(min_depth >= 0.f && min_depth < max_depth)) return ParamOutOfBounds("EngineParams", "min_depth", min_depth, "0 <= min_depth < max_depth");
  if (!(max_depth <= 20.f)) return ParamOutOfBounds("EngineParams", "max_depth", max_depth, "max_depth <= 20 m");
  if (colour_registered != "auto" && colour_registered != "yes" && colour_registered != "no")
    return InvalidArgument("--colour-registered expects auto, yes or no, got '" + colour_registered + "'");
  if (prefetch_preprocess != "auto" && prefetch_preprocess != "on" && prefetch_preprocess != "off")
    return InvalidArgument("--prefetch-preprocess expects auto, on or off, got '" + prefetch_preprocess + "'");
  if (!(max_grid_mb >= 1.0 && max_grid_mb <= 64000.0)) return ParamOutOfBounds("EngineParams", "max_grid_mb", max_grid_mb, "1 <= max_grid_mb <= 64000");
  if (!(volume_margin >= 0.f && volume_margin <= 2.f)) return ParamOutOfBounds("EngineParams", "volume_margin", volume_margin, "0 <= volume_margin <= 2 m");
  if (!(bilateral_radius >= 1 && bilateral_radius <= 7)) return ParamOutOfBounds("EngineParams", "bilateral_radius", bilateral_radius, "1 <= r <= 7");
  if (!(bilateral_sigma_space_px > 0.f)) return ParamOutOfBounds("EngineParams", "bilateral_sigma_space_px", bilateral_sigma_space_px, "> 0");
  if (!(bilateral_sigma_depth_m > 0.f)) return ParamOutOfBounds("EngineParams", "bilateral_sigma_depth_m", bilateral_sigma_depth_m, "> 0");
  for (int it : icp_iterations)
    if (it < 0 || it > 100) return ParamOutOfBounds("EngineParams", "icp_iterations", it, "0 <= iterations <= 100");
  if (!(icp_degeneracy >= 0.f && icp_degeneracy < 0.1f)) return ParamOutOfBounds("EngineParams", "icp_degeneracy", icp_degeneracy, "0 <= tau < 0.1");
  if (!(icp_max_distance > 0.f)) return ParamOutOfBounds("EngineParams", "icp_max_distance", icp_max_distance, "> 0");
  if (!(icp_min_step >= 0.f && icp_min_step <= 1e-3f))
    return ParamOutOfBounds("EngineParams", "icp_min_step", icp_min_step, "0 <= step <= 1e-3");
  if (!(icp_max_normal_angle_deg > 0.f && icp_max_normal_angle_deg <= 90.f))
    return ParamOutOfBounds("EngineParams", "icp_max_normal_angle_deg", icp_max_normal_angle_deg, "0 < angle <= 90");
  if (!(min_inlier_fraction >= 0.f && min_inlier_fraction < 1.f))
    return ParamOutOfBounds("EngineParams", "min_inlier_fraction", min_inlier_fraction, "0 <= f < 1");
  if (!(max_frame_translation > 0.f)) return ParamOutOfBounds("EngineParams", "max_frame_translation", max_frame_translation, "> 0");
  if (!(max_frame_rotation_deg > 0.f)) return ParamOutOfBounds("EngineParams", "max_frame_rotation_deg", max_frame_rotation_deg, "> 0");
  if (!(solve_view_margin <= 10.f))
    return ParamOutOfBounds("EngineParams", "solve_view_margin", solve_view_margin, "margin <= 10 (negative = off)");
  if (!(nonrigid_outer_iterations >= 0 && nonrigid_outer_iterations <= 20))
    return ParamOutOfBounds("EngineParams", "nonrigid_outer_iterations", nonrigid_outer_iterations, "0 <= n <= 20");
  if (!(corr_eps_d > 0.f && corr_eps_n > 0.f && corr_eps_n <= 2.f && corr_eps_v > 0.f && corr_eps_v <= 2.f))
    return ParamOutOfBounds("EngineParams", "corr_eps_*", corr_eps_d, "eps_d > 0, 0 < eps_n, eps_v <= 2");
  if (!(k_min >= 0.f && k_min <= 100.f)) return ParamOutOfBounds("EngineParams", "k_min", k_min, "0 <= k_min <= 100");
  if (!(field_rigid_threshold >= 0.f && field_rigid_threshold <= 1.f))
    return ParamOutOfBounds("EngineParams", "field_rigid_threshold", field_rigid_threshold, "0 <= threshold <= 1 m");
  if (!(static_levels >= 0 && static_levels <= 8))
    return ParamOutOfBounds("EngineParams", "static_levels", static_levels, "0 <= static_levels <= 8");
  if (!(static_solve_every >= 1 && static_solve_every <= 10))
    return ParamOutOfBounds("EngineParams", "static_solve_every", static_solve_every,
                            "1 <= static_solve_every <= 10 (--static-solve-every)");
  if (!(k_min_new >= 0.f && k_min_new <= 100.f))
    return ParamOutOfBounds("EngineParams", "k_min_new", k_min_new, "0 <= k_min_new <= 100");
  if (!(carve_rate >= 0.f && carve_rate < 1.f))
    return ParamOutOfBounds("EngineParams", "carve_rate", carve_rate, "0 <= carve_rate < 1");
  if (!(carve_radius >= 0 && carve_radius <= 8))
    return ParamOutOfBounds("EngineParams", "carve_radius", carve_radius, "0 <= carve_radius <= 8");
  if (sparse_volume && !rigid_only && solver.levels > 4)
    return InvalidArgument("--sparse-volume: on bricks of 8 voxels the solver has at most 4 levels (--levels " +
                           std::to_string(solver.levels) + ")");
  if (sparse_volume && !rigid_only && solver.levels > 1 && !solver.cache_btb_coarse)
    return InvalidArgument(
        "--sparse-volume solves the coarse levels from cached B^T B blocks: drop --no-btb-cache-coarse");
  VD_RETURN_IF_ERROR(solver.Validate());
  VD_RETURN_IF_ERROR(features.Validate());
  return Status::Ok();
}

StatusOr<std::unique_ptr<Engine>> Engine::Create(const EngineParams& params, const std::string& device_spec) {
  VD_RETURN_IF_ERROR(params.Validate());
  VD_ASSIGN_OR_RETURN(auto ctx, ocl::Context::Create(device_spec));
  // OpenCV's worker pool spins between jobs: beside an OpenCL device that runs on the same CPU
  // cores (PoCL) it took twice its own time from the kernels (measured on the tube: 4.95 fps with
  // OpenCV's pool, 6.38 with one OpenCV thread; 6.81 without features). Feature detection runs
  // on its own thread anyway, so OpenCV gets one.
  if (params.features.enabled && ctx->device().is_cpu) cv::setNumThreads(1);
  std::unique_ptr<Engine> e(new Engine(params, std::move(ctx)));
  VD_RETURN_IF_ERROR(e->ops_.Init());
  // Pipelining needs the second queue; without one every frame is preprocessed in Process.
  const bool prefetch =
      params.prefetch_preprocess == "on" || (params.prefetch_preprocess == "auto" && e->ctx_->device().is_gpu);
  if (!prefetch) return e;
  if (auto sibling = e->ctx_->CreateSibling(); sibling.ok()) {
    e->prep_ctx_ = std::move(sibling).value();
    e->prep_ops_ = std::make_unique<DeviceOps>(e->prep_ctx_.get());
    if (Status s = e->prep_ops_->Init(); !s.ok()) {
      VD_LOG_WARNING << "no second OpenCL queue, frames are preprocessed one after another: " << s.ToString();
      e->prep_ops_.reset();
      e->prep_ctx_.reset();
    }
  } else {
    VD_LOG_WARNING << "no second OpenCL queue, frames are preprocessed one after another: "
                   << sibling.status().ToString();
  }
  return e;
}

Engine::~Engine() { DropPrefetch(); }

Engine::Engine(const EngineParams& params, std::unique_ptr<ocl::Context> ctx)
    : params_(params),
      ctx_(std::move(ctx)),
      ops_(ctx_.get()),
      colour_check_(ColourRegistrationParams(), params_.min_depth, params_.max_depth),
      solver_(std::make_unique<HierarchicalSolver>(&ops_, params_.solver)),
      matcher_(ctx_.get(), params_.features) {
  extractor_.Configure(params_.features, params_.min_depth, params_.max_depth);
}

bool Engine::SparseEnabled() const {
  return params_.features.enabled && !params_.rigid_only && params_.nonrigid_outer_iterations > 0;
}

bool Engine::PhotometricWanted() const {
  return params_.solver.w_photo > 0.f && !params_.rigid_only && params_.nonrigid_outer_iterations > 0 &&
         params_.colour_registered != "no" && colour_verdict_.load() != ColourRegistration::Verdict::kUnregistered;
}

bool Engine::PhotometricEnabled() const {
  return PhotometricWanted() &&
         (params_.colour_registered == "yes" || colour_verdict_.load() == ColourRegistration::Verdict::kRegistered);
}

void Engine::CheckColourRegistration(const RgbdFrame& frame) {
  if (params_.colour_registered != "auto" || colour_check_.verdict() != ColourRegistration::Verdict::kUndecided ||
      !(params_.solver.w_photo > 0.f) || params_.rigid_only || params_.nonrigid_outer_iterations <= 0)
    return;
  const ColourRegistration::Verdict v = colour_check_.Add(frame);
  if (v == ColourRegistration::Verdict::kUndecided) return;
  colour_verdict_.store(v);
  char line[320];
  std::snprintf(line, sizeof line,
                "colour %s to depth (edge alignment %.2f over %lld depth-edge crossings in %d frames; registered "
                "from %.2f): the dense colour term is %s%s",
                VerdictName(v), colour_check_.ratio(), static_cast<long long>(colour_check_.samples()),
                colour_check_.frames(), colour_check_.params().min_peak_ratio,
                v == ColourRegistration::Verdict::kRegistered ? "on" : "off",
                v == ColourRegistration::Verdict::kRegistered ? "" : " (--colour-registered yes overrides)");
  VD_LOG_INFO << line;
}

void Engine::Prefetch(const RgbdFrame& next) {
  if (!next.Validate().ok()) return;
  if (SparseEnabled()) extractor_.Prefetch(next);
  if (!prep_ops_) return;
  std::vector<Prefetched> dropped;
  {
    std::lock_guard<std::mutex> lock(prep_mu_);
    if (prefetched_.count(next.seq)) return;
    while (prefetched_.size() >= kMaxPrefetched) {
      dropped.push_back(std::move(prefetched_.begin()->second));
      prefetched_.erase(prefetched_.begin());
    }
    Prefetched& p = prefetched_[next.seq];
    if (!spare_maps_.empty()) {
      p.maps = std::move(spare_maps_.back());
      spare_maps_.pop_back();
    } else {
      p.maps = std::make_unique<FrameMaps>();
    }
    p.frame = std::make_unique<RgbdFrame>(next);
    p.frame->color = next.color.clone();
    p.frame->depth = next.depth.clone();
    if (prep_window_) LaunchPrefetch(&p);
  }
  // A dropped one's thread still writes its maps: they are freed only after it ends.
  for (Prefetched& p : dropped)
    if (p.done.valid()) p.done.wait();
}

void Engine::LaunchPrefetch(Prefetched* p) {
  p->done = std::async(std::launch::async, [this, maps = p->maps.get(), frame = p->frame.get()]() {
    NameThisThread("vd-prep");
    std::lock_guard<std::mutex> one_at_a_time(prep_run_mu_);
    return Preprocess(*prep_ctx_, *prep_ops_, *frame, maps);
  });
}

void Engine::SetPrefetchWindow(bool open) {
  std::lock_guard<std::mutex> lock(prep_mu_);
  prep_window_ = open;
  if (!open) return;
  for (auto& [seq, p] : prefetched_)
    if (!p.done.valid()) LaunchPrefetch(&p);
}

void Engine::DropPrefetch() {
  std::map<int64_t, Prefetched> dropped;
  {
    std::lock_guard<std::mutex> lock(prep_mu_);
    dropped.swap(prefetched_);
  }
  for (auto& [seq, p] : dropped)
    if (p.done.valid()) p.done.wait();
}

Status Engine::TakeMaps(const RgbdFrame& frame) {
  std::optional<Prefetched> mine;
  std::vector<Prefetched> stale;
  {
    std::lock_guard<std::mutex> lock(prep_mu_);
    for (auto it = prefetched_.begin(); it != prefetched_.end() && it->first <= frame.seq;) {
      if (it->first == frame.seq)
        mine = std::move(it->second);
      else
        stale.push_back(std::move(it->second));
      it = prefetched_.erase(it);
    }
  }
  for (Prefetched& p : stale)
    if (p.done.valid()) p.done.wait();
  Status built = FailedPrecondition("not prefetched");
  if (mine && mine->done.valid()) {
    built = mine->done.get();
    // The same size, or it was built for another stream's frame of this number.
    if (built.ok() &&
        (mine->maps->cam.width != frame.intrinsics.width || mine->maps->cam.height != frame.intrinsics.height))
      built = FailedPrecondition("prefetched at another size");
    if (built.ok()) std::swap(maps_, *mine->maps);
  }
  {
    std::lock_guard<std::mutex> lock(prep_mu_);
    for (Prefetched& p : stale) spare_maps_.push_back(std::move(p.maps));
    if (mine) spare_maps_.push_back(std::move(mine->maps));
  }
  // A failed or mismatched prefetch: preprocessed here, where a failure that recurs is returned.
  if (built.ok()) return Status::Ok();
  return Preprocess(*ctx_, ops_, frame, &maps_);
}

Status Engine::DownloadDeformation(std::vector<vd_float4>* def_pos) {
  if (bricks_) return Unimplemented("the sparse volume's field is per brick: there is no grid to download");
  if (!volume_.has_deformation()) return FailedPrecondition("the grid has no deformation field");
  def_pos->resize(volume_.num_voxels());
  return ctx_->Download(volume_.def_pos, def_pos->data(), def_pos->size());
}

Status Engine::SaveState(EngineState* state) {
  if (!initialised_) return FailedPrecondition("no model yet: nothing to save");
  EngineState& s = *state;
  s.vol = volume_.vol;
  s.has_deformation = has_field();
  s.sparse = bricks_.has_value();
  s.def_pos.clear();
  s.def_rot.clear();
  s.brick_keys.clear();
  if (s.sparse) {
    // Every slot handed out, in slot order, with its voxels.
    VD_ASSIGN_OR_RETURN(const ocl::BrickCounts counts, bricks_->Counts(*ctx_));
    const size_t n = size_t(counts.used) * VD_BRICK_VOXELS;
    s.brick_keys.resize(counts.used);
    s.tsdf.resize(n);
    s.weight.resize(n);
    s.color.resize(n);
    VD_RETURN_IF_ERROR(ctx_->Download(bricks_->slot_keys(), s.brick_keys.data(), counts.used));
    VD_RETURN_IF_ERROR(ctx_->Download(pool_->tsdf, s.tsdf.data(), n));
    VD_RETURN_IF_ERROR(ctx_->Download(pool_->weight, s.weight.data(), n));
    VD_RETURN_IF_ERROR(ctx_->Download(pool_->color, s.color.data(), n));
    if (s.has_deformation) {
      s.def_pos.resize(n);
      s.def_rot.resize(n);
      VD_RETURN_IF_ERROR(ctx_->Download(pool_->def_pos, s.def_pos.data(), n));
      VD_RETURN_IF_ERROR(ctx_->Download(pool_->def_rot, s.def_rot.data(), n));
    }
  } else {
    VD_RETURN_IF_ERROR(DownloadVolume(&s.tsdf, &s.weight, &s.color));
  }
  if (s.has_deformation && !s.sparse) {
    s.def_pos.resize(volume_.num_voxels());
    s.def_rot.resize(volume_.num_voxels());
    VD_RETURN_IF_ERROR(ctx_->Download(volume_.def_pos, s.def_pos.data(), s.def_pos.size()));
    VD_RETURN_IF_ERROR(ctx_->Download(volume_.def_rot, s.def_rot.data(), s.def_rot.size()));
  }
  s.pose = pose_;
  s.cam = cam_;
  s.frames_fused = frames_fused_;
  s.frames_seen = frames_seen_;
  s.history = history_.frames();
  s.keyframes = history_.keyframes();
  s.links = history_.links();
  s.tracked = track_mesh_ ? tracked_canonical_ : TriangleMesh();
  s.colour_registration = static_cast<uint8_t>(colour_verdict_.load());
  return Status::Ok();
}

Status Engine::RestoreState(const EngineState& s, FrameResult* meshes) {
  Reset();
  VD_RETURN_IF_ERROR(s.Validate());
  if (s.sparse != params_.sparse_volume)
    return FailedPrecondition(std::string("the checkpoint holds a ") + (s.sparse ? "sparse" : "dense") +
                              " volume; this server runs " + (params_.sparse_volume ? "with" : "without") +
                              " --sparse-volume");
  if (s.has_deformation == params_.rigid_only)
    return FailedPrecondition(std::string("the checkpoint was written by a ") +
                              (s.has_deformation ? "non-rigid" : "rigid-only") + " server; this one is " +
                              (params_.rigid_only ? "rigid-only" : "non-rigid"));
  if (s.sparse) {
    // The checkpoint's voxel size, truncation and weight cap go on, as a dense grid's placement does.
    VD_RETURN_IF_ERROR(CreateBricks());
    volume_.vol = s.vol;
    const size_t bricks = s.brick_keys.size(), n = bricks * VD_BRICK_VOXELS;
    if (bricks > bricks_->pool())
      return FailedPrecondition("the checkpoint's " + std::to_string(bricks) + " bricks do not fit --max-grid-mb (" +
                                std::to_string(bricks_->pool()) + " bricks)");
    VD_ASSIGN_OR_RETURN(ocl::Buffer<uint32_t> keys, ctx_->Alloc<uint32_t>(std::max<size_t>(bricks, 1)));
    VD_RETURN_IF_ERROR(ctx_->Upload(keys, s.brick_keys.data(), bricks));
    Status restored = bricks_->Restore(*ctx_, keys, bricks);
    if (restored.ok()) restored = pool_->Grow(*ctx_, uint32_t(bricks));
    if (restored.ok()) restored = ctx_->Upload(pool_->tsdf, s.tsdf.data(), n);
    if (restored.ok()) restored = ctx_->Upload(pool_->weight, s.weight.data(), n);
    if (restored.ok()) restored = ctx_->Upload(pool_->color, s.color.data(), n);
    if (restored.ok() && s.has_deformation) restored = ctx_->Upload(pool_->def_pos, s.def_pos.data(), n);
    if (restored.ok() && s.has_deformation) restored = ctx_->Upload(pool_->def_rot, s.def_rot.data(), n);
    bricks_in_use_ = uint32_t(bricks);
    if (!restored.ok()) {
      Reset();
      return restored;
    }
  } else {
    const double budget = params_.max_grid_mb * 1e6 / DenseGridPointBytes(!params_.rigid_only);
    if (double(s.num_voxels()) > budget)
      return FailedPrecondition("the checkpoint's grid (" + std::to_string(s.num_voxels()) +
                                " points) does not fit max_grid_mb");
    if (volume_.num_voxels() != s.num_voxels() || volume_.has_deformation() != s.has_deformation) {
      volume_ = DeviceVolume();
      VD_RETURN_IF_ERROR(ops_.AllocVolume(s.vol, s.has_deformation, &volume_));
    }
    volume_.vol = s.vol;
    const size_t n = s.num_voxels();
    VD_RETURN_IF_ERROR(ctx_->Upload(volume_.tsdf, s.tsdf.data(), n));
    VD_RETURN_IF_ERROR(ctx_->Upload(volume_.weight, s.weight.data(), n));
    VD_RETURN_IF_ERROR(ctx_->Upload(volume_.color, s.color.data(), n));
    VD_RETURN_IF_ERROR(ops_.MarkTouched(volume_));
    if (s.has_deformation) {
      VD_RETURN_IF_ERROR(ctx_->Upload(volume_.def_pos, s.def_pos.data(), n));
      VD_RETURN_IF_ERROR(ctx_->Upload(volume_.def_rot, s.def_rot.data(), n));
    }
  }
  cam_ = s.cam;
  pose_ = model_pose_ = s.pose;
  frames_fused_ = s.frames_fused;
  frames_seen_ = s.frames_seen;
  history_.Restore(s.history, s.keyframes, s.links);
  colour_check_.Restore(static_cast<ColourRegistration::Verdict>(s.colour_registration));
  colour_verdict_.store(colour_check_.verdict());
  initialised_ = true;
  // The tracked mesh goes on with the vertices it had (a run that tracks a given mesh keeps that).
  if (track_mesh_ && !s.tracked.triangles.empty() && track_given_.positions.empty()) {
    Status t = FixTracked(s.tracked);
    if (!t.ok()) {
      Reset();
      return t;
    }
  }
  // The surface the next frame is tracked against.
  FrameResult scratch;
  FrameResult* out = meshes ? meshes : &scratch;
  out->pose = pose_;
  out->seq = s.last_seq;
  Status st = ExtractMesh(out);
  if (!st.ok()) Reset();
  return st;
}

void Engine::Reset() {
  DropPrefetch();
  initialised_ = false;
  frames_fused_ = 0;
  frames_seen_ = 0;
  frames_since_rigid_check_ = 0;
  frames_since_state_check_ = 0;
  field_static_ = false;
  static_unsolved_ = 0;
  colour_check_.Clear();
  colour_verdict_.store(ColourRegistration::Verdict::kUndecided);
  history_.Clear();
  extractor_.Clear();
  matches_.clear();
  pose_ = model_pose_ = Eigen::Matrix4d::Identity();
  mesh_.num_vertices = mesh_.num_triangles = mesh_.num_brick_slots = 0;
  tracked_.num_vertices = tracked_.num_triangles = 0;
  tracked_canonical_ = TriangleMesh();
}

Status Engine::TrackMesh(const TriangleMesh& canonical) {
  if (!canonical.positions.empty() || !canonical.triangles.empty()) {
    const size_t nv = canonical.num_vertices();
    if (nv == 0 || canonical.triangles.empty() || canonical.positions.size() != 3 * nv)
      return InvalidArgument("the mesh to track needs vertices and faces");
    for (int32_t i : canonical.triangles)
      if (i < 0 || size_t(i) >= nv)
        return InvalidArgument("the mesh to track has a face naming vertex " + std::to_string(i) + " of " +
                               std::to_string(nv));
    for (float v : canonical.positions)
      if (!std::isfinite(v)) return InvalidArgument("the mesh to track has a non-finite vertex");
  }
  track_mesh_ = true;
  track_given_ = canonical;
  tracked_.num_vertices = tracked_.num_triangles = 0;
  return Status::Ok();
}

Status Engine::FixTracked(const TriangleMesh& source) {
  const size_t nv = source.num_vertices();
  const VdVolume& vol = volume_.vol;
  std::vector<vd_float4> grid(nv);
  size_t outside = 0;
  for (size_t i = 0; i < nv; ++i) {
    const float* p = &source.positions[3 * i];
    grid[i] = VD_F4((p[0] - vol.origin.x) / vol.voxel_size, (p[1] - vol.origin.y) / vol.voxel_size,
                    (p[2] - vol.origin.z) / vol.voxel_size, 1.f);
    outside += !bricks_ && (grid[i].x < 0 || grid[i].y < 0 || grid[i].z < 0 || grid[i].x > vol.dim_x - 1 ||
                            grid[i].y > vol.dim_y - 1 || grid[i].z > vol.dim_z - 1);
  }
  if (outside > 0)
    VD_LOG_WARNING << "tracked mesh: " << outside << " of " << nv
                   << " vertices lie outside the volume; they follow its nearest cells' field";
  VD_RETURN_IF_ERROR(ctx_->Reserve(&tracked_.positions_grid, nv));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&tracked_.positions, nv));
  VD_RETURN_IF_ERROR(ctx_->Upload(tracked_.positions_grid, grid.data(), nv));
  tracked_.num_vertices = nv;
  tracked_.num_triangles = source.triangles.size() / 3;
  tracked_canonical_.positions = source.positions;
  tracked_canonical_.colors = source.colors;
  tracked_canonical_.triangles = source.triangles;
  return Status::Ok();
}

Status Engine::ExtractTracked(FrameResult* result) {
  if (!track_mesh_) return Status::Ok();
  if (tracked_.num_vertices == 0) {
    // Fixed now: the given mesh, or this (first) frame's canonical mesh.
    const TriangleMesh& source = track_given_.positions.empty() ? result->canonical_mesh : track_given_;
    if (source.num_vertices() == 0 || source.triangles.empty()) return Status::Ok();  // nothing fused yet
    VD_RETURN_IF_ERROR(FixTracked(source));
  }
  result->tracked_mesh.triangles = tracked_canonical_.triangles;
  result->tracked_mesh.colors = tracked_canonical_.colors;
  const size_t nv = tracked_.num_vertices;
  if (bricks_ && pool_->with_field) {
    VD_RETURN_IF_ERROR(ops_.DeformVertices(*bricks_, *pool_, volume_.vol.voxel_size, &tracked_));
  } else if (volume_.has_deformation()) {
    VD_RETURN_IF_ERROR(ops_.DeformVertices(volume_, &tracked_));
  } else {
    VD_RETURN_IF_ERROR(ops_.GridToWorld(volume_.vol, &tracked_));
  }
  tracked_host_.resize(nv);
  VD_RETURN_IF_ERROR(ctx_->Download(tracked_.positions, tracked_host_.data(), nv));
  const Eigen::Matrix4d inv = pose_.inverse();
  const Eigen::Matrix3f R = inv.topLeftCorner<3, 3>().cast<float>();
  const Eigen::Vector3f tr = inv.topRightCorner<3, 1>().cast<float>();
  TriangleMesh& t = result->tracked_mesh;
  t.positions.resize(3 * nv);
  for (size_t i = 0; i < nv; ++i) {
    const Eigen::Vector3f p = R * Eigen::Vector3f(tracked_host_[i].x, tracked_host_[i].y, tracked_host_[i].z) + tr;
    for (int a = 0; a < 3; ++a) t.positions[3 * i + a] = p[a];
  }
  return Status::Ok();
}

StatusOr<VdVolume> Engine::PlaceVolume(const RgbdFrame& frame, const EngineParams& p) {
  // Robust bounds of the valid points: 1st and 99th percentile per axis.
  std::vector<float> xs, ys, zs;
  const Intrinsics& k = frame.intrinsics;
  const float inv = 1.f / frame.depth_scale;
  for (int y = 0; y < frame.depth.rows; y += 2) {
    const uint16_t* row = frame.depth.ptr<uint16_t>(y);
    for (int x = 0; x < frame.depth.cols; x += 2) {
      const float d = row[x] * inv;
      if (row[x] == 0 || d < p.min_depth || d > p.max_depth) continue;
      xs.push_back((x - k.cx) * d / k.fx);
      ys.push_back((y - k.cy) * d / k.fy);
      zs.push_back(d);
    }
  }
  if (zs.size() < 100) {
    return FailedPrecondition("the first frame has only " + std::to_string(zs.size() * 4) +
                              " valid depth pixels in [min_depth, max_depth]; cannot place the volume");
  }
  auto pct = [](std::vector<float>& v, double q) {
    const size_t i = std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1)));
    std::nth_element(v.begin(), v.begin() + i, v.end());
    return v[i];
  };
  const float lo[3] = {pct(xs, 0.01), pct(ys, 0.01), pct(zs, 0.01)};
  const float hi[3] = {pct(xs, 0.99), pct(ys, 0.99), pct(zs, 0.99)};
  const float trunc = p.truncation_voxels * p.voxel_size;
  VdVolume vol{};
  float mn[3], ext[3];
  int dims[3];
  // Grid points the memory budget holds.
  const double budget = p.max_grid_mb * 1e6 / DenseGridPointBytes(!p.rigid_only);
  // The box around the first view with `margin` metres of room, `scale` of each side kept; its
  // grid points.
  auto place = [&](float margin, double scale) {
    int64_t total = 1;
    for (int a = 0; a < 3; ++a) {
      const float m = margin + 2.f * trunc;
      mn[a] = lo[a] - m;
      ext[a] = hi[a] - lo[a] + 2.f * m;
      dims[a] = std::max(8, static_cast<int>(std::ceil(ext[a] * scale / p.voxel_size)) + 1);
      total *= dims[a];
    }
    return double(total);
  };
  // The room around the view gives way first: the largest margin up to volume_margin that fits
  // (cropping the box instead loses the surface the first frame saw; with --volume-margin 1.5 the
  // tube was lost in 59 of 60 frames, docs/BENCHMARKS.md "Sparse volume").
  float margin = p.volume_margin;
  if (place(margin, 1.0) > budget) {
    float fits = 0.f, fails = margin;
    if (place(0.f, 1.0) <= budget) {
      for (int iter = 0; iter < 24; ++iter) {
        const float mid = 0.5f * (fits + fails);
        (place(mid, 1.0) <= budget ? fits : fails) = mid;
      }
    }
    margin = fits;
    VD_LOG_WARNING << "a margin of " << p.volume_margin << " m around the first frame does not fit " << p.max_grid_mb
                   << " MB of " << p.voxel_size * 1000 << " mm voxels; the grid keeps " << margin << " m";
  }
  // Shrink around the centre until the grid fits the budget (the far part goes first in z): only
  // when the first view alone is larger than the budget.
  double scale = 1.0;
  for (int iter = 0; iter < 64; ++iter) {
    if (place(margin, scale) <= budget) break;
    scale *= 0.95;
  }
  int64_t total = int64_t(dims[0]) * dims[1] * dims[2];
  if (double(total) > budget) return FailedPrecondition("the grid does not fit max_grid_mb");
  if (scale < 1.0) {
    VD_LOG_WARNING << "first frame spans " << ext[0] << " x " << ext[1] << " x " << ext[2] << " m; the grid of "
                   << p.voxel_size * 1000 << " mm voxels is limited to " << p.max_grid_mb << " MB = "
                   << int64_t(budget) << " points, so it covers " << scale * 100 << "% of each side (nearest part kept in depth)";
    for (int a = 0; a < 2; ++a) mn[a] += 0.5f * float(1.0 - scale) * ext[a];
  }
  vol.origin = VD_F4(mn[0], mn[1], mn[2], 1.f);
  vol.dim_x = dims[0];
  vol.dim_y = dims[1];
  vol.dim_z = dims[2];
  vol.voxel_size = p.voxel_size;
  vol.truncation = trunc;
  vol.max_weight = p.max_weight;
  return vol;
}

Status Engine::Preprocess(ocl::Context& ctx, DeviceOps& ops, const RgbdFrame& frame, FrameMaps* out) const {
  const Intrinsics& k = frame.intrinsics;
  const size_t n = static_cast<size_t>(k.width) * k.height;
  FrameMaps& m = *out;
  m.cam = ToVdCamera(k);
  VD_RETURN_IF_ERROR(ctx.Reserve(&m.raw_depth, n));
  VD_RETURN_IF_ERROR(ctx.Reserve(&m.rgba, n));
  VD_RETURN_IF_ERROR(ctx.Reserve(&m.depth_raw_m, n));
  for (int l = 0; l < 3; ++l) {
    const size_t nl = static_cast<size_t>(k.width >> l) * (k.height >> l);
    VD_RETURN_IF_ERROR(ctx.Reserve(&m.depth[l], nl));
    VD_RETURN_IF_ERROR(ctx.Reserve(&m.vmap[l], nl));
    VD_RETURN_IF_ERROR(ctx.Reserve(&m.nmap[l], nl));
  }
  const cv::Mat depth = frame.depth.isContinuous() ? frame.depth : frame.depth.clone();
  m.valid_pixels = 0;
  const uint16_t lo = uint16_t(std::clamp(params_.min_depth * frame.depth_scale, 1.f, 65535.f));
  const uint16_t hi = uint16_t(std::clamp(params_.max_depth * frame.depth_scale, 1.f, 65535.f));
  for (size_t i = 0; i < n; ++i) {
    const uint16_t d = depth.ptr<uint16_t>()[i];
    m.valid_pixels += d >= lo && d <= hi;
  }
  VD_RETURN_IF_ERROR(ctx.Upload(m.raw_depth, depth.ptr<uint16_t>(), n));
  m.rgba_host.resize(n);
  if (frame.color.empty()) {
    std::fill(m.rgba_host.begin(), m.rgba_host.end(), 0u);
  } else {
    cv::Mat rgba(k.height, k.width, CV_8UC4, m.rgba_host.data());
    cv::cvtColor(frame.color, rgba, cv::COLOR_BGR2RGBA);
  }
  VD_RETURN_IF_ERROR(ctx.Upload(m.rgba, m.rgba_host.data(), n));
  VD_RETURN_IF_ERROR(ops.DepthConvert(m.raw_depth, m.depth_raw_m, int(n), 1.f / frame.depth_scale, params_.min_depth,
                                      params_.max_depth));
  if (params_.bilateral) {
    VD_RETURN_IF_ERROR(ops.Bilateral(m.depth_raw_m, m.depth[0], k.width, k.height, params_.bilateral_radius,
                                     params_.bilateral_sigma_space_px, params_.bilateral_sigma_depth_m));
  } else {
    VD_RETURN_IF_ERROR(ctx.Copy(m.depth_raw_m, m.depth[0], n));
  }
  if (PhotometricWanted()) {
    const size_t half = static_cast<size_t>(k.width / 2) * (k.height / 2);
    VD_RETURN_IF_ERROR(ctx.Reserve(&m.intensity, half));
    VD_RETURN_IF_ERROR(ctx.Reserve(&m.intensity_tmp, half));
    VD_RETURN_IF_ERROR(ops.Intensity(m.rgba, m.intensity_tmp, m.intensity, k.width, k.height));
  }
  for (int l = 0; l < 3; ++l) {
    const VdCamera cl = ScaledCamera(m.cam, l);
    if (l > 0)
      VD_RETURN_IF_ERROR(ops.PyrDown(m.depth[l - 1], m.depth[l], k.width >> (l - 1), k.height >> (l - 1), 0.05f));
    VD_RETURN_IF_ERROR(ops.VertexMap(m.depth[l], m.vmap[l], cl));
    VD_RETURN_IF_ERROR(ops.NormalMap(m.vmap[l], m.nmap[l], cl.width, cl.height, params_.normal_max_jump));
  }
  return ctx.Finish();
}

Status Engine::Track(FrameResult* result) {
  const float min_dot = std::cos(params_.icp_max_normal_angle_deg * float(M_PI) / 180.f);
  Eigen::Matrix4d T = pose_;
  const Eigen::Matrix4d model_inv = model_pose_.inverse();
  // E_sparse's part in the pose (paper eq. 1 with the field fixed): each match aligns its
  // keypoint with the earlier feature moved by the field.
  pose_pairs_.clear();
  for (const SparseMatch& m : matches_)
    pose_pairs_.push_back({Eigen::Vector3d(m.camera_point.x, m.camera_point.y, m.camera_point.z),
                           Eigen::Vector3d(m.predicted.x, m.predicted.y, m.predicted.z)});
  IcpSystem sys;
  Vector6d xi_total = Vector6d::Zero();
  for (int l = 2; l >= 0; --l) {
    const VdCamera cl = ScaledCamera(cam_, l);
    PoseStepParams step_params;
    step_params.sparse_weight =
        params_.features.w_sparse / std::max(1e-6f, params_.solver.w_dense) / float(1 << (2 * l));
    step_params.sparse_huber = params_.features.pose_huber;
    step_params.degeneracy = params_.icp_degeneracy;
    for (int it = 0; it < params_.icp_iterations[l]; ++it) {
      VdIcpParams prm{};
      prm.cam_to_world = ToVdPose(T);
      prm.world_to_model = ToVdPose(model_inv);
      prm.model_to_world = ToVdPose(model_pose_);
      prm.model_cam = model_.cam;
      prm.max_distance = params_.icp_max_distance;
      prm.min_normal_dot = min_dot;
      double acc[VD_ICP_ACC];
      VD_RETURN_IF_ERROR(
          ops_.IcpReduce(maps_.vmap[l], maps_.nmap[l], model_.vertex, model_.normal, cl.width * cl.height, prm, acc));
      sys = IcpSystem::FromAccumulator(acc);
      if (sys.inliers < 6) break;
      const PoseStep step = SolvePoseStep(sys, pose_pairs_, T, xi_total, step_params);
      if (!step.ok) break;
      T = step.pose;
      xi_total += step.xi;
      if (step.xi.norm() < params_.icp_min_step) break;
    }
  }
  result->icp_inliers = sys.inliers;
  result->icp_rmse = sys.inliers > 0 ? float(std::sqrt(sys.sum_sq_residual / sys.inliers)) : 0.f;
  TrackingLimits limits;
  limits.min_inlier_fraction = params_.min_inlier_fraction;
  limits.max_translation = params_.max_frame_translation;
  limits.max_rotation_deg = params_.max_frame_rotation_deg;
  const std::string why = CheckTracking(pose_, T, sys.inliers, maps_.valid_pixels, limits);
  if (!why.empty()) {
    result->tracking_ok = false;
    result->tracking_message = why + "; kept the last good pose";
    return Status::Ok();
  }
  pose_ = T;
  return Status::Ok();
}

Status Engine::ExtractMesh(FrameResult* result) {
  auto t0 = Clock::now();
  if (bricks_) {
    VD_RETURN_IF_ERROR(ops_.MarchingCubes(*bricks_, *pool_, &mesh_));
  } else {
    VD_RETURN_IF_ERROR(ops_.MarchingCubes(volume_, &mesh_));
  }
  if (bricks_ && pool_->with_field) {
    VD_RETURN_IF_ERROR(ops_.DeformVertices(*bricks_, *pool_, volume_.vol.voxel_size, &mesh_));
  } else if (volume_.has_deformation()) {
    VD_RETURN_IF_ERROR(ops_.DeformVertices(volume_, &mesh_));
  } else {
    VD_RETURN_IF_ERROR(ops_.GridToWorld(volume_.vol, &mesh_));
  }
  VD_RETURN_IF_ERROR(ctx_->Finish());
  result->times[Stage::kMarchingCubes] = MsSince(t0);
  t0 = Clock::now();
  const size_t nv = mesh_.num_vertices, nt = mesh_.num_triangles;
  // Host copies reuse the engine's scratch: no allocation per frame once the mesh stops growing.
  std::vector<vd_float4>& pos = host_pos_;
  std::vector<vd_float4>& grid = host_grid_;
  std::vector<vd_float4>& nrm = host_nrm_;
  std::vector<uint32_t>& col = host_col_;
  pos.resize(nv);
  grid.resize(nv);
  nrm.resize(nv);
  col.resize(nv);
  TriangleMesh& canon = result->canonical_mesh;
  canon.triangles.resize(3 * nt);
  VD_RETURN_IF_ERROR(ctx_->Download(mesh_.positions, pos.data(), nv));
  VD_RETURN_IF_ERROR(ctx_->Download(mesh_.positions_grid, grid.data(), nv));
  VD_RETURN_IF_ERROR(ctx_->Download(mesh_.normals, nrm.data(), nv));
  VD_RETURN_IF_ERROR(ctx_->Download(mesh_.colors, col.data(), nv));
  VD_RETURN_IF_ERROR(ctx_->Download(mesh_.triangles, canon.triangles.data(), 3 * nt));
  if (bricks_ && pool_->with_field) host_tris_.assign(canon.triangles.begin(), canon.triangles.end());
  canon.positions.resize(3 * nv);
  canon.normals.resize(3 * nv);
  canon.colors.resize(3 * nv);
  TriangleMesh& live = result->live_mesh;
  live.positions.resize(3 * nv);
  live.normals.resize(3 * nv);
  live.colors.resize(3 * nv);
  live.triangles = canon.triangles;
  const Eigen::Matrix4d inv = pose_.inverse();
  const Eigen::Matrix3f R = inv.topLeftCorner<3, 3>().cast<float>();
  const Eigen::Vector3f t = inv.topRightCorner<3, 1>().cast<float>();
  for (size_t i = 0; i < nv; ++i) {
    // Live: the deformed position seen from this frame's camera. Canonical: the undeformed grid
    // position (world = first frame's camera), same vertex order and faces.
    const Eigen::Vector3f p(pos[i].x, pos[i].y, pos[i].z), n(nrm[i].x, nrm[i].y, nrm[i].z);
    const Eigen::Vector3f rest(volume_.vol.origin.x + volume_.vol.voxel_size * grid[i].x,
                               volume_.vol.origin.y + volume_.vol.voxel_size * grid[i].y,
                               volume_.vol.origin.z + volume_.vol.voxel_size * grid[i].z);
    const Eigen::Vector3f pc = R * p + t, nc = R * n;
    for (int a = 0; a < 3; ++a) {
      canon.positions[3 * i + a] = rest[a];
      canon.normals[3 * i + a] = n[a];
      live.positions[3 * i + a] = pc[a];
      live.normals[3 * i + a] = nc[a];
      live.colors[3 * i + a] = canon.colors[3 * i + a] = uint8_t((col[i] >> (8 * a)) & 255u);
    }
  }
  result->times[Stage::kDownload] = MsSince(t0);
  return Status::Ok();
}

Eigen::Matrix4d Engine::FieldRigidMotion(const std::vector<vd_float4>& deformed, const std::vector<int32_t>& list,
                                         const VdVolume& vol, double* rms_motion, double* rms_residual) {
  std::vector<vd_float4> rest(std::min(list.size(), deformed.size()), VD_F4(0.f, 0.f, 0.f, 0.f));
  for (size_t k = 0; k < rest.size(); ++k) {
    if (list[k] < 0) continue;
    int x, y, z;
    vd_grid_coords(list[k], vol, &x, &y, &z);
    rest[k] = vd_rest_position(vol, x, y, z);
    rest[k].w = 1.f;
  }
  return FieldRigidMotion(deformed, rest, rms_motion, rms_residual);
}

Eigen::Matrix4d Engine::FieldRigidMotion(const std::vector<vd_float4>& deformed, const std::vector<vd_float4>& rest,
                                         double* rms_motion, double* rms_residual) {
  *rms_motion = 0.0;
  *rms_residual = 0.0;
  std::vector<Eigen::Vector3d> from, to;
  for (size_t k = 0; k < rest.size() && k < deformed.size(); ++k) {
    if (!(deformed[k].w > 0.f) || !(rest[k].w > 0.f)) continue;
    from.emplace_back(rest[k].x, rest[k].y, rest[k].z);
    to.emplace_back(deformed[k].x, deformed[k].y, deformed[k].z);
  }
  if (from.size() < 4) return Eigen::Matrix4d::Identity();
  const Eigen::Map<const Eigen::Matrix3Xd> src(from[0].data(), 3, Eigen::Index(from.size()));
  const Eigen::Map<const Eigen::Matrix3Xd> dst(to[0].data(), 3, Eigen::Index(to.size()));
  const Eigen::Matrix4d a = Eigen::umeyama(src, dst, false);
  const Eigen::Matrix3Xd moved = (a.topLeftCorner<3, 3>() * src).colwise() + a.topRightCorner<3, 1>();
  *rms_motion = std::sqrt((moved - src).colwise().squaredNorm().mean());
  *rms_residual = std::sqrt((dst - moved).colwise().squaredNorm().mean());
  return a;
}

Status Engine::FactorRigidMotion(FrameResult* result) {
  // A camera's pose error builds up over seconds, so a check every kFieldRigidInterval frames (10
  // with the dense colour term, which corrects the pose's slide along surfaces through the field)
  // keeps up with it; the move itself is a pass over the whole grid (~10 ms at 6 M points).
  const int interval = PhotometricEnabled() ? kFieldRigidIntervalColour : kFieldRigidInterval;
  const bool move_due = params_.field_rigid_threshold > 0.f && ++frames_since_rigid_check_ >= interval;
  const bool state_due = params_.static_levels > 0 && ++frames_since_state_check_ >= kFieldStateInterval;
  if (!move_due && !state_due) return Status::Ok();
  if (move_due) frames_since_rigid_check_ = 0;
  if (state_due) frames_since_state_check_ = 0;
  const size_t m = active_.count;
  if (m < 4) return Status::Ok();
  VD_RETURN_IF_ERROR(ctx_->Reserve(&factor_pos_, m));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&factor_rot_, m));
  ocl::Buffer<vd_float4>& def_pos = bricks_ ? pool_->def_pos : volume_.def_pos;
  ocl::Buffer<vd_float4>& def_rot = bricks_ ? pool_->def_rot : volume_.def_rot;
  VD_RETURN_IF_ERROR(ocl::GatherState(*ctx_, m, active_.list, def_pos, def_rot, factor_pos_, factor_rot_));
  factor_host_.resize(m);
  factor_list_.resize(m);
  VD_RETURN_IF_ERROR(ctx_->Download(factor_pos_, factor_host_.data(), m));
  VD_RETURN_IF_ERROR(ctx_->Download(active_.list, factor_list_.data(), m));
  double rms = 0.0, residual = 0.0;
  Eigen::Matrix4d a;
  if (bricks_) {
    // Rest positions from the members' brick keys (pool voxel indices).
    std::vector<uint32_t> keys(bricks_in_use_);
    VD_RETURN_IF_ERROR(ctx_->Download(bricks_->slot_keys(), keys.data(), keys.size()));
    std::vector<vd_float4> rest(m);
    for (size_t k = 0; k < m; ++k) {
      rest[k] = vd_pool_rest_position(keys.data(), factor_list_[k], volume_.vol.voxel_size);
      rest[k].w = 1.f;
    }
    a = FieldRigidMotion(factor_host_, rest, &rms, &residual);
  } else {
    a = FieldRigidMotion(factor_host_, factor_list_, volume_.vol, &rms, &residual);
  }
  // A field whose non-rigid rest is under half a voxel is a static scene's (its noise: 0.6-0.8 mm on
  // the rigid scene at 4 mm); a deforming one (10-30 mm on the tube and the cloth) keeps its rigid
  // part, so the pose stays the camera's there.
  const bool still = residual < 0.5 * volume_.vol.voxel_size;
  if (state_due && still != field_static_) {
    field_static_ = still;
    VD_LOG_INFO << "the field is " << (still ? "static" : "deforming") << " (non-rigid rest " << residual * 1000
                << " mm): solving on "
                << (still ? std::min(params_.static_levels, params_.solver.levels) : params_.solver.levels)
                << " level(s)";
  }
  if (!(move_due && rms > params_.field_rigid_threshold && still)) return Status::Ok();
  // t' = A^-1 t, R' = R_A^-1 R, and the pose A^-1 pose: the camera sees every point where it did.
  const Eigen::Matrix4d a_inv = a.inverse();
  const Eigen::Quaterniond q(Eigen::Matrix3d(a_inv.topLeftCorner<3, 3>()));
  const vd_float4 q_a = VD_F4(float(q.x()), float(q.y()), float(q.z()), float(q.w()));
  if (bricks_) {
    VD_RETURN_IF_ERROR(ops_.TransformField(*pool_, ToVdPose(a_inv), q_a));
  } else {
    VD_RETURN_IF_ERROR(ops_.TransformField(volume_, ToVdPose(a_inv), q_a));
  }
  pose_ = a_inv * pose_;
  result->pose = pose_;
  return Status::Ok();
}

Status Engine::RasterizeModel(const VdPose& world_to_cam) {
  if (bricks_) {
    VD_RETURN_IF_ERROR(ops_.DeformVertices(*bricks_, *pool_, volume_.vol.voxel_size, &mesh_));
  } else {
    VD_RETURN_IF_ERROR(ops_.DeformVertices(volume_, &mesh_));
  }
  return ops_.Rasterize(mesh_, world_to_cam, cam_, &live_);
}

Status Engine::FollowSolved() {
  if (bricks_) return ops_.Follow(*bricks_, *pool_, active_, volume_.vol.voxel_size);
  return ops_.Follow(volume_, active_);
}

Status Engine::NonRigid(FrameResult* result, bool solve) {
  // M from the surface extracted after the last frame; new members start from the field. A static
  // field is solved on fewer levels (EngineParams::static_levels).
  solver_->set_levels(field_static_ ? params_.static_levels : 0);
  if (bricks_) {
    VD_RETURN_IF_ERROR(PrepareBricks(result));
  } else {
    const std::optional<SolveView> view = ViewToSolve();
    VD_RETURN_IF_ERROR(ops_.BuildActiveSet(volume_, &active_, &solved_, view ? &*view : nullptr));
    VD_RETURN_IF_ERROR(ops_.Extrapolate(volume_, active_));
  }
  // Unsolved (EngineParams::static_solve_every), the frame still has this frame's active set (the
  // fusion goes through it, and on bricks an older one could name slots evicted since) and this
  // frame's raster of the model (the features' lifting and the bricks' growth read it, by the
  // triangle ids of the mesh extracted since), and its points count it as an optimisation that
  // left the solved ones where they were (vd_count_optimisation), the ring following them as after
  // a solve (Follow), so fusion (k_min, k_min_new) starts as early as when every frame is solved.
  if (!solve) {
    VD_RETURN_IF_ERROR(RasterizeModel(ToVdPose(pose_.inverse())));
    ocl::Buffer<vd_float4>& def_pos = bricks_ ? pool_->def_pos : volume_.def_pos;
    VD_RETURN_IF_ERROR(ocl::CountOptimisation(*ctx_, solved_.count, solved_.list, def_pos));
    VD_RETURN_IF_ERROR(FollowSolved());
    return ctx_->Finish();
  }
  if (bricks_) {
    VD_RETURN_IF_ERROR(
        solver_->Prepare(DeviceLattice::Bricks(*bricks_, volume_.vol.voxel_size), bricks_in_use_, solved_));
  } else {
    VD_RETURN_IF_ERROR(solver_->Prepare(volume_, solved_));
  }
  const size_t pixels = static_cast<size_t>(cam_.width) * cam_.height;
  // E_sparse: each match as three axis rows after the per-pixel constraints (weight w_s / w_d).
  sparse_host_.clear();
  if (!matches_.empty() && params_.solver.w_dense > 0.f)
    AppendSparseConstraints(matches_, params_.features.w_sparse / params_.solver.w_dense, &sparse_host_);
  // The dense colour rows, when on, follow the depth rows, one per 2x2 block of pixels (Preprocess
  // made the intensity image; DeviceOps checks its size). They are the coarse levels' alone
  // (VD_CORR_COARSE_ONLY): a solve on the fine level alone (a static field, --levels 1) would sort
  // and walk them for nothing.
  const bool photo =
      PhotometricEnabled() && solver_->num_levels() > 1 && params_.solver.coarse_flip_flop_iterations > 0;
  const size_t dense_rows = photo ? pixels + size_t(vd_photo_rows(cam_.width, cam_.height)) : pixels;
  const size_t total = dense_rows + sparse_host_.size();
  VD_RETURN_IF_ERROR(ctx_->Reserve(&corr_, total));
  VD_RETURN_IF_ERROR(ctx_->Upload(corr_, sparse_host_.data(), sparse_host_.size(), dense_rows));
  VdCorrParams cp{};
  cp.eps_d = params_.corr_eps_d;
  cp.eps_n = params_.corr_eps_n;
  cp.eps_v = params_.corr_eps_v;
  cp.cam_to_world = ToVdPose(pose_);
  const VdPose world_to_cam = ToVdPose(pose_.inverse());
  for (int outer = 0; outer < params_.nonrigid_outer_iterations; ++outer) {
    // The deformed mesh at the current pose: each pixel pairs a model sample with its observation.
    VD_RETURN_IF_ERROR(RasterizeModel(world_to_cam));
    VD_RETURN_IF_ERROR(ops_.Correspondences(live_, maps_.vmap[0], maps_.nmap[0], mesh_, cp, corr_));
    if (photo) {
      VdPhotoParams pp{};
      pp.cam_to_world = cp.cam_to_world;
      pp.cam = cam_;
      pp.scale = params_.solver.w_photo;
      pp.huber = params_.solver.photo_huber;
      pp.min_gradient = params_.solver.photo_min_gradient;
      pp.max_jump = params_.normal_max_jump;
      pp.max_strength = params_.solver.photo_max_strength;
      pp.edge_radius = kPhotoEdgeRadius;
      VD_RETURN_IF_ERROR(ops_.PhotometricCorrespondences(live_, maps_.vmap[0], mesh_, maps_.intensity, pp, corr_));
    }
    const bool energies = nonrigid_solves_++ % params_.solver.energy_interval == 0;
    SolverSummary summary;
    if (bricks_) {
      VD_ASSIGN_OR_RETURN(summary, solver_->Solve(pool_->def_pos, pool_->def_rot, corr_, total, energies));
      VD_RETURN_IF_ERROR(solver_->WriteBack(pool_->def_pos, pool_->def_rot));
    } else {
      VD_ASSIGN_OR_RETURN(summary, solver_->Solve(volume_, corr_, total, energies));
      VD_RETURN_IF_ERROR(solver_->WriteBack(volume_));
    }
    VD_RETURN_IF_ERROR(FollowSolved());
    if (energies) {
      if (!result->energies_evaluated) result->energy_initial = summary.energy_initial;
      result->energy_final = summary.energy_final;
      result->energies_evaluated = true;
    }
    result->dense_correspondences = summary.constraints;
    result->solver_levels = solver_->num_levels();
  }
  return ctx_->Finish();
}

StatusOr<FrameResult> Engine::Process(const RgbdFrame& frame) {
  VD_RETURN_IF_ERROR(frame.Validate());
  if (initialised_ && (frame.intrinsics.width != cam_.width || frame.intrinsics.height != cam_.height))
    return InvalidArgument("frame size changed from " + std::to_string(cam_.width) + "x" + std::to_string(cam_.height) +
                           " to " + std::to_string(frame.intrinsics.width) + "x" +
                           std::to_string(frame.intrinsics.height) + "; reset the model first");
  FrameResult result;
  result.seq = frame.seq;
  // Detection runs beside preprocessing and tracking when the caller did not prefetch it.
  const bool sparse = SparseEnabled();
  if (sparse) extractor_.Prefetch(frame);
  auto t0 = Clock::now();
  CheckColourRegistration(frame);
  VD_RETURN_IF_ERROR(TakeMaps(frame));
  cam_ = maps_.cam;
  result.times[Stage::kPreprocess] = MsSince(t0);

  // The field exists, has been fused into and has a surface: the non-rigid path runs.
  const bool nonrigid = initialised_ && has_field() && frames_fused_ > 0 && mesh_.num_triangles > 0;
  FrameFeatures features;
  matches_.clear();
  if (sparse) {
    // Matched before tracking (pruned with the last pose, section 5.2: the motion between two
    // frames is taken as rigid), so E_sparse takes part in the global pose as well.
    VD_ASSIGN_OR_RETURN(features, extractor_.Take(frame));
    features.frame_index = frames_seen_;
    result.features_detected = int(features.size_keypoints());
    result.feature_extract_ms = features.extract_ms;
    if (nonrigid && history_.num_frames() > 0) {
      t0 = Clock::now();
      MatchStats stats;
      VD_RETURN_IF_ERROR(matcher_.Match(features, history_, history_.Candidates(params_.features), field(),
                                        ToVdPose(pose_), cam_, &matches_, &stats));
      result.feature_match_ms = MsSince(t0);
      result.times[Stage::kFeatures] += result.feature_match_ms;
    }
  }
  if (!initialised_ && params_.sparse_volume) {
    VD_RETURN_IF_ERROR(CreateBricks());
    pose_ = model_pose_ = Eigen::Matrix4d::Identity();
    initialised_ = true;
  } else if (!initialised_) {
    VD_ASSIGN_OR_RETURN(VdVolume vol, PlaceVolume(frame, params_));
    if (volume_.num_voxels() != size_t(vol.dim_x) * vol.dim_y * vol.dim_z ||
        volume_.has_deformation() == params_.rigid_only) {
      volume_ = DeviceVolume();
      VD_RETURN_IF_ERROR(ops_.AllocVolume(vol, !params_.rigid_only, &volume_));
    } else {
      volume_.vol = vol;
      VD_RETURN_IF_ERROR(ops_.ResetVolume(volume_));
    }
    VD_LOG_INFO << "volume " << vol.dim_x << "x" << vol.dim_y << "x" << vol.dim_z << " at " << vol.voxel_size * 1000
                << " mm, origin (" << vol.origin.x << ", " << vol.origin.y << ", " << vol.origin.z << ")";
    pose_ = model_pose_ = Eigen::Matrix4d::Identity();
    initialised_ = true;
  } else {
    t0 = Clock::now();
    VD_RETURN_IF_ERROR(ops_.Rasterize(mesh_, ToVdPose(model_pose_.inverse()), cam_, &model_));
    VD_RETURN_IF_ERROR(ctx_->Finish());
    result.times[Stage::kRaster] = MsSince(t0);
    t0 = Clock::now();
    VD_RETURN_IF_ERROR(Track(&result));
    result.times[Stage::kIcp] = MsSince(t0);
  }
  result.pose = pose_;
  if (result.tracking_ok) {
    RetargetMatches(ToVdPose(pose_), params_.features.prune, &matches_);
  } else {
    matches_.clear();
  }
  result.sparse_matches = int(matches_.size());
  ++frames_seen_;
  // The next frame's preprocessing may start now, beside the solve and the fusion (the device has
  // gaps there: host round trips); it is closed again however this call ends.
  struct WindowCloser {
    Engine* e;
    ~WindowCloser() { e->SetPrefetchWindow(false); }
  } closer{this};
  SetPrefetchWindow(true);
  if (result.tracking_ok && nonrigid && params_.nonrigid_outer_iterations > 0) {
    // A static field is solved on every static_solve_every-th frame (EngineParams).
    const bool solve = !field_static_ || ++static_unsolved_ >= params_.static_solve_every;
    if (solve) static_unsolved_ = 0;
    t0 = Clock::now();
    VD_RETURN_IF_ERROR(NonRigid(&result, solve));
    result.times[Stage::kNonRigid] = MsSince(t0);
  }
  if (result.tracking_ok && sparse) {
    // Into the canonical pose through this frame's field (after its solve), before fusion
    // changes the surface the raster showed.
    t0 = Clock::now();
    VD_RETURN_IF_ERROR(
        matcher_.Lift(&features, live_, mesh_, field(), ToVdPose(pose_), ToVdPose(pose_.inverse()), !nonrigid));
    for (const vd_float4& g : features.canonical) result.features_lifted += g.w > 0.f;
    const int64_t index = features.frame_index;
    history_.Add(std::move(features), params_.features.keyframe_interval, matches_);
    history_.Compact(params_.features);
    result.feature_lift_ms = MsSince(t0);
    result.times[Stage::kFeatures] += result.feature_lift_ms;
    // The adjustment runs when this frame became a keyframe: it is corrected before later frames
    // match against it.
    const BundleParams& bundle = params_.features.bundle;
    const std::vector<int>& keyframes = history_.keyframes();
    if (bundle.keyframes > 0 && !keyframes.empty() && history_.frame(keyframes.back()).frame_index == index) {
      t0 = Clock::now();
      // The adjustment only refines the features: a failure leaves them as lifted and the frame
      // goes on.
      Status adjusted = history_.Adjust(bundle, &result.bundle);
      if (!adjusted.ok()) VD_LOG_WARNING << "keyframe bundle adjustment skipped: " << adjusted.ToString();
      result.bundle_ms = MsSince(t0);
      result.times[Stage::kFeatures] += result.bundle_ms;
    }
  }
  if (result.tracking_ok && nonrigid && params_.nonrigid_outer_iterations > 0 &&
      (params_.field_rigid_threshold > 0.f || params_.static_levels > 0)) {
    t0 = Clock::now();
    VD_RETURN_IF_ERROR(FactorRigidMotion(&result));
    result.times[Stage::kNonRigid] += MsSince(t0);
  }
  if (result.tracking_ok) {
    t0 = Clock::now();
    if (nonrigid) {
      VdFusionParams fp{};
      fp.k_min = params_.k_min;
      fp.k_min_new = std::max(params_.k_min, params_.k_min_new);
      fp.carve_rate = params_.carve_rate;
      fp.carve_radius = params_.carve_radius;
      if (bricks_) {
        VD_RETURN_IF_ERROR(ops_.IntegrateActive(*pool_, active_, fp, volume_.vol, cam_, ToVdPose(pose_.inverse()),
                                                maps_.depth_raw_m, maps_.rgba));
      } else {
        VD_RETURN_IF_ERROR(
            ops_.IntegrateActive(volume_, active_, fp, cam_, ToVdPose(pose_.inverse()), maps_.depth_raw_m, maps_.rgba));
      }
    } else if (bricks_) {
      VD_RETURN_IF_ERROR(IntegrateBricks(&result));
    } else {
      VD_RETURN_IF_ERROR(ops_.IntegrateTsdf(volume_, cam_, ToVdPose(pose_.inverse()), maps_.depth_raw_m, maps_.rgba));
    }
    if (nonrigid && bricks_) {
      VD_RETURN_IF_ERROR(GrowBricks(frame, &result));
      VD_RETURN_IF_ERROR(EvictUnseenBricks(&result));
    }
    VD_RETURN_IF_ERROR(ctx_->Finish());
    result.times[Stage::kIntegrate] = MsSince(t0);
    ++frames_fused_;
  }
  VD_RETURN_IF_ERROR(ExtractMesh(&result));
  const auto t_tracked = Clock::now();
  VD_RETURN_IF_ERROR(ExtractTracked(&result));
  result.times[Stage::kDownload] += MsSince(t_tracked);
  model_pose_ = pose_;
  result.active_voxels = int64_t(active_.count);
  result.solved_voxels = int64_t(solved_.count);
  return result;
}

std::string BrickPoolNote(const FrameResult& r) {
  char note[200];
  std::snprintf(note, sizeof(note), "bricks %lld of %lld (%.0f %%)", static_cast<long long>(r.bricks_used),
                static_cast<long long>(r.bricks_pool), r.bricks_pool > 0 ? 100.0 * r.bricks_used / r.bricks_pool : 0.0);
  std::string out = note;
  if (r.bricks_evicted_total > 0)
    out += "; " + std::to_string(r.bricks_evicted_total) + " bricks seen longest ago dropped to make room" +
           (r.bricks_evicted > 0 ? " (" + std::to_string(r.bricks_evicted) + " this frame)" : "");
  if (r.bricks_grown > 0) out += "; " + std::to_string(r.bricks_grown) + " bricks grown for new surface";
  if (r.bricks_out_of_range > 0)
    out += "; surface beyond the volume's reach (" + std::to_string(VD_BRICK_COORD_MAX) +
           " bricks from the first camera) not fused: " + std::to_string(r.bricks_out_of_range) + " samples";
  if (r.bricks_failed > 0)
    out += "; BRICK POOL FULL: " + std::to_string(r.bricks_failed) +
           " bricks of this frame's surface were not fused (raise --max-grid-mb)";
  return out;
}

Status Engine::CreateBricks() {
  VdVolume vol{};
  vol.voxel_size = params_.voxel_size;
  vol.truncation = params_.truncation_voxels * params_.voxel_size;
  vol.max_weight = params_.max_weight;
  vol.origin = VD_F4(0.f, 0.f, 0.f, 1.f);
  volume_ = DeviceVolume();
  volume_.vol = vol;
  pool_full_reported_ = false;
  bricks_evicted_ = 0;
  bricks_in_use_ = 0;
  bricks_failed_seen_ = 0;
  sightings_.Clear();
  const bool with_field = !params_.rigid_only;
  if (bricks_ && pool_ && pool_->with_field == with_field) {
    // A new model in the same table and pool: every brick back at rest.
    VD_RETURN_IF_ERROR(bricks_->Clear(*ctx_));
    return pool_->Reset(*ctx_);
  }
  const double slots = std::floor(params_.max_grid_mb * 1e6 / SparseBrickBytes(with_field));
  if (slots < 1.0) return InvalidArgument("--max-grid-mb holds no brick");
  VD_ASSIGN_OR_RETURN(ocl::BrickTable table, ocl::BrickTable::Create(*ctx_, uint32_t(std::min(slots, double(1 << 28)))));
  // The pool's voxels grow with the bricks taken (IntegrateBricks); the table holds them all.
  VD_ASSIGN_OR_RETURN(ocl::BrickPool pool,
                      ocl::BrickPool::Create(*ctx_, std::min(table.pool(), kInitialBricks), with_field));
  VD_LOG_INFO << "sparse volume: room for " << table.pool() << " bricks of " << VD_BRICK << "^3 voxels at "
              << vol.voxel_size * 1000 << " mm (" << params_.max_grid_mb << " MB)";
  bricks_.reset();
  pool_.reset();
  bricks_.emplace(std::move(table));
  pool_.emplace(std::move(pool));
  return Status::Ok();
}

Status Engine::RefreshBricks(uint32_t used_before, FrameResult* result) {
  VD_ASSIGN_OR_RETURN(const ocl::BrickCounts counts, bricks_->Counts(*ctx_));
  if (counts.used > pool_->slots)
    VD_RETURN_IF_ERROR(pool_->Grow(*ctx_, std::min(bricks_->pool(), counts.used + counts.used / 2)));
  if (counts.used > used_before)
    VD_RETURN_IF_ERROR(
        pool_->RestField(*ctx_, *bricks_, used_before, counts.used - used_before, volume_.vol.voxel_size));
  bricks_in_use_ = counts.used;
  result->bricks_used = counts.used;
  result->bricks_pool = bricks_->pool();
  // Inserts that found no room since the last count: the pool is full (reported; the bricks seen
  // longest ago make room at the end of the frame, EvictUnseenBricks).
  result->bricks_failed += int64_t(counts.failed) - int64_t(bricks_failed_seen_);
  bricks_failed_seen_ = counts.failed;
  if (result->bricks_failed > 0 && !pool_full_reported_)
    VD_LOG_WARNING << "the brick pool is full (" << counts.used << " bricks, --max-grid-mb " << params_.max_grid_mb
                   << "): the surface's support could not grow by " << result->bricks_failed
                   << " bricks (said once; the status says it every frame)";
  pool_full_reported_ = pool_full_reported_ || result->bricks_failed > 0;
  // The surface's cells and M again, over the new bricks too (marching cubes rebuilds the
  // neighbour table; the new bricks are empty, so the mesh is the same).
  VD_RETURN_IF_ERROR(ops_.MarchingCubes(*bricks_, *pool_, &mesh_));
  return BuildBrickActiveSet();
}

std::optional<SolveView> Engine::ViewToSolve() const {
  if (params_.solve_view_margin < 0.f) return std::nullopt;
  SolveView view;
  view.cam = cam_;
  view.world_to_cam = ToVdPose(pose_.inverse());
  view.margin = params_.solve_view_margin;
  return view;
}

Status Engine::BuildBrickActiveSet() {
  const std::optional<SolveView> view = ViewToSolve();
  return ops_.BuildActiveSet(*bricks_, &active_, &solved_, view ? &*view : nullptr, &pool_->def_pos);
}

Status Engine::GrowBricks(const RgbdFrame& frame, FrameResult* result) {
  const size_t pixels = size_t(cam_.width) * cam_.height, nv = mesh_.num_vertices;
  if (nv == 0 || live_.ids.size() < pixels || host_grid_.size() != nv || host_tris_.size() != 3 * mesh_.num_triangles)
    return Status::Ok();
  grow_ids_.resize(pixels);
  grow_deformed_.resize(nv);
  VD_RETURN_IF_ERROR(ctx_->Download(live_.ids, grow_ids_.data(), pixels));
  VD_RETURN_IF_ERROR(ctx_->Download(mesh_.positions, grow_deformed_.data(), nv));
  sightings_.See(grow_ids_.data(), cam_.width, cam_.height, kSightingStep, host_tris_.data(), mesh_.num_triangles,
                 host_grid_.data(), uint32_t(frames_fused_ + 1));
  const VdVolume& vol = volume_.vol;
  std::vector<GrowthBrick> plan =
      PlanGrowth(frame.depth, 1.f / frame.depth_scale, params_.min_depth, params_.max_depth, cam_, ToVdPose(pose_),
                 grow_ids_.data(), host_tris_.data(), mesh_.num_triangles, grow_deformed_.data(), host_grid_.data(),
                 vol.voxel_size, vol.truncation, GrowthParams());
  if (plan.empty()) return Status::Ok();
  const size_t m = plan.size();
  std::vector<uint32_t> keys(m);
  std::vector<VdPose> motion(m);
  for (size_t i = 0; i < m; ++i) keys[i] = plan[i].key, motion[i] = plan[i].motion;
  VD_RETURN_IF_ERROR(ctx_->Reserve(&grow_keys_, m));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&grow_slots_, m));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&grow_motion_, m));
  VD_RETURN_IF_ERROR(ctx_->Upload(grow_keys_, keys.data(), m));
  VD_RETURN_IF_ERROR(ctx_->Upload(grow_motion_, motion.data(), m));
  // The missing bricks first (a full pool leaves them out: -1 below), at rest.
  const uint32_t before = bricks_in_use_;
  VD_RETURN_IF_ERROR(bricks_->Insert(*ctx_, grow_keys_, m));
  VD_ASSIGN_OR_RETURN(const ocl::BrickCounts counts, bricks_->Counts(*ctx_));
  if (counts.used > before) {
    if (counts.used > pool_->slots)
      VD_RETURN_IF_ERROR(pool_->Grow(*ctx_, std::min(bricks_->pool(), counts.used + counts.used / 2)));
    VD_RETURN_IF_ERROR(pool_->RestField(*ctx_, *bricks_, before, counts.used - before, volume_.vol.voxel_size));
    bricks_in_use_ = counts.used;
  }
  VD_RETURN_IF_ERROR(bricks_->Lookup(*ctx_, grow_keys_, m, grow_slots_));
  VD_RETURN_IF_ERROR(ocl::GrowBricks(*ctx_, *bricks_, *pool_, m, grow_slots_, grow_motion_, volume_.vol, cam_,
                                     ToVdPose(pose_.inverse()), maps_.depth_raw_m, maps_.rgba));
  result->bricks_grown = int64_t(counts.used) - int64_t(before);
  result->bricks_failed += int64_t(counts.failed) - int64_t(bricks_failed_seen_);
  bricks_failed_seen_ = counts.failed;
  result->bricks_used = counts.used;
  result->bricks_pool = bricks_->pool();
  return Status::Ok();
}

Status Engine::EvictUnseenBricks(FrameResult* result) {
  result->bricks_evicted_total = bricks_evicted_;
  // Failed inserts not counted yet (a ring or corners that found no room add no brick, so no
  // refresh counted them).
  VD_ASSIGN_OR_RETURN(const ocl::BrickCounts before, bricks_->Counts(*ctx_));
  result->bricks_failed += int64_t(before.failed) - int64_t(bricks_failed_seen_);
  bricks_failed_seen_ = before.failed;
  if (result->bricks_failed <= 0) return Status::Ok();
  VD_ASSIGN_OR_RETURN(const std::vector<uint32_t> keys, bricks_->DownloadSlotKeys(*ctx_, before.used));
  const uint32_t want = std::max(bricks_->pool() / 4, uint32_t(result->bricks_failed));
  VD_ASSIGN_OR_RETURN(const uint32_t dropped,
                      bricks_->Drop(ops_, *pool_, sightings_.Oldest(keys, uint32_t(frames_fused_ + 1), want)));
  if (dropped == 0) return Status::Ok();
  // Compaction restarts the table's counters (the slots kept are the ones in use).
  VD_ASSIGN_OR_RETURN(const ocl::BrickCounts after, bricks_->Counts(*ctx_));
  bricks_in_use_ = after.used;
  bricks_failed_seen_ = after.failed;
  NoteEviction(dropped, result);
  result->bricks_used = after.used;
  return Status::Ok();
}

void Engine::NoteEviction(uint32_t dropped, FrameResult* result) {
  result->bricks_evicted = dropped;
  bricks_evicted_ += dropped;
  result->bricks_evicted_total = bricks_evicted_;
  VD_LOG_INFO << "brick pool full (" << bricks_->pool() << " bricks, --max-grid-mb " << params_.max_grid_mb
              << "): dropped the " << dropped << " bricks seen longest ago";
}

Status Engine::PrepareBricks(FrameResult* result) {
  result->bricks_used = bricks_in_use_;
  result->bricks_pool = bricks_->pool();
  VD_RETURN_IF_ERROR(BuildBrickActiveSet());
  // The one-ring of the surface where its brick is missing, then the corners of every coarse
  // level's cells (the coarsest's bricks hold the finer ones'): each found once, so after the first
  // frames of a region both add nothing and cost a count.
  VD_ASSIGN_OR_RETURN(const uint32_t ring, ops_.AllocateActiveRing(*bricks_));
  if (ring > 0) VD_RETURN_IF_ERROR(RefreshBricks(bricks_in_use_, result));
  const int coarsest = 1 << (params_.solver.levels - 1);
  if (coarsest > 1) {
    VD_ASSIGN_OR_RETURN(const uint32_t corners, bricks_->AllocateLevelCorners(*ctx_, active_, coarsest));
    if (corners > 0) VD_RETURN_IF_ERROR(RefreshBricks(bricks_in_use_, result));
  }
  return ops_.Extrapolate(*bricks_, *pool_, active_, volume_.vol.voxel_size);
}

Status Engine::IntegrateBricks(FrameResult* result) {
  const VdVolume& vol = volume_.vol;
  const float brick = VD_BRICK * vol.voxel_size;
  const VdPose cam_to_world = ToVdPose(pose_);
  auto allocate = [&]() -> StatusOr<ocl::BrickCounts> {
    VD_RETURN_IF_ERROR(bricks_->AllocateAndList(*ctx_, maps_.depth_raw_m, cam_, cam_to_world, vol.truncation, brick));
    return bricks_->Counts(*ctx_);
  };
  VD_ASSIGN_OR_RETURN(ocl::BrickCounts counts, allocate());
  // (A deforming model is fused through its active set, not here: EvictUnseenBricks.)
  if (counts.unfused > 0 && !pool_->with_field) {
    // The pool is full: the bricks seen longest ago make room (a quarter of the pool at once, so this
    // stays rare), then the frame's band is allocated again.
    VD_ASSIGN_OR_RETURN(const uint32_t dropped,
                        bricks_->EvictOldest(ops_, *pool_, std::max(bricks_->pool() / 4, counts.unfused)));
    if (dropped > 0) {
      NoteEviction(dropped, result);
      VD_ASSIGN_OR_RETURN(counts, allocate());
    }
  }
  // The voxels follow the bricks handed out, half as many again ahead so growth stays rare.
  if (counts.used > pool_->slots)
    VD_RETURN_IF_ERROR(pool_->Grow(*ctx_, std::min(bricks_->pool(), counts.used + counts.used / 2)));
  // New bricks' field starts at rest (a no-op without one).
  if (counts.used > bricks_in_use_)
    VD_RETURN_IF_ERROR(pool_->RestField(*ctx_, *bricks_, bricks_in_use_, counts.used - bricks_in_use_, vol.voxel_size));
  bricks_in_use_ = counts.used;
  bricks_failed_seen_ = counts.failed;
  VD_RETURN_IF_ERROR(ocl::IntegrateBricks(*ctx_, *bricks_, *pool_, vol, cam_, ToVdPose(pose_.inverse()),
                                          maps_.depth_raw_m, maps_.rgba));
  result->bricks_used = counts.used;
  result->bricks_pool = bricks_->pool();
  result->bricks_evicted_total = bricks_evicted_;
  result->bricks_failed = counts.unfused;
  result->bricks_out_of_range = counts.out_of_range;
  if (counts.unfused > 0 && !pool_full_reported_)
    VD_LOG_WARNING << "the brick pool is full (" << counts.used << " bricks, --max-grid-mb " << params_.max_grid_mb
                   << ") with the surface in view: " << counts.unfused
                   << " of this frame's bricks are not fused (said once; the status says it every frame)";
  pool_full_reported_ = pool_full_reported_ || counts.unfused > 0;
  return Status::Ok();
}

Status Engine::DownloadVolume(std::vector<float>* tsdf, std::vector<float>* weight, std::vector<uint32_t>* color) {
  if (bricks_) return Unimplemented("the sparse volume (--sparse-volume) has no dense grid to download");
  const size_t n = volume_.num_voxels();
  tsdf->resize(n);
  weight->resize(n);
  color->resize(n);
  VD_RETURN_IF_ERROR(ctx_->Download(volume_.tsdf, tsdf->data(), n));
  VD_RETURN_IF_ERROR(ctx_->Download(volume_.weight, weight->data(), n));
  return ctx_->Download(volume_.color, color->data(), n);
}

}  // namespace vd
