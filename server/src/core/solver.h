#pragma once
// The flip-flop solver of one hierarchy level on the device (VolumeDeform section 7.1): rotations
// by Procrustes, positions by Jacobi-preconditioned conjugate gradients on
// (2 w_r L + w_d B^T B + lambda I) x = b, B^T B applied on the fly from constraints grouped by
// cell (shared/solver.h). Caller-owned buffers are reused: nothing is allocated once warm.
#include <array>
#include <cstdint>

#include "ocl/device_ops.h"
#include "shared/solver.h"

namespace vd {

class FlagParser;

struct SolverParams {
  // Weights of the dense point-to-plane term and the ARAP prior (paper eq. 1). w_reg was 2 while
  // the one-ring was solved too; over the surface points alone each point has fewer ARAP edges,
  // and 3 restores the rigid scene's stiffness (non-rigid displacement over 150 frames 0.76 mm at
  // 2, 0.72 at 3, 0.69 before) while the tube's drift falls 1.45 -> 1.08 mm (docs/BENCHMARKS.md
  // "Session 26").
  float w_dense = 1.f;
  float w_reg = 3.f;
  // The dense colour term (shared/correspondence.h vd_photometric_pixel; beyond the paper): the
  // metres of point-to-plane error one unit of intensity (black to white) weighs as, 0 = off. It
  // pins the motion along the surface that depth cannot see wherever the surface has texture. Its
  // rows enter the hierarchy's coarse levels alone (VD_CORR_COARSE_ONLY): the slide it corrects
  // adds up smoothly along a bending surface, while on the fine level the same rows pulled each
  // point by the image's grain (the rigid scene's non-rigid displacement over 150 frames 0.53 ->
  // 0.60 mm coarse-only, 0.66 -> 0.85 mm on every level). At 0.06 (docs/BENCHMARKS.md "Session
  // 35"): drift tube 1.09 -> 0.98 mm, cloth 2.24 -> 1.35, bend 150 7.34 -> 4.83, bend 300 7.6 ->
  // 5.59. Off by default: the fine level then needs 56 % more PCG iterations to settle the coarse
  // levels' correction, 10 % of the tube's frame, which the real-time targets cannot give (the
  // live 30 Hz fraction is 52-63 % against a bound of 50). It runs only on colour registered to
  // depth (EngineParams::colour_registered): on 7-Scenes, whose colour comes from a second,
  // uncalibrated sensor, it took the room's ATE 26.3 -> 31.6 mm (rigid 29.2; session 28, on every
  // level), trusting colour misplaced on the geometry; the registration check keeps it off there.
  float w_photo = 0.f;
  // A colour row weighs at most this much of a depth row: strong edges are where the linearisation
  // holds least. Coarse-only at 0.06: cap 1 bend 150 4.83 mm, rigid 150 0.60; with the cap at 4 and
  // w_photo 0.1 the bend reached 3.91 mm but the rigid scene 0.68 and the bend's worst surface
  // frame over 300 frames 0.98 mm (bound 1).
  float photo_max_strength = 1.f;
  // Intensity residual beyond which a colour row weighs linearly (Huber): occlusions, highlights
  // and lighting changes.
  float photo_huber = 0.1f;
  // Colour rows whose smoothed intensity changes by less than this per pixel are dropped (no
  // texture there: they would only cost time).
  float photo_min_gradient = 0.002f;
  // Damping towards the current positions, relative to w_reg: keeps parts without data still.
  float damping = 1e-4f;
  // Flip-flop iterations (position step + rotation step) per solve, on the finest level; with the
  // coarse levels in front, 2 reach what 4-8 did on one level (docs/BENCHMARKS.md).
  int flip_flop_iterations = 2;
  // Levels of the nested coarse-to-fine hierarchy (section 7.2): 1 = the fine grid only; level l
  // has 2^l times the voxel spacing. Coarse levels run coarse_flip_flop_iterations each.
  int levels = 3;
  // 2 reach what 4 did on the tube, cloth and rigid scenes to the printed digit (docs/BENCHMARKS.md).
  int coarse_flip_flop_iterations = 2;
  // Pre-compute and cache B^T B as 27 3x3 blocks per point before the PCG iterations (section
  // 7.1) instead of applying it from the constraints every iteration; per level kind.
  bool cache_btb_coarse = true;
  bool cache_btb_fine = true;
  // PCG iterations per position step, and the relative residual at which it stops early.
  int pcg_iterations = 20;
  float pcg_tolerance = 1e-4f;
  // Rotation step: refinement steps from each point's current rotation (shared/procrustes.h,
  // branch-free; 2 steps cost a third of the SVD, vd_procrustes_bench), or 0 for the exact SVD
  // every time. The first
  // rotation step of a coarse level, whose rotations start at the identity, is always exact.
  int rotation_iterations = 2;
  // Solves between evaluations of E_total before and after the solve (FrameResult, the status):
  // diagnostics only, each evaluation walks every constraint and point twice (~5 % of a frame).
  // 1 = every frame.
  int energy_interval = 10;
  // Adaptive rigidity (shared/solver.h vd_arap_edge_weights; the paper's section 10 names the
  // uniform ARAP weight a limitation): on the fine level each edge's weight falls as
  // 1 / (1 + e / s^2) with the strain e of the field at the solve's start, s this fraction of
  // the voxel, down to rigidity_floor; 0 = the paper's uniform weight.
  float adaptive_rigidity = 0.f;
  float rigidity_floor = 0.1f;
  Status Validate() const;
  // Registers a flag for every field; the fields' values now are the defaults --help shows.
  void Bind(FlagParser* flags);
};

struct SolverSummary {
  int constraints = 0;
  int active_points = 0;
  int pcg_iterations = 0;
  // E_total = w_d E_dense + w_r E_reg before and after the solve.
  double energy_initial = 0.0;
  double energy_final = 0.0;
};

class DeviceSolver {
 public:
  // params are validated by the caller (EngineParams::Validate at start-up); cache_btb: apply
  // B^T B from cached blocks (built in Setup) rather than from the constraints.
  DeviceSolver(DeviceOps* ops, const SolverParams& params, bool cache_btb);

