#pragma once
// The reconstruction engine: one RGB-D frame in, the live mesh, the pose and statistics out.
// Every heavy step runs as an OpenCL kernel (server/kernels); this class orders them.
#include <Eigen/Geometry>
#include <array>
#include <atomic>
#include <cstdint>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "core/brick_sightings.h"
#include "core/checkpoint.h"
#include "core/colour_registration.h"
#include "core/features.h"
#include "core/hierarchy.h"
#include "core/rigid_tracker.h"
#include "core/solver.h"
#include "ocl/brick_hash_ocl.h"
#include "ocl/device_ops.h"
#include "vd/common/frame.h"
#include "vd/common/mesh.h"
#include "vd/common/status.h"

namespace vd {

struct EngineParams {
  // Edge length of a grid cell, metres. The paper's grids are a few millimetres.
  float voxel_size = 0.004f;
  // Truncation band in voxels: wide enough for the sensor's noise at ~1 m, narrow enough for detail.
  float truncation_voxels = 4.f;
  // Weight cap of the running average: higher = smoother, slower to follow change.
  float max_weight = 64.f;
  // Depth outside [min_depth, max_depth] metres is ignored (Kinect-class sensors: 0.4..4 m).
  float min_depth = 0.2f;
  float max_depth = 3.5f;
  // Device memory the automatic grid placement may use, MB (12 bytes per grid point rigid-only,
  // 44 with the deformation field); a larger first view is cropped around its centre.
  double max_grid_mb = 600.0;
  // Space left around the first frame's points when placing the grid, metres.
  float volume_margin = 0.10f;
  // Edge-preserving smoothing of the depth used for tracking (fusion uses the raw depth).
  bool bilateral = true;
  // Preprocess the next frame on a second device queue while this one is solved (Engine::Prefetch):
  // "on", "off", or "auto" = on for a GPU. On 2 CPU cores through PoCL it bought nothing, as the
  // cores have little idle time to fill (0.91-1.06 of the frame time, docs/BENCHMARKS.md).
  std::string prefetch_preprocess = "auto";
  // Whether the frames' colour lies on the depth's pixel grid, which the dense colour term
  // (SolverParams::w_photo) needs: "auto" measures it from the first frames (core/
  // colour_registration.h: depth edges against intensity edges), "yes" trusts the source, "no"
  // keeps the term off. 7-Scenes' colour, from a second, uncalibrated sensor, measures 0.67-1.24
  // against 1.45, the synthetic scenes 1.61-2.61 and a registered Kinect v1 (Snoopy) 1.68.
  std::string colour_registered = "auto";
  int bilateral_radius = 2;
  float bilateral_sigma_space_px = 3.f;
  float bilateral_sigma_depth_m = 0.02f;
  // Normals are dropped across depth jumps larger than this fraction of the depth.
  float normal_max_jump = 0.05f;
  // ICP iterations per pyramid level, coarsest last (level 0 = full resolution).
  std::array<int, 3> icp_iterations = {10, 5, 4};
  // Information ratio (eigenvalue / largest eigenvalue of the ICP normal equations) below which a
  // pose direction counts as unobserved and is held at the last pose (a cylinder's spin about its
  // axis, a plane sliding in itself); soft, 0 = off. Measured: the synthetic tube's spin 2e-5..1.3e-4,
  // the observed directions of the rigid scene >= 8e-4, of 7-Scenes >= 1e-2.
  float icp_degeneracy = 5e-5f;
  // Correspondences farther apart than this are rejected, metres.
  float icp_max_distance = 0.10f;
  // An ICP level stops when a step |xi| (radians and metres together) falls below this. The step
  // is applied; the stop leaves out only the next one, and Gauss-Newton steps shrink by an order of
  // magnitude or more once this close. 3e-4 is 0.3 mm or 0.017 degrees (0.5 mm at 2 m), under the
  // sensor's noise (~1 mm). 5e-5 -> 3e-4 took 19-26 % of the reductions away on the synthetic scenes
  // with surface error and drift within 0.03 mm, and 7-Scenes' ATE to within 1 mm (docs/BENCHMARKS.md
  // "Session 35").
  float icp_min_step = 3e-4f;
  // Correspondences whose normals differ by more than this are rejected, degrees.
  float icp_max_normal_angle_deg = 30.f;
  // Tracking fails when fewer pixels than this fraction of the valid ones are inliers ...
  float min_inlier_fraction = 0.10f;
  // ... or the pose moves more than this per frame (the sensor does not teleport).
  float max_frame_translation = 0.20f;
  float max_frame_rotation_deg = 30.f;
  // Rigid tracking and fusion only: no deformation field is allocated (12 instead of 44 bytes per
  // grid point). Without it the field exists and deforms the mesh (identity until the non-rigid
  // solve moves it).
  bool rigid_only = false;
  // The volume as 8^3 bricks allocated where each frame's truncation band reaches (issue 17;
  // docs/SPARSE_VOLUME.md): no box fixed at the first frame, memory in proportion to the surface,
  // max_grid_mb the brick pool. Rigid-only for now (the field is not on bricks yet).
  bool sparse_volume = false;
  // Non-rigid tracking: outer iterations (re-rendering and new correspondences) per frame. With
  // the coarse-to-fine solver one reaches the quality two did on one level at half the time.
  int nonrigid_outer_iterations = 1;
  // The solve's points are limited to the surface points whose deformed position is in the frame's
  // view widened by this fraction of the image on each side; the others keep their field (ring
  // points beside the solved ones still follow them). Points out of view have no data term, only
  // the regulariser. In a room most of the surface is out of view, and solving it costs memory and
  // time in proportion (docs/BENCHMARKS.md "Session 27"). Negative: solve all of M's surface.
  float solve_view_margin = -1.f;
  // Correspondence kernels (section 5.1): distance (m), normal deviation and view (1 - cos).
  float corr_eps_d = 0.02f;
  float corr_eps_n = 0.5f;
  float corr_eps_v = 0.8f;
  // Grid points are fused only after taking part in this many optimisations (section 8).
  float k_min = 3.f;
  // Rigid motion in the field: every 30 frames, the rigid motion that best explains the active
  // points' deformation is measured (Kabsch, rest -> deformed); when it moves them by more than
  // this RMS (metres) while the non-rigid rest of the field is under half a voxel (a static
  // scene), it is moved into the camera pose and out of the field, so the field keeps only the
  // non-rigid part (paper section 4: global R, t, then the local deformation). Without it a static
  // scene's field slowly takes up the camera's pose error (docs/BENCHMARKS.md "Long takes"); a
  // deforming field (a bending object before a still camera) is left alone, so the pose stays the
  // camera's. 0: never.
  float field_rigid_threshold = 2e-4f;
  // Levels of the solver's hierarchy while the field is static: every kFieldStateInterval frames
  // the same measurement finds the field's non-rigid rest (after its best rigid motion); under
  // half a voxel the scene is static (0.6-0.8 mm on the rigid scene at 4 mm, 10-30 mm on the
  // deforming ones) and the next frames solve on this many levels. The coarse levels carry large
  // non-rigid updates across the surface; a static field has none to carry, and there they only
  // add low-frequency noise (rigid scene: non-rigid displacement 0.62 mm with 3 levels, 0.49 with
  // the fine level alone, and a quarter of the frame time). 0: always SolverParams::levels.
  int static_levels = 1;
  // While the field is static, the non-rigid solve runs on every static_solve_every-th frame; the
  // frames between still build their active set, rasterise, fuse through the field as it stands
  // (counted as an optimisation for k_min), track the camera and publish the mesh. A static field
  // has nothing to solve (its solve only keeps it static), and a scene that starts to deform is
  // found by the same measurement within kFieldStateInterval frames (the bend's slow start, static
  // on frames 12-21: drift 7.26 -> 7.36 mm). Rigid scene: frame 0.82-0.84x, displacement 0.52 ->
  // 0.50 mm (docs/BENCHMARKS.md "Session 34"). 1: every frame.
  int static_solve_every = 2;
  // ... and points never fused before (new space: weight 0) only after this many. Measured on the
  // long bend (docs/BENCHMARKS.md "Long takes"): new geometry fused after 3 optimisations, as the
  // paper's K_min, is the duplicated surface section 8 warns of, grown at the parts that turn.
  float k_min_new = 20.f;
  // Carving (shared/tsdf.h): a fused point holding surface where the depth sees free space (every
  // pixel of a (2 carve_radius + 1)^2 window more than a truncation band behind it) loses this share
  // of its weight, so wrong geometry is unlearnt in a few frames instead of max_weight / 2.
  float carve_rate = 0.5f;
  int carve_radius = 2;
  SolverParams solver;
  // Sparse colour features and E_sparse (section 5.2); used by the non-rigid solve only.
  FeatureParams features;
  Status Validate() const;
  // Registers a flag for every field (and the solver's and features' ones); the fields' values
  // now are the defaults --help shows.
  void Bind(FlagParser* flags);
};

// The stages of a frame, in the order they are reported (stats, status messages).
enum class Stage : int {
  kPreprocess,
  kRaster,
  kIcp,
  kNonRigid,
  kIntegrate,
  kMarchingCubes,
  kDownload,
  // Matching and lifting on the frame's thread (detection runs beside it, see
  // FrameResult::feature_extract_ms).
  kFeatures,
  kCount
};

// Wall-clock milliseconds of each stage of the last frame.
struct StageTimes {
  static constexpr int kCount = int(Stage::kCount);
  static constexpr const char* kNames[kCount] = {"preprocess", "raster",   "icp",      "nonrigid",
                                                 "integrate",  "marching_cubes", "download", "features"};
  double& operator[](Stage s) { return ms[int(s)]; }
  double operator[](Stage s) const { return ms[int(s)]; }
  static const char* Name(Stage s) { return kNames[int(s)]; }
  double Total() const {
    double t = 0.0;
    for (double v : ms) t += v;
    return t;
  }
  // Indexed by Stage; the array is for code that walks every stage (statistics, status).
  std::array<double, kCount> ms{};
};

struct FrameResult {
  int64_t seq = 0;
  // Camera-to-world pose estimated for this frame (world = first frame's camera coordinates).
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
  // False when tracking failed: the frame was not fused and the last good pose was kept.
  bool tracking_ok = true;
  std::string tracking_message;
  // Live mesh in this frame's camera coordinates, and the same vertices/faces in canonical pose.
  TriangleMesh live_mesh;
  TriangleMesh canonical_mesh;
  // With TrackMesh: the tracked mesh (fixed vertices and faces) deformed by this frame's field,
  // in this frame's camera coordinates; empty otherwise.
  TriangleMesh tracked_mesh;
  StageTimes times;
  int icp_inliers = 0;
  float icp_rmse = 0.f;
  int64_t active_voxels = 0;
  // Of them the surface points, the solver's unknowns (the rest, the one-ring, follows them).
  int64_t solved_voxels = 0;
  // Sparse volume: bricks in the pool, the pool's size, and the bricks this frame's band needed
  // but found no room for (nonzero: the pool is full with this frame's own surface, which was not
  // all fused). A full pool first drops the bricks seen longest ago: how many this frame, and since
  // the model began.
  int64_t bricks_used = 0;
  int64_t bricks_pool = 0;
  int64_t bricks_failed = 0;
  int64_t bricks_evicted = 0;
  int64_t bricks_evicted_total = 0;
  // Samples of this frame's surface beyond the reach of the brick keys (512 bricks from the first
  // camera along each axis: +-16 m at 4 mm), not fused.
  int64_t bricks_out_of_range = 0;
  // Non-rigid on the bricks: bricks grown this frame for depth the live model did not explain.
  int64_t bricks_grown = 0;
  // Non-rigid solve of this frame: constraint rows (dense pixels + 3 per sparse match), E_total before and after (0 when rigid).
  int dense_correspondences = 0;
  double energy_initial = 0.0;
  double energy_final = 0.0;
  // Whether this frame evaluated the energies (every SolverParams::energy_interval solves).
  bool energies_evaluated = false;
  // Levels of the hierarchy the solve used (fewer while the field is static,
  // EngineParams::static_levels).
  int solver_levels = 0;
  // Sparse features of this frame: keypoints detected, lifted into the canonical pose, matches
  // used as E_sparse constraints, and the detection + description time (off the frame's thread
  // when prefetched).
  int features_detected = 0;
  int features_lifted = 0;
  int sparse_matches = 0;
  double feature_extract_ms = 0.0;
  // The two parts of the "features" stage: matching against the history, lifting into canonical.
  double feature_match_ms = 0.0;
  double feature_lift_ms = 0.0;
  // The keyframe bundle adjustment when it ran this frame (FeatureHistory::Adjust): its time (part
  // of the "features" stage) and what it did.
  double bundle_ms = 0.0;
  BundleStats bundle;
};

// Device bytes of one grid point of the dense volume: TSDF, weight and colour (12), and with the
// deformation field t_i and R_i (44). --max-grid-mb divides by it.
double DenseGridPointBytes(bool with_field);
// Device bytes of one brick of the sparse volume: its 512 voxels (as DenseGridPointBytes), its 27
// neighbour slots, key, stamp and list entry, and up to four table entries of 8 bytes (the table
// is a power of two at least twice the pool). --max-grid-mb divides by it with --sparse-volume.
double SparseBrickBytes(bool with_field);

class Engine {
 public:
  // device_spec as for ocl::Context::Create.
  static StatusOr<std::unique_ptr<Engine>> Create(const EngineParams& params, const std::string& device_spec);
  // Waits for a prefetch in flight.
  ~Engine();

