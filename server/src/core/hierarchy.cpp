#include "core/hierarchy.h"

#include <algorithm>

#include "ocl/hierarchy_ocl.h"
#include "ocl/solver_ocl.h"

namespace vd {

Status HierarchicalSolver::BuildLevel(uint32_t slots, const DeviceActiveSet& fine, Level* L) {
  ocl::Context& ctx = ops_->ctx();
  L->lattice = lattice_.Level(L->spacing);
  const size_t n = L->lattice.Entries(slots);
  VD_RETURN_IF_ERROR(ctx.Reserve(&L->member, std::max<size_t>(n, 1)));
  VD_RETURN_IF_ERROR(ctx.Fill(L->member, uint8_t(0), n));
  VD_RETURN_IF_ERROR(ocl::MarkLevel(ctx, lattice_, fine, L->spacing, L->lattice, L->member));
  VD_RETURN_IF_ERROR(ocl::CompactLevel(*ops_, L->lattice, n, L->member, L->row_count, L->row_offset, &L->active));
  return ctx.Reserve(&L->x0, std::max<size_t>(L->active.count, 1));
}

Status HierarchicalSolver::Prepare(const DeviceLattice& lattice, uint32_t slots, const DeviceActiveSet& fine) {
  const int levels = params_.levels;
  if (lattice.lat.bricks && levels > 4)
    return InvalidArgument("on bricks of 8 voxels the hierarchy has at most 4 levels (spacing 8)");
  lattice_ = lattice;
  fine_active_ = &fine;
  // Levels kept for a frame that needs fewer keep their buffers for the next that needs them.
  while (int(levels_.size()) < levels - 1) levels_.push_back(std::make_unique<Level>(ops_, params_));
  coarse_ = std::max(0, std::min(levels_in_use_ > 0 ? levels_in_use_ : levels, levels) - 1);
  for (int i = 0; i < coarse_; ++i) {
    levels_[i]->spacing = 2 << i;
    VD_RETURN_IF_ERROR(BuildLevel(slots, fine, levels_[i].get()));
  }
  return Status::Ok();
}

StatusOr<SolverSummary> HierarchicalSolver::Solve(const ocl::Buffer<vd_float4>& def_pos,
                                                  const ocl::Buffer<vd_float4>& def_rot,
                                                  const ocl::Buffer<VdCorrespondence>& per_pixel, size_t n,
                                                  bool energies) {
  const SolverParams& params = params_;
  if (!fine_active_) return FailedPrecondition("HierarchicalSolver::Solve before Prepare");
  ocl::Context& ctx = ops_->ctx();
  const DeviceActiveSet& fine = *fine_active_;
  VD_RETURN_IF_ERROR(fine_.Setup(lattice_, def_pos, def_rot, fine, per_pixel, n));
  SolverSummary summary;
  if (energies) {
    VD_ASSIGN_OR_RETURN(summary.energy_initial, fine_.Energy());
  }

  const size_t nc = fine_.num_constraints();
  const bool coarse = coarse_ > 0 && params.coarse_flip_flop_iterations > 0 && nc > 0;
  if (coarse && params.cache_btb_coarse) {
    VD_RETURN_IF_ERROR(SolveCoarseFromMoments(fine, nc, &summary));
  } else if (coarse) {
    // Without the cache the constraints are re-expressed on each level and sorted. Coarsest first;
    // each level restricts the current fine state, so it solves for what the coarser levels left.
    const int top = coarse_ - 1;
    for (int i = top; i >= 0; --i) {
      Level& L = *levels_[i];
      if (L.active.count == 0) continue;
      const int s = L.spacing;
      VD_RETURN_IF_ERROR(ctx.Reserve(&L.rot0, std::max<size_t>(L.active.count, 1)));
      VD_RETURN_IF_ERROR(ocl::RestrictState(ctx, lattice_, fine, L.lattice, L.active, s, fine_.positions(),
                                            fine_.rotations(), L.x0, L.rot0));
      VD_RETURN_IF_ERROR(ctx.Reserve(&L.cons, std::max<size_t>(nc, 1)));
      VD_RETURN_IF_ERROR(ocl::RestrictConstraints(ctx, lattice_, fine, L.lattice, L.active, s, nc, fine_.constraints(),
                                                  fine_.constraint_cells(), fine_.positions(), L.x0, L.cons));
      VD_RETURN_IF_ERROR(L.solver.SetupConstraints(L.lattice, L.active, L.cons, nc));
      VD_RETURN_IF_ERROR(SolveLevel(fine, L, &summary));
    }
  }
  if (coarse) {
    // The fine rotations follow the prolongated positions before the fine flip-flop.
    VD_RETURN_IF_ERROR(fine_.RotationStep());
  }
  VD_ASSIGN_OR_RETURN(SolverSummary fs, fine_.Solve(params.flip_flop_iterations, false));

  summary.constraints = fs.constraints;
  summary.active_points = fs.active_points;
  summary.pcg_iterations += fs.pcg_iterations;
  if (energies) {
    VD_ASSIGN_OR_RETURN(summary.energy_final, fine_.Energy());
  }
  return summary;
}

Status HierarchicalSolver::SolveLevel(const DeviceActiveSet& fine, Level& L, SolverSummary* summary) {
  // Rotations warm-started from the fine ones (the mean of the last frame's around each point)
  // and refined for the restricted state first, then the flip-flop.
  VD_RETURN_IF_ERROR(L.solver.InitState(L.x0, L.rot0));
  VD_RETURN_IF_ERROR(L.solver.RotationStep());
  VD_ASSIGN_OR_RETURN(SolverSummary ls, L.solver.Solve(params_.coarse_flip_flop_iterations, false));
  summary->pcg_iterations += ls.pcg_iterations;
  return ocl::ProlongateIncrement(ops_->ctx(), lattice_, fine, L.lattice, L.active, L.spacing, L.solver.positions(),
                                  L.x0, fine_.mutable_positions());
}

Status HierarchicalSolver::SolveCoarseFromMoments(const DeviceActiveSet& fine, size_t nc, SolverSummary* summary) {
  ocl::Context& ctx = ops_->ctx();
  const int top = coarse_ - 1;
  // Every level's moments at the fine state of the solve's start: the first level's from the fine
  // constraints, each level above from the one below (the same sums, shared/hierarchy.h
  // vd_level_moments_up, without walking the constraints again).
  for (int i = 0; i <= top; ++i) {
    Level& L = *levels_[i];
    if (L.active.count == 0) continue;
    const size_t n = std::max<size_t>(L.active.count, 1);
    VD_RETURN_IF_ERROR(ctx.Reserve(&L.rot0, n));
    VD_RETURN_IF_ERROR(ctx.Reserve(&L.shift, n));
    VD_RETURN_IF_ERROR(ctx.Fill(L.shift, VD_F4(0.f, 0.f, 0.f, 0.f), L.active.count));
    VD_RETURN_IF_ERROR(L.solver.SetupFromMoments(L.lattice, L.active, nc));
    if (i == 0) {
      VD_RETURN_IF_ERROR(ocl::LevelMoments(ctx, lattice_, fine, L.lattice, L.active, L.spacing, fine_.constraints(),
                                           fine_.cell_start(), fine_.positions(), L.solver.mutable_moments()));
    } else {
      const Level& B = *levels_[i - 1];
      VD_RETURN_IF_ERROR(ocl::LevelMomentsUp(ctx, B.lattice, B.active, L.lattice, L.active, B.solver.moments(),
                                             L.solver.mutable_moments()));
    }
  }
  // Coarsest first; each level restricts the current fine state (x0), so it solves for what the
  // coarser levels left. Its data term is w n . (p~ - p_cur + sum alpha (x - x0)) with p_cur under
  // the current fine state, while its moments hold the residuals at the start's: a coarser level's
  // increment u moved p_cur by sum alpha u exactly (a trilinear field is trilinear on every finer
  // cell), so the system is the start's assembled at x0 - u (shift). Each solved level therefore
  // subtracts its increment from the shift of every finer level.
  for (int i = top; i >= 0; --i) {
    Level& L = *levels_[i];
    if (L.active.count == 0) continue;
    VD_RETURN_IF_ERROR(ocl::RestrictState(ctx, lattice_, fine, L.lattice, L.active, L.spacing, fine_.positions(),
                                          fine_.rotations(), L.x0, L.rot0));
    VD_RETURN_IF_ERROR(ocl::Axpy(ctx, L.active.count, 1.f, L.x0, L.shift));
    VD_RETURN_IF_ERROR(L.solver.AssembleFromMoments(L.shift));
    VD_RETURN_IF_ERROR(SolveLevel(fine, L, summary));
    for (int j = i - 1; j >= 0; --j) {
      Level& F = *levels_[j];
      if (F.active.count == 0) continue;
      // x0 - x: the increment, negated.
      VD_RETURN_IF_ERROR(ocl::ProlongateIncrement(ctx, F.lattice, F.active, L.lattice, L.active, L.spacing / F.spacing,
                                                  L.x0, L.solver.positions(), F.shift));
    }
  }
  return Status::Ok();
}

}  // namespace vd
