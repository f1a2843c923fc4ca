#pragma once
// The flip-flop solver of one hierarchy level on the device (VolumeDeform section 7.1): rotations
// by Procrustes, positions by Jacobi-preconditioned conjugate gradients on
// (2 w_r L + w_d B^T B + lambda I) x = b, B^T B applied on the fly from constraints grouped by
// cell (shared/solver.h). Caller-owned buffers are reused: nothing is allocated once warm.
#include <cstdint>

#include "core/device_ops.h"
#include "shared/solver.h"

namespace vd {

struct SolverParams {
  // Weights of the dense point-to-plane term and the ARAP prior (paper eq. 1).
  float w_dense = 1.f;
  float w_reg = 2.f;
  // Damping towards the current positions, relative to w_reg: keeps parts without data still.
  float damping = 1e-4f;
  // Flip-flop iterations (position step + rotation step) per solve.
  int flip_flop_iterations = 4;
  // PCG iterations per position step, and the relative residual at which it stops early.
  int pcg_iterations = 20;
  float pcg_tolerance = 1e-4f;
  Status Validate() const;
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
  explicit DeviceSolver(DeviceOps* ops) : ops_(ops) {}

  // Groups the valid per-pixel constraints by cell and copies the active points' state.
  Status Setup(const DeviceVolume& v, const DeviceActiveSet& active, const ocl::Buffer<VdCorrespondence>& per_pixel,
               size_t num_pixels, const SolverParams& params);
  // Position step: PCG from the current positions; returns the iterations used.
  StatusOr<int> PositionStep();
  // Rotation step: Procrustes for every active point.
  Status RotationStep();
  // E_total at the current state, and its two parts.
  StatusOr<double> Energy(double* dense = nullptr, double* reg = nullptr);
  // Runs flip_flop_iterations of (positions, rotations).
  StatusOr<SolverSummary> Solve();
  // Writes positions and rotations back into the grid (counting the optimisation).
  Status WriteBack(DeviceVolume& v);

  size_t num_constraints() const { return num_constraints_; }
  // The current compact state (tests).
  const ocl::Buffer<vd_float4>& positions() const { return x_; }
  const ocl::Buffer<vd_float4>& rotations() const { return rot_; }

 private:
  StatusOr<double> Dot(const ocl::Buffer<vd_float4>& a, const ocl::Buffer<vd_float4>& b);
  StatusOr<double> SumPartials(size_t groups);
  VdSolverWeights Weights() const;

  DeviceOps* ops_;
  SolverParams params_;
  VdVolume vol_{};
  const DeviceActiveSet* active_ = nullptr;
  size_t m_ = 0;
  size_t num_constraints_ = 0;
  ocl::Buffer<int32_t> cell_of_;
  ocl::Buffer<uint32_t> cell_count_;
  ocl::Buffer<uint32_t> cell_start_;
  ocl::Buffer<VdCorrespondence> cons_;
  ocl::Buffer<float> targets_;
  ocl::Buffer<float> residuals_;
  ocl::Buffer<vd_float4> x_, x_prev_, rot_, rest_, b_, r_, z_, p_, q_;
  ocl::Buffer<VdMat3> diag_inv_;
  ocl::Buffer<float> partials_;
  std::vector<float> partials_host_;
};

}  // namespace vd