  // Processes one frame. Errors are returned for bad input or device failure; a tracking failure
  // is a successful call with tracking_ok == false.
  StatusOr<FrameResult> Process(const RgbdFrame& frame);
  // Starts feature detection and the device preprocessing (on a second queue) for a frame that
  // will be processed next, so both run while the current frame is solved. Optional: Process does
  // what was not prefetched. Safe to call from another thread than Process's; a frame prefetched
  // for a later one than the frame processed is kept, an earlier one is dropped, and beyond two
  // the oldest gives way.
  void Prefetch(const RgbdFrame& next);
  // Drops the model; the next frame starts a new one.
  void Reset();
  // A fixed-topology tracked mesh in every FrameResult (tracked_mesh): `canonical` (world metres,
  // i.e. canonical coordinates), or, when empty, the first frame's canonical mesh. The same
  // vertices and faces in every frame, each vertex moved by the deformation field S and seen from
  // the frame's camera. A mesh with no vertices or faces, or with a face naming a missing vertex,
  // is refused. Kept across Reset (a given mesh) or re-taken from the next first frame.
  Status TrackMesh(const TriangleMesh& canonical = {});

  const EngineParams& params() const { return params_; }
  std::string DeviceDescription() const { return ctx_->Describe(); }
  // The colour's registration as measured so far (EngineParams::colour_registered), and whether the
  // dense colour term runs on the frames now.
  const ColourRegistration& colour_registration() const { return colour_check_; }
  bool colour_term_active() const { return PhotometricEnabled(); }
  bool has_model() const { return initialised_; }
  const VdVolume& volume() const { return volume_.vol; }
  const FeatureHistory& feature_history() const { return history_; }
  // Matches of the last frame (tests).
  const std::vector<SparseMatch>& last_matches() const { return matches_; }
  // Download of the deformation field positions (tests).
  Status DownloadDeformation(std::vector<vd_float4>* def_pos);
  // Peak OpenCL buffer bytes, the prefetch queue's counted beside the main one's (an upper bound:
  // the two peaks may fall at different times).
  size_t device_peak_bytes() const { return ctx_->peak_bytes() + (prep_ctx_ ? prep_ctx_->peak_bytes() : 0); }
  // Downloads the grid (for snapshots and tests).
  Status DownloadVolume(std::vector<float>* tsdf, std::vector<float>* weight, std::vector<uint32_t>* color);

