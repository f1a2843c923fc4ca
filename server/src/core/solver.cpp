#include "core/solver.h"

#include <cassert>
#include <cmath>
#include <sstream>

#include "ocl/procrustes_ocl.h"
#include "ocl/solver_ocl.h"
#include "vd/common/flags.h"

namespace vd {
namespace {
// Elements per work item of the partial sums.
constexpr int kChunk = 256;
}  // namespace

void SolverParams::Bind(FlagParser* f) {
  f->Add("w-dense", &w_dense, "Weight w_d of the dense point-to-plane term (paper eq. 1)");
  f->Add("w-reg", &w_reg, "Weight w_r of the as-rigid-as-possible prior (paper eq. 1)");
  f->Add("w-photo", &w_photo,
         "Dense colour term, solved on the coarse levels: metres of point-to-plane error one unit of intensity "
         "(black to white) weighs as (0 = off; it runs on colour registered to depth, --colour-registered)");
  f->Add("photo-max-strength", &photo_max_strength, "A colour row weighs at most this much of a depth row");
  f->Add("photo-huber", &photo_huber, "Intensity residual beyond which a colour row weighs linearly (Huber)");
  f->Add("photo-min-gradient", &photo_min_gradient,
         "Colour rows whose smoothed intensity changes by less than this per pixel are dropped");
  f->Add("damping", &damping, "Damping towards the current positions, relative to w_reg");
  f->Add("levels", &levels, "Levels of the non-rigid solver's coarse-to-fine hierarchy (1 = fine grid only)");
  f->Add("flip-flop-iterations", &flip_flop_iterations, "Flip-flop iterations on the fine level per outer iteration");
  f->Add("coarse-iterations", &coarse_flip_flop_iterations,
         "Flip-flop iterations on each coarse level per outer iteration");
  f->Add("pcg-iterations", &pcg_iterations, "PCG iterations per position step (at most)");
  f->Add("pcg-tolerance", &pcg_tolerance, "Relative residual at which PCG stops early");
  f->Add("rotation-iterations", &rotation_iterations,
         "Warm-started refinement steps per rotation step (0 = exact SVD each time)");
  f->Add("energy-interval", &energy_interval,
         "Solves between evaluations of the energy before and after the solve (status diagnostics; 1 = every frame)");
  f->Add("adaptive-rigidity", &adaptive_rigidity,
         "Adaptive rigidity: an ARAP edge's weight halves where the field's strain reaches this fraction of a voxel "
         "(0: the paper's uniform weight)");
  f->Add("rigidity-floor", &rigidity_floor, "Lowest ARAP edge weight adaptive rigidity may give");
  f->AddNegation("no-btb-cache-coarse", &cache_btb_coarse,
                 "Apply B^T B from the constraints on the coarse levels instead of caching its blocks");
  f->AddNegation("no-btb-cache-fine", &cache_btb_fine,
                 "Apply B^T B from the constraints on the fine level instead of caching its blocks");
}

Status SolverParams::Validate() const {
  if (!(w_dense > 0.f && w_dense < 1e6f)) return ParamOutOfBounds("SolverParams", "w_dense", w_dense, "0 < w_dense < 1e6");
  if (!(w_reg > 0.f && w_reg < 1e6f)) return ParamOutOfBounds("SolverParams", "w_reg", w_reg, "0 < w_reg < 1e6");
  if (!(w_photo >= 0.f && w_photo <= 10.f))
    return ParamOutOfBounds("SolverParams", "w_photo", w_photo, "0 <= w_photo <= 10 m");
  if (!(photo_max_strength > 0.f && photo_max_strength <= 100.f))
    return ParamOutOfBounds("SolverParams", "photo_max_strength", photo_max_strength, "0 < strength <= 100");
  if (!(photo_huber > 0.f && photo_huber <= 1.f))
    return ParamOutOfBounds("SolverParams", "photo_huber", photo_huber, "0 < huber <= 1");
  if (!(photo_min_gradient >= 0.f && photo_min_gradient < 1.f))
    return ParamOutOfBounds("SolverParams", "photo_min_gradient", photo_min_gradient, "0 <= gradient < 1");
  if (!(damping > 0.f && damping < 1.f)) return ParamOutOfBounds("SolverParams", "damping", damping, "0 < damping < 1");
  if (!(flip_flop_iterations >= 1 && flip_flop_iterations <= 100))
    return ParamOutOfBounds("SolverParams", "flip_flop_iterations", flip_flop_iterations, "1 <= n <= 100");
  if (!(pcg_iterations >= 1 && pcg_iterations <= 1000)) return ParamOutOfBounds("SolverParams", "pcg_iterations", pcg_iterations, "1 <= n <= 1000");
  if (!(pcg_tolerance > 0.f && pcg_tolerance < 1.f)) return ParamOutOfBounds("SolverParams", "pcg_tolerance", pcg_tolerance, "0 < tol < 1");
  if (!(rotation_iterations >= 0 && rotation_iterations <= 50))
    return ParamOutOfBounds("SolverParams", "rotation_iterations", rotation_iterations, "0 <= n <= 50");
  if (!(energy_interval >= 1 && energy_interval <= 100000))
    return ParamOutOfBounds("SolverParams", "energy_interval", energy_interval, "1 <= n <= 100000");
  if (!(levels >= 1 && levels <= 5)) return ParamOutOfBounds("SolverParams", "levels", levels, "1 <= levels <= 5");
  if (!(coarse_flip_flop_iterations >= 0 && coarse_flip_flop_iterations <= 100))
    return ParamOutOfBounds("SolverParams", "coarse_flip_flop_iterations", coarse_flip_flop_iterations, "0 <= n <= 100");
  if (!(adaptive_rigidity >= 0.f && adaptive_rigidity <= 10.f))
    return ParamOutOfBounds("SolverParams", "adaptive_rigidity", adaptive_rigidity, "0 <= s <= 10 voxels");
  if (!(rigidity_floor > 0.f && rigidity_floor <= 1.f))
    return ParamOutOfBounds("SolverParams", "rigidity_floor", rigidity_floor, "0 < floor <= 1");
  return Status::Ok();
}

DeviceSolver::DeviceSolver(DeviceOps* ops, const SolverParams& params, bool cache_btb)
    : ops_(ops), params_(params), cache_btb_(cache_btb) {
  assert(params.Validate().ok());
}

VdSolverWeights DeviceSolver::Weights() const {
  VdSolverWeights w{};
  w.w_dense = params_.w_dense;
  w.w_reg = params_.w_reg;
  w.damping = params_.damping * params_.w_reg;
  w.weighted_edges = adaptive_ ? 1 : 0;
  return w;
}

Status DeviceSolver::Setup(const DeviceVolume& v, const DeviceActiveSet& active,
                           const ocl::Buffer<VdCorrespondence>& per_pixel, size_t num_pixels) {
  if (!v.has_deformation()) return FailedPrecondition("the solver needs a grid with a deformation field");
  return Setup(DeviceLattice::Dense(v.vol), v.def_pos, v.def_rot, active, per_pixel, num_pixels);
}

Status DeviceSolver::Setup(const DeviceLattice& lattice, const ocl::Buffer<vd_float4>& def_pos,
                           const ocl::Buffer<vd_float4>& def_rot, const DeviceActiveSet& active,
                           const ocl::Buffer<VdCorrespondence>& per_pixel, size_t num_pixels) {
  const Field field{&def_pos, &def_rot};
  VD_RETURN_IF_ERROR(SetupLevel(lattice, active, per_pixel, num_pixels, &field));
  rot_warm_ = true;
  return Status::Ok();
}

Status DeviceSolver::InitState(const ocl::Buffer<vd_float4>& x0) {
  ocl::Context& ctx = ops_->ctx();
  if (m_ == 0) return Status::Ok();
  VD_RETURN_IF_ERROR(ctx.Copy(x0, x_, m_));
  rot_warm_ = false;
  return ctx.Fill(rot_, VD_F4(0.f, 0.f, 0.f, 1.f), m_);
}

Status DeviceSolver::InitState(const ocl::Buffer<vd_float4>& x0, const ocl::Buffer<vd_float4>& rot0) {
  ocl::Context& ctx = ops_->ctx();
  if (m_ == 0) return Status::Ok();
  VD_RETURN_IF_ERROR(ctx.Copy(x0, x_, m_));
  rot_warm_ = true;
  return ctx.Copy(rot0, rot_, m_);
}

Status DeviceSolver::SetupConstraints(const DeviceLattice& lattice, const DeviceActiveSet& active,
                                      const ocl::Buffer<VdCorrespondence>& per_pixel, size_t num_pixels) {
  return SetupLevel(lattice, active, per_pixel, num_pixels, nullptr);
}

Status DeviceSolver::SetupLevel(const DeviceLattice& lattice, const DeviceActiveSet& active,
                                const ocl::Buffer<VdCorrespondence>& per_pixel, size_t num_pixels, const Field* field) {
  ocl::Context& ctx = ops_->ctx();
  VD_RETURN_IF_ERROR(SetupPoints(lattice, active));
  VD_RETURN_IF_ERROR(ctx.Reserve(&cell_count_, m_ + 1));
  VD_RETURN_IF_ERROR(ctx.Reserve(&cell_start_, m_ + 1));
  VD_RETURN_IF_ERROR(ctx.Reserve(&cell_of_, std::max<size_t>(num_pixels, 1)));
  if (field) VD_RETURN_IF_ERROR(ocl::GatherState(ctx, m_, active.list, *field->def_pos, *field->def_rot, x_, rot_));
  adaptive_ = field && params_.adaptive_rigidity > 0.f;
  if (adaptive_ && m_ > 0) {
    const float s = params_.adaptive_rigidity * lattice.lat.spacing;
    VD_RETURN_IF_ERROR(
        ocl::ArapEdgeWeights(ctx, m_, active.neighbours, x_, rot_, rest_, s * s, params_.rigidity_floor, edge_w_));
  } else if (m_ > 0) {
    VD_RETURN_IF_ERROR(ctx.Fill(edge_w_, 1.f, 6 * m_));
  }

  // Counting sort of the constraints by cell.
  VD_RETURN_IF_ERROR(ctx.Fill(cell_count_, 0u, m_ + 1));
  VD_RETURN_IF_ERROR(ocl::CountConstraints(ctx, num_pixels, per_pixel, lattice_, active, cell_of_, cell_count_));
  uint32_t total = 0;
  VD_RETURN_IF_ERROR(ops_->ScanExclusive(cell_count_, m_, cell_start_, &total));
  num_constraints_ = total;
  VD_RETURN_IF_ERROR(ctx.Reserve(&cons_, std::max<size_t>(total, 1)));
  VD_RETURN_IF_ERROR(ctx.Reserve(&cons_cell_, std::max<size_t>(total, 1)));
  VD_RETURN_IF_ERROR(ctx.Reserve(&cons_order_, std::max<size_t>(total, 1)));
  VD_RETURN_IF_ERROR(ctx.Reserve(&targets_, std::max<size_t>(total, 1)));
  VD_RETURN_IF_ERROR(ctx.Reserve(&residuals_, std::max<size_t>(total, 1)));
  VD_RETURN_IF_ERROR(ctx.Fill(cell_count_, 0u, m_ + 1));
  VD_RETURN_IF_ERROR(ocl::SortConstraints(ctx, num_pixels, m_, per_pixel, cell_of_, cell_start_, cell_count_,
                                          cons_order_, cons_, cons_cell_));
  if (cache_btb_) {
    return ocl::BuildBtb(ctx, lattice_, active, edge_w_, cons_, cell_start_, Weights(), moments_, btb_, btb_nbr_,
                         data_rhs_, diag_inv_);
  }
  VD_RETURN_IF_ERROR(ocl::ConstraintTargets(ctx, total, cons_, targets_));
  return ocl::DataRhsAndDiagonal(ctx, lattice_, active, edge_w_, cons_, cell_start_, targets_, Weights(), data_rhs_,
                                 diag_inv_);
}

Status DeviceSolver::SetupPoints(const DeviceLattice& lattice, const DeviceActiveSet& active) {
  ocl::Context& ctx = ops_->ctx();
  lattice_ = lattice;
  active_ = &active;
  m_ = active.count;
  const size_t m = std::max<size_t>(m_, 1);
  for (auto* b : {&x_, &rot_, &rest_, &r_, &u_, &w_, &p_, &s_, &data_rhs_}) VD_RETURN_IF_ERROR(ctx.Reserve(b, m));
  VD_RETURN_IF_ERROR(ctx.Reserve(&diag_inv_, m));
  VD_RETURN_IF_ERROR(ctx.Reserve(&edge_w_, 6 * m));
  if (cache_btb_) {
    VD_RETURN_IF_ERROR(ctx.Reserve(&moments_, VD_CELL_MOMENT_FLOATS * m));
    VD_RETURN_IF_ERROR(ctx.Reserve(&btb_, VD_BTB_FLOATS * m));
    VD_RETURN_IF_ERROR(ctx.Reserve(&btb_nbr_, VD_BTB_BLOCKS * m));
  } else {
    VD_RETURN_IF_ERROR(ctx.Reserve(&b_, m));  // the cached path's start never stores b
  }
  if (m_ == 0) return Status::Ok();
  return ocl::RestPositions(ctx, lattice_, active, rest_);
}

Status DeviceSolver::SetupFromMoments(const DeviceLattice& lattice, const DeviceActiveSet& active,
                                      size_t num_constraints) {
  if (!cache_btb_) return FailedPrecondition("SetupFromMoments needs the cached B^T B");
  VD_RETURN_IF_ERROR(SetupPoints(lattice, active));
  num_constraints_ = num_constraints;
  adaptive_ = false;
  if (m_ == 0) return Status::Ok();
  return ops_->ctx().Fill(edge_w_, 1.f, 6 * m_);
}

Status DeviceSolver::AssembleFromMoments(const ocl::Buffer<vd_float4>& x0) {
  if (m_ == 0) return Status::Ok();
  ocl::Context& ctx = ops_->ctx();
  return ocl::AssembleBtb(ctx, lattice_, *active_, edge_w_, moments_, Weights(), x0, btb_, btb_nbr_, data_rhs_,
                          diag_inv_);
}

StatusOr<double> DeviceSolver::SumPartials(size_t groups) {
  partials_host_.resize(groups);
  VD_RETURN_IF_ERROR(ops_->ctx().Download(partials_, partials_host_.data(), groups));
  double s = 0.0;
  for (float v : partials_host_) s += v;
  return s;
}

Status DeviceSolver::Apply(const ocl::Buffer<vd_float4>& d, ocl::Buffer<vd_float4>& q) {
  ocl::Context& ctx = ops_->ctx();
  const auto& a = *active_;
  const VdSolverWeights w = Weights();
  if (cache_btb_) return ocl::ApplySystemCached(ctx, m_, btb_, btb_nbr_, d, q);
  VD_RETURN_IF_ERROR(ocl::ConstraintResiduals(ctx, num_constraints_, cons_, cons_cell_, lattice_, a, d, residuals_));
  return ocl::ApplySystem(ctx, lattice_, a, edge_w_, cons_, cell_start_, residuals_, d, w, q);
}

Status DeviceSolver::ApplyDots() {
  ocl::Context& ctx = ops_->ctx();
  if (cache_btb_) return ocl::PcgApplyDots(ctx, m_, scal_, btb_, btb_nbr_, r_, u_, w_, partials_);
  VD_RETURN_IF_ERROR(Apply(u_, w_));
  return ocl::PcgDots(ctx, m_, r_, u_, w_, partials_);
}

StatusOr<int> DeviceSolver::PositionStep() {
  if (m_ == 0) return 0;
  ocl::Context& ctx = ops_->ctx();
  const VdSolverWeights w = Weights();
  const auto& a = *active_;
  // Scalars on the device (shared/solver.h): per iteration an update with r.r, the convergence
  // test, one host round trip, then the product with the dots of the step sizes.
  const size_t chunks = std::max<size_t>((m_ + kChunk - 1) / kChunk, 1);
  const size_t groups = ocl::PcgGroups(m_);
  VD_RETURN_IF_ERROR(ctx.Reserve(&partials_, std::max(chunks, 3 * groups)));
  VD_RETURN_IF_ERROR(ctx.Reserve(&scal_, VD_PCG_SCALARS));
  const float tol = params_.pcg_tolerance;
  // r = b - A x, u = M^-1 r and the stop from b.b; x is the damping's anchor (b holds lambda x).
  size_t bb_partials = groups;
  if (cache_btb_) {
    VD_RETURN_IF_ERROR(ocl::PcgStart(ctx, m_, lattice_.lat.spacing, a.neighbours, edge_w_, rot_, data_rhs_, w, btb_,
                                     btb_nbr_, diag_inv_, x_, r_, u_, partials_));
  } else {
    VD_RETURN_IF_ERROR(
        ocl::SystemRhs(ctx, m_, lattice_.lat.spacing, a.neighbours, edge_w_, rot_, data_rhs_, x_, w, b_));
    VD_RETURN_IF_ERROR(Apply(x_, r_));
    VD_RETURN_IF_ERROR(ocl::SubFrom(ctx, m_, b_, r_));
    VD_RETURN_IF_ERROR(ocl::Precondition(ctx, m_, diag_inv_, r_, u_));
    VD_RETURN_IF_ERROR(ocl::DotPartials(ctx, chunks, b_, b_, int(m_), kChunk, partials_));
    bb_partials = chunks;
  }
  VD_RETURN_IF_ERROR(ocl::PcgScalars(ctx, partials_, int(bb_partials), VD_PCG_SET_STOP, tol, scal_));
  VD_RETURN_IF_ERROR(ApplyDots());
  VD_RETURN_IF_ERROR(ocl::PcgScalars(ctx, partials_, int(groups), VD_PCG_SET_START, tol, scal_));
  // The host reads each convergence test while the device already runs the next product and
  // update, queued behind the read: if the test says converged, they return at once on the
  // device (vd_pcg_done), so x ends where the one-round-trip-per-iteration loop left it, and the
  // device never waits for the host between iterations.
  int it = 0;
  ocl::PendingRead test;
  VD_RETURN_IF_ERROR(ctx.DownloadAsync(scal_, scal_host_.data(), VD_PCG_SCALARS, &test));
  VD_RETURN_IF_ERROR(ocl::PcgCgUpdate(ctx, m_, scal_, diag_inv_, w_, p_, s_, x_, r_, u_, partials_));
  for (;;) {
    VD_RETURN_IF_ERROR(ctx.Wait(&test));
    if (scal_host_[VD_PCG_CONVERGED] != 0.f) break;  // the update queued last did nothing
    if (++it == params_.pcg_iterations) break;       // no further update would use the next product
    VD_RETURN_IF_ERROR(ocl::PcgScalars(ctx, partials_, int(groups), VD_PCG_SET_RR, tol, scal_));
    VD_RETURN_IF_ERROR(ctx.DownloadAsync(scal_, scal_host_.data(), VD_PCG_SCALARS, &test));
    VD_RETURN_IF_ERROR(ApplyDots());
    VD_RETURN_IF_ERROR(ocl::PcgScalars(ctx, partials_, int(groups), VD_PCG_SET_NEXT, tol, scal_));
    VD_RETURN_IF_ERROR(ocl::PcgCgUpdate(ctx, m_, scal_, diag_inv_, w_, p_, s_, x_, r_, u_, partials_));
  }
  return it;
}

Status DeviceSolver::RotationStep() {
  const int iterations = rot_warm_ ? params_.rotation_iterations : 0;
  rot_warm_ = true;
  return ocl::FitRotations(ops_->ctx(), m_, active_->neighbours, edge_w_, x_, rest_, iterations, rot_);
}

StatusOr<double> DeviceSolver::Energy(double* dense, double* reg) {
  ocl::Context& ctx = ops_->ctx();
  const size_t gc = (num_constraints_ + kChunk - 1) / kChunk, gp = (m_ + kChunk - 1) / kChunk;
  VD_RETURN_IF_ERROR(ctx.Reserve(&partials_, std::max<size_t>(std::max(gc, gp), 1)));
  double ed = 0.0, er = 0.0;
  if (gc) {
    VD_RETURN_IF_ERROR(ocl::DenseEnergyPartials(ctx, gc, cons_, cons_cell_, int(num_constraints_), kChunk, lattice_,
                                                *active_, x_, partials_));
    VD_ASSIGN_OR_RETURN(ed, SumPartials(gc));
  }
  if (gp) {
    VD_RETURN_IF_ERROR(ocl::ArapEnergyPartials(ctx, gp, active_->neighbours, edge_w_, lattice_.lat.spacing, x_, rot_,
                                               int(m_), kChunk, partials_));
    VD_ASSIGN_OR_RETURN(er, SumPartials(gp));
  }
  if (dense) *dense = ed;
  if (reg) *reg = er;
  return params_.w_dense * ed + params_.w_reg * er;
}

StatusOr<SolverSummary> DeviceSolver::Solve(int iterations, bool energies) {
  SolverSummary s;
  s.constraints = int(num_constraints_);
  s.active_points = int(m_);
  if (energies) {
    VD_ASSIGN_OR_RETURN(s.energy_initial, Energy());
  }
  const int n = iterations >= 0 ? iterations : params_.flip_flop_iterations;
  for (int i = 0; i < n; ++i) {
    VD_ASSIGN_OR_RETURN(int it, PositionStep());
    s.pcg_iterations += it;
    VD_RETURN_IF_ERROR(RotationStep());
  }
  if (energies) {
    VD_ASSIGN_OR_RETURN(s.energy_final, Energy());
  }
  return s;
}

Status DeviceSolver::WriteBack(ocl::Buffer<vd_float4>& def_pos, ocl::Buffer<vd_float4>& def_rot) {
  return ocl::ScatterState(ops_->ctx(), m_, active_->list, x_, rot_, def_pos, def_rot);
}

}  // namespace vd