  // Groups the valid per-pixel constraints by cell and copies the active points' state (and, with
  // adaptive rigidity, weighs the ARAP edges by its strain).
  Status Setup(const DeviceVolume& v, const DeviceActiveSet& active, const ocl::Buffer<VdCorrespondence>& per_pixel,
               size_t num_pixels);
  // The same on any lattice (shared/lattice.h: the dense grid or the pool's bricks), the field
  // def_pos / def_rot indexed by its entries.
  Status Setup(const DeviceLattice& lattice, const ocl::Buffer<vd_float4>& def_pos,
               const ocl::Buffer<vd_float4>& def_rot, const DeviceActiveSet& active,
               const ocl::Buffer<VdCorrespondence>& per_pixel, size_t num_pixels);
  // The two halves of Setup for a grid level without a stored field (coarse levels): constraints
  // grouped by the cells of `vol`, then positions x0 with identity rotations (solved exactly by
  // the first rotation step) or with the warm-start rotations rot0 (refined).
  Status SetupConstraints(const DeviceLattice& lattice, const DeviceActiveSet& active,
                          const ocl::Buffer<VdCorrespondence>& constraints, size_t n);
  // The other way for a coarse level with cached B^T B: no constraints of its own, its moments
  // filled by the caller from the fine constraints or the level below (mutable_moments(),
  // shared/hierarchy.h vd_level_moments, vd_level_moments_up), then assembled with its x0.
  // num_constraints is reported only.
  Status SetupFromMoments(const DeviceLattice& lattice, const DeviceActiveSet& active, size_t num_constraints);
  Status AssembleFromMoments(const ocl::Buffer<vd_float4>& x0);
  Status InitState(const ocl::Buffer<vd_float4>& x0);
  Status InitState(const ocl::Buffer<vd_float4>& x0, const ocl::Buffer<vd_float4>& rot0);
  // Position step: PCG from the current positions; returns the iterations used.
  StatusOr<int> PositionStep();
  // Rotation step: Procrustes for every active point, refined from the current rotations when
  // they are warm (after Setup, InitState with rotations or a rotation step), exact after
  // InitState without.
  Status RotationStep();
  // E_total at the current state, and its two parts.
  StatusOr<double> Energy(double* dense = nullptr, double* reg = nullptr);
  // Runs `iterations` (default flip_flop_iterations) of (positions, rotations); the energies are
  // evaluated only when asked for.
  StatusOr<SolverSummary> Solve(int iterations = -1, bool energies = true);
  // Writes positions and rotations back into the grid (counting the optimisation).
  Status WriteBack(DeviceVolume& v) { return WriteBack(v.def_pos, v.def_rot); }
  Status WriteBack(ocl::Buffer<vd_float4>& def_pos, ocl::Buffer<vd_float4>& def_rot);