  // Copies the model (volume, field, pose, camera, feature history) to the host, for checkpoints.
  // FailedPrecondition before the first frame.
  Status SaveState(EngineState* state);
  // Continues from a saved model: the next frame is tracked against it as if this engine had
  // processed the frames before. Refuses a state whose kind (rigid-only or not) differs from
  // these parameters, or that does not fit max_grid_mb; on error the engine is left reset.
  // meshes, when given, receives the restored live and canonical meshes.
  Status RestoreState(const EngineState& state, FrameResult* meshes = nullptr);
  int64_t frames_fused() const { return frames_fused_; }

  // Grid placement from the first frame's valid depth (exposed for tests).
  static StatusOr<VdVolume> PlaceVolume(const RgbdFrame& frame, const EngineParams& params);
  // The rigid motion A (4x4, world -> world) that best maps the rest positions of the optimised
  // points among `list` (grid indices) onto their deformed positions `deformed` (least squares,
  // Eigen::umeyama without scale), the RMS of |A g - g| over them in *rms_motion and of what A leaves, |t - A g|, in
  // *rms_residual (both 0 with fewer than 4 points: the identity). Exposed for tests.
  static Eigen::Matrix4d FieldRigidMotion(const std::vector<vd_float4>& deformed, const std::vector<int32_t>& list,
                                          const VdVolume& vol, double* rms_motion, double* rms_residual);
  // The same from each point's rest position (w > 0 where it counts; the bricks' from their keys).
  static Eigen::Matrix4d FieldRigidMotion(const std::vector<vd_float4>& deformed, const std::vector<vd_float4>& rest,
                                          double* rms_motion, double* rms_residual);