  size_t num_constraints() const { return num_constraints_; }
  // The current compact state (tests).
  const ocl::Buffer<vd_float4>& positions() const { return x_; }
  ocl::Buffer<vd_float4>& mutable_positions() { return x_; }
  // Constraints sorted by cell (num_constraints() of them), and each one's cell (the compact index
  // of its first corner).
  const ocl::Buffer<VdCorrespondence>& constraints() const { return cons_; }
  const ocl::Buffer<int32_t>& constraint_cells() const { return cons_cell_; }
  const ocl::Buffer<vd_float4>& rotations() const { return rot_; }
  // Per-cell moments of the cached B^T B (VD_CELL_MOMENT_FLOATS per active point; filled by the
  // caller after SetupFromMoments) and the constraints' cell ranges (m + 1) as Setup left them.
  ocl::Buffer<float>& mutable_moments() { return moments_; }
  const ocl::Buffer<float>& moments() const { return moments_; }
  const ocl::Buffer<uint32_t>& cell_start() const { return cell_start_; }

 private:
  StatusOr<double> SumPartials(size_t groups);
  VdSolverWeights Weights() const;

  DeviceOps* ops_;
  const SolverParams params_;
  DeviceLattice lattice_{};
  // The stored field a fine level's state is gathered from.
  struct Field {
    const ocl::Buffer<vd_float4>* def_pos;
    const ocl::Buffer<vd_float4>* def_rot;
  };
  const DeviceActiveSet* active_ = nullptr;
  size_t m_ = 0;
  size_t num_constraints_ = 0;
  ocl::Buffer<int32_t> cell_of_;
  ocl::Buffer<uint32_t> cell_count_;
  ocl::Buffer<uint32_t> cell_start_;
  ocl::Buffer<VdCorrespondence> cons_;
  ocl::Buffer<int32_t> cons_cell_;
  // The counting sort's scratch: each place's constraint index, put in input order per cell.
  ocl::Buffer<int32_t> cons_order_;
  ocl::Buffer<float> targets_;
  ocl::Buffer<float> residuals_;
  ocl::Buffer<vd_float4> x_, rot_, rest_;
  // The right-hand side (the constraints' path only: the cached path never stores it).
  ocl::Buffer<vd_float4> b_;
  // The PCG's vectors (Chronopoulos/Gear form, shared/solver.h): residual r, preconditioned u =
  // M^-1 r, its product w = A u, direction p and its product s = A p.
  ocl::Buffer<vd_float4> r_, u_, w_, p_, s_;
  // ARAP weight of each point's six edges, fixed per solve: 1, or from the field's strain
  // (adaptive rigidity, fine level only).
  ocl::Buffer<float> edge_w_;
  // edge_w_ holds strain weights (not all 1) in this solve.
  bool adaptive_ = false;
  // What every level kind needs per active point: lattice_, active_, m_, the per-point buffers
  // reserved (the cache's too when cached) and the rest positions.
  Status SetupPoints(const DeviceLattice& lattice, const DeviceActiveSet& active);
  // SetupConstraints with, on the fine level, the field the state is gathered from.
  Status SetupLevel(const DeviceLattice& lattice, const DeviceActiveSet& active,
                    const ocl::Buffer<VdCorrespondence>& per_pixel, size_t num_pixels, const Field* field);
  // rot_ holds rotations near the optimum (the stored field's or a previous rotation step's), so
  // the rotation step may refine them instead of solving from scratch.
  bool rot_warm_ = false;
  const bool cache_btb_;
  ocl::Buffer<float> btb_;
  ocl::Buffer<int32_t> btb_nbr_;
  // Per-cell moments of the constraints, scratch of the B^T B build (shared/solver.h).
  ocl::Buffer<float> moments_;
  // A d into q (both paths).
  Status Apply(const ocl::Buffer<vd_float4>& d, ocl::Buffer<vd_float4>& q);
  // w_ = A u_ with the triples (r.u, w.u, r.r) per work-group in partials_ (both paths).
  Status ApplyDots();
  // Constraint-only part of b, fixed per solve.
  ocl::Buffer<vd_float4> data_rhs_;
  ocl::Buffer<VdMat3> diag_inv_;
  ocl::Buffer<float> partials_;
  std::vector<float> partials_host_;
  // The PCG scalars (shared/solver.h VD_PCG_*): step sizes kept on the device between kernels.
  ocl::Buffer<float> scal_;
  // The host's copy of scal_, read behind queued work (PositionStep): a member, so it outlives
  // any read still in flight when a step returns early.
  std::array<float, VD_PCG_SCALARS> scal_host_{};
};

}  // namespace vd