 private:
  Engine(const EngineParams& params, std::unique_ptr<ocl::Context> ctx);
  // One frame's device input and pyramid. The engine holds the current frame's (maps_) and those
  // Prefetch builds on a second queue while the current frame is solved; Process then swaps one in
  // instead of preprocessing.
  struct FrameMaps {
    VdCamera cam{};
    // Valid pixels in range, the reference for the tracking failure check.
    int valid_pixels = 0;
    ocl::Buffer<uint16_t> raw_depth;
    ocl::Buffer<uint32_t> rgba;
    ocl::Buffer<float> depth_raw_m;
    std::array<ocl::Buffer<float>, 3> depth;
    std::array<ocl::Buffer<vd_float4>, 3> vmap;
    std::array<ocl::Buffer<vd_float4>, 3> nmap;
    // The dense colour term's smoothed luma at half resolution (only when it is on), and its
    // passes' scratch.
    ocl::Buffer<float> intensity;
    ocl::Buffer<float> intensity_tmp;
    std::vector<uint32_t> rgba_host;
  };
  // Uploads and filters `frame` into *out through ctx and ops (either queue); waits for it.
  Status Preprocess(ocl::Context& ctx, DeviceOps& ops, const RgbdFrame& frame, FrameMaps* out) const;
  // maps_ for `frame`: the prefetched maps when Prefetch built them for this frame, else built now.
  Status TakeMaps(const RgbdFrame& frame);
  // Waits for the prefetches in flight and drops them.
  void DropPrefetch();
  Status Track(FrameResult* result);
  Status ExtractMesh(FrameResult* result);
  Status ExtractTracked(FrameResult* result);
  // The frame's active set, then (solve) its correspondences and the solve.
  Status NonRigid(FrameResult* result, bool solve);
  // The model (mesh_) deformed by the field and rasterised into live_ at world_to_cam: what each
  // pixel pairs with, and what the features' lifting and the bricks' growth read.
  Status RasterizeModel(const VdPose& world_to_cam);
  // The ring of M follows the solved points and counts the optimisation (ops_.Follow).
  Status FollowSolved();
  // Moves the rigid part of the field into the camera pose once it exceeds
  // EngineParams::field_rigid_threshold (the deformed surface stays where the camera sees it), and
  // decides from the same measurement whether the field is static (EngineParams::static_levels).
  Status FactorRigidMotion(FrameResult* result);
  bool SparseEnabled() const;
  // The dense colour term is asked for (SolverParams::w_photo > 0 on the non-rigid path) and not
  // (yet) ruled out by the colour's registration: frames are preprocessed with the intensity.
  bool PhotometricWanted() const;
  // ... and it runs: the colour is registered (measured or trusted).
  bool PhotometricEnabled() const;
  // While undecided (EngineParams::colour_registered "auto"), measures `frame`'s registration and
  // logs the verdict once it falls.
  void CheckColourRegistration(const RgbdFrame& frame);

  EngineParams params_;
  std::unique_ptr<ocl::Context> ctx_;
  DeviceOps ops_;
  // The second queue and its operations for Prefetch's preprocessing (null: none, e.g. a failed
  // start; Process then preprocesses every frame itself).
  std::unique_ptr<ocl::Context> prep_ctx_;
  std::unique_ptr<DeviceOps> prep_ops_;
  bool initialised_ = false;
  int64_t frames_fused_ = 0;
  // Frames since FactorRigidMotion last measured the field's rigid part (it does every
  // kFieldRigidInterval frames).
  int frames_since_rigid_check_ = 0;
  // Frames since the field's state was last measured, and whether it was found static then (the
  // solve then uses EngineParams::static_levels; Reset and a resume start as deforming).
  int frames_since_state_check_ = 0;
  bool field_static_ = false;
  // Frames in a row whose static field was not solved (EngineParams::static_solve_every).
  int static_unsolved_ = 0;
  // The colour's registration, measured on the first frames of a model (Reset starts again), and
  // its verdict for Preprocess on the prefetch thread.
  ColourRegistration colour_check_;
  std::atomic<ColourRegistration::Verdict> colour_verdict_{ColourRegistration::Verdict::kUndecided};
  static constexpr int kFieldRigidInterval = 30;
  // The field's state for EngineParams::static_levels is measured this often: a third of a second
  // at 30 Hz decides, and a scene that starts to deform is back on every level within as long.
  static constexpr int kFieldStateInterval = 10;
  // With the dense colour term: it corrects the camera's drift along surfaces (which depth-only ICP
  // leaves) through the field, as a rigid part this moves into the pose (rigid scene, 60 frames:
  // non-rigid displacement 0.95 mm checked every 30 frames, 0.70 every 10; session 28, with the
  // rows on every level). Its rows now act on the coarse levels alone, so on a field solved on the
  // fine level only (static) this correction waits for the next solve on every level.
  static constexpr int kFieldRigidIntervalColour = 10;
  // Colour rows within this many pixels of an observed depth edge are dropped (VdPhotoParams): the
  // smoothed intensity (sqrt(3) px) there mixes the two surfaces.
  static constexpr int kPhotoEdgeRadius = 4;
  DeviceVolume volume_;
  // The sparse volume (EngineParams::sparse_volume): volume_.vol gives its voxel size, truncation
  // and weight cap (origin 0: the bricks tile space from the world origin); volume_'s dense
  // buffers stay empty.
  std::optional<ocl::BrickTable> bricks_;
  std::optional<ocl::BrickPool> pool_;
  // Bricks of voxels the pool starts with (it grows as the table hands out slots).
  static constexpr uint32_t kInitialBricks = 1024;
  // The log has said once that the pool is full with the surface in view.
  bool pool_full_reported_ = false;
  // Bricks dropped to make room since the model began.
  int64_t bricks_evicted_ = 0;
  // Creates the table and pool within max_grid_mb.
  Status CreateBricks();
  Status IntegrateBricks(FrameResult* result);
  // The deformation field: on the bricks (a pool with a field) or the dense grid.
  bool has_field() const { return bricks_ ? pool_->with_field : volume_.has_deformation(); }
  DeviceField field() const {
    return bricks_ ? DeviceField::Bricks(*bricks_, *pool_, volume_.vol.voxel_size) : DeviceField::Dense(volume_);
  }
  // After bricks were taken (a ring, coarse corners): the pool's voxels follow, the new bricks'
  // field starts at rest, and the surface's cells and the active set are found again over them.
  // `used_before`: the slots in use before; fills the frame's pool counts.
  Status RefreshBricks(uint32_t used_before, FrameResult* result);
  // The non-rigid solve's active set on the bricks: M, its one-ring and the coarse levels' corners
  // allocated, the field of new members extrapolated.
  Status PrepareBricks(FrameResult* result);
  // The view the solve is limited to this frame (EngineParams::solve_view_margin), if any.
  std::optional<SolveView> ViewToSolve() const;
  // M and the solver's points on the bricks (DeviceOps::BuildActiveSet with the view).
  Status BuildBrickActiveSet();
  // Depth the live model does not explain gets bricks (core/growth.h), their field started at the
  // nearest rendered surface's motion, and is fused into them once through it.
  Status GrowBricks(const RgbdFrame& frame, FrameResult* result);
  // A deforming model whose pool had no room this frame (a ring, a coarse corner or growth not
  // taken): the bricks seen longest ago (sightings_) are dropped, a quarter of the pool at once,
  // so the next frame's support fits. Bricks in view and within two bricks of them are never dropped.
  Status EvictUnseenBricks(FrameResult* result);
  // Counts `dropped` bricks evicted this frame into `result` (the frame's and the total) and logs them (both paths).
  void NoteEviction(uint32_t dropped, FrameResult* result);
  // When each brick of a deforming model was last under the rendered live model (GrowBricks
  // marks them every frame from the raster it downloads anyway).
  BrickSightings sightings_;
  // Pixels between sightings in x and y. A brick (8 voxels a side: 3.2 cm at 4 mm, 17 pixels at
  // 1 m) narrower than this in the image may be missed, but a sighting protects the bricks within
  // two of it (BrickSightings::kReach), so nothing in view is dropped. Every 4th pixel cost 0.39 ms
  // a frame on the tube (0.55 on the rigid scene, 2026-12-06), every 8th a quarter of the pixels.
  static constexpr int kSightingStep = 8;
  // GrowBricks' host copies (the raster's triangle ids, the deformed vertices, the faces) and its
  // bricks' keys, slots and motions on the device.
  std::vector<uint32_t> grow_ids_;
  std::vector<vd_float4> grow_deformed_;
  std::vector<int32_t> host_tris_;
  ocl::Buffer<uint32_t> grow_keys_;
  ocl::Buffer<int32_t> grow_slots_;
  ocl::Buffer<VdPose> grow_motion_;
  // Slots in use at the last count (the lattice's extent on the bricks).
  uint32_t bricks_in_use_ = 0;
  // The table's failed inserts at the last count (each frame reports its own).
  uint32_t bricks_failed_seen_ = 0;
  DeviceMesh mesh_;
  DeviceRaster model_;
  // The tracked mesh (TrackMesh): on, given in canonical coordinates (empty: the first frame's),
  // and on the device in grid units once the volume is placed (positions_grid fixed).
  bool track_mesh_ = false;
  TriangleMesh track_given_;
  // The mesh being tracked once fixed (canonical world metres; positions, colours, faces): what
  // checkpoints keep so a resumed run deforms the same vertices.
  TriangleMesh tracked_canonical_;
  // Uploads `source` (canonical world metres) as the tracked mesh's vertices, in grid units.
  Status FixTracked(const TriangleMesh& source);
  DeviceMesh tracked_;
  std::vector<vd_float4> tracked_host_;
  // Non-rigid state: the active set, the deformed mesh rendered at the current pose, the
  // per-pixel correspondences and the solver's buffers.
  DeviceActiveSet active_;
  // M's surface points alone, the solver's unknowns: the ring follows them (DeviceOps::Follow).
  DeviceActiveSet solved_;
  // FactorRigidMotion's gathered active state and its host copies.
  ocl::Buffer<vd_float4> factor_pos_, factor_rot_;
  std::vector<vd_float4> factor_host_;
  std::vector<int32_t> factor_list_;
  DeviceRaster live_;
  ocl::Buffer<VdCorrespondence> corr_;
  std::unique_ptr<HierarchicalSolver> solver_;
  // Sparse features: detection off the frame's thread, every frame's lifted features, the device
  // matcher, this frame's matches and their constraints.
  AsyncFeatureExtractor extractor_;
  FeatureHistory history_;
  FeatureMatcher matcher_;
  std::vector<SparseMatch> matches_;
  std::vector<VdCorrespondence> sparse_host_;
  // This frame's matches as the pose step takes them.
  std::vector<PosePair> pose_pairs_;
  int64_t frames_seen_ = 0;
  // Non-rigid solves so far: the energies are evaluated on every energy_interval-th.
  int64_t nonrigid_solves_ = 0;
  Eigen::Matrix4d pose_ = Eigen::Matrix4d::Identity();
  // Pose at which mesh_ was last rendered into model_.
  Eigen::Matrix4d model_pose_ = Eigen::Matrix4d::Identity();
  VdCamera cam_{};
  // Per-frame input and pyramid; sized on the first frame and whenever the size changes.
  FrameMaps maps_;
  // Mesh download scratch (positions, grid positions, normals, colours).
  std::vector<vd_float4> host_pos_, host_grid_, host_nrm_;
  std::vector<uint32_t> host_col_;
  // Prefetched frames by sequence number (at most kMaxPrefetched, the oldest giving way: the next
  // frame, and those a caller offers before it takes that one), each built on its own thread;
  // Prefetch runs on the caller's thread (the node's receive thread, the offline reader, the
  // bench) beside Process. Finished maps go back to spare_maps_ so their buffers are reused.
  // The device work starts only while Process is solving (the window, see OpenPrefetchWindow):
  // started beside the previous frame's matching and tracking it slowed them by as much as it
  // saved.
  struct Prefetched {
    // On the heap: the thread building it keeps a pointer while the entry moves.
    std::unique_ptr<RgbdFrame> frame;
    std::unique_ptr<FrameMaps> maps;
    std::future<Status> done;
  };
  static constexpr size_t kMaxPrefetched = 3;
  std::mutex prep_mu_;
  std::map<int64_t, Prefetched> prefetched_;
  std::vector<std::unique_ptr<FrameMaps>> spare_maps_;
  bool prep_window_ = false;
  // Held by each prefetch thread while it runs: the second queue's kernel objects and DeviceOps
  // scratch take one frame at a time.
  std::mutex prep_run_mu_;
  // Starts p's preprocessing on its own thread (prep_mu_ held).
  void LaunchPrefetch(Prefetched* p);
  // While open (Process's solve and fusion), prefetched frames start at once; opening starts those
  // that waited.
  void SetPrefetchWindow(bool open);
};

// The sparse volume's pool use of a frame for status lines: "bricks U of P (x %)", and when the
// pool is full, how many bricks of the frame's surface found no room.
std::string BrickPoolNote(const FrameResult& r);

// Conversions between Eigen poses and the kernels' VdPose.
VdPose ToVdPose(const Eigen::Matrix4d& T);
// Process resident set size now and at its peak, bytes (from /proc/self/status).
int64_t ResidentBytes();
int64_t PeakResidentBytes();

}  // namespace vd
