#include "core/hierarchy.h"

#include <algorithm>

#include "ocl/active_set_ocl.h"
#include "ocl/hierarchy_ocl.h"

namespace vd {

VdVolume LevelVolume(const VdVolume& fine, int s) {
  VdVolume c = fine;
  c.voxel_size = fine.voxel_size * float(s);
  c.dim_x = (fine.dim_x - 1) / s + 2;
  c.dim_y = (fine.dim_y - 1) / s + 2;
  c.dim_z = (fine.dim_z - 1) / s + 2;
  return c;
}

Status HierarchicalSolver::BuildLevel(const DeviceVolume& v, const DeviceActiveSet& fine, Level* L) {
  ocl::Context& ctx = ops_->ctx();
  L->vol = LevelVolume(v.vol, L->spacing);
  const size_t n = size_t(L->vol.dim_x) * L->vol.dim_y * L->vol.dim_z, rows = size_t(L->vol.dim_y) * L->vol.dim_z;
  VD_RETURN_IF_ERROR(ctx.Reserve(&L->member, n));
  VD_RETURN_IF_ERROR(ctx.Reserve(&L->row_count, rows));
  VD_RETURN_IF_ERROR(ctx.Reserve(&L->row_offset, rows + 1));
  VD_RETURN_IF_ERROR(ctx.Reserve(&L->active.compact, n));
  VD_RETURN_IF_ERROR(ctx.Fill(L->member, uint8_t(0), n));
  VD_RETURN_IF_ERROR(ocl::MarkLevel(ctx, fine.count, fine.list, v.vol, L->spacing, L->vol, L->member));
  VD_RETURN_IF_ERROR(ocl::CountLevelRows(ctx, L->member, L->vol, L->row_count));
  uint32_t total = 0;
  VD_RETURN_IF_ERROR(ops_->ScanExclusive(L->row_count, rows, L->row_offset, &total));
  L->active.count = total;
  VD_RETURN_IF_ERROR(ctx.Reserve(&L->active.list, std::max<size_t>(total, 1)));
  VD_RETURN_IF_ERROR(ctx.Reserve(&L->active.neighbours, 6 * std::max<size_t>(total, 1)));
  VD_RETURN_IF_ERROR(ctx.Reserve(&L->x0, std::max<size_t>(total, 1)));
  return ocl::CompactActiveSet(ctx, L->member, L->row_offset, L->vol, &L->active);
}

Status HierarchicalSolver::Prepare(const DeviceVolume& v, const DeviceActiveSet& fine) {
  const int levels = params_.levels;
  fine_active_ = &fine;
  while (int(levels_.size()) < levels - 1) levels_.push_back(std::make_unique<Level>(ops_, params_));
  levels_.resize(std::max(0, levels - 1));
  for (size_t i = 0; i < levels_.size(); ++i) {
    levels_[i]->spacing = 2 << i;
    VD_RETURN_IF_ERROR(BuildLevel(v, fine, levels_[i].get()));
  }
  return Status::Ok();
}

Status HierarchicalSolver::LevelMoments(const DeviceVolume& v, Level* L) {
  const DeviceActiveSet& fine = *fine_active_;
  return ocl::LevelMoments(ops_->ctx(), L->active.count, L->active.list, L->vol, L->spacing, fine.compact, v.vol,
                           fine_.constraints(), fine_.cell_start(), fine_.positions(), L->solver.mutable_moments());
}

StatusOr<SolverSummary> HierarchicalSolver::Solve(const DeviceVolume& v,
                                                  const ocl::Buffer<VdCorrespondence>& per_pixel, size_t n,
                                                  bool energies) {
  const SolverParams& params = params_;
  if (!fine_active_) return FailedPrecondition("HierarchicalSolver::Solve before Prepare");
  ocl::Context& ctx = ops_->ctx();
  VD_RETURN_IF_ERROR(fine_.Setup(v, *fine_active_, per_pixel, n));
  SolverSummary summary;
  if (energies) {
    VD_ASSIGN_OR_RETURN(summary.energy_initial, fine_.Energy());
  }

  const size_t nc = fine_.num_constraints();
  const bool coarse = !levels_.empty() && params.coarse_flip_flop_iterations > 0 && nc > 0;
  if (coarse) {
    // With B^T B cached, each coarse system's moments come straight from the fine constraints
    // (shared/hierarchy.h); otherwise the constraints are re-expressed on the level and sorted.
    const bool from_moments = params.cache_btb_coarse;
    const int top = int(levels_.size()) - 1;
    // Coarsest first; each level restricts the current fine state, so it solves for what the
    // coarser levels left.
    for (int i = top; i >= 0; --i) {
      Level& L = *levels_[i];
      if (L.active.count == 0) continue;
      const int s = L.spacing;
      VD_RETURN_IF_ERROR(ctx.Reserve(&L.rot0, std::max<size_t>(L.active.count, 1)));
      VD_RETURN_IF_ERROR(ocl::RestrictState(ctx, L.active.count, L.active.list, L.vol, s, fine_active_->compact, v.vol,
                                            fine_.positions(), fine_.rotations(), L.x0, L.rot0));
      if (from_moments) {
        VD_RETURN_IF_ERROR(L.solver.SetupFromMoments(L.vol, L.active, nc));
        VD_RETURN_IF_ERROR(LevelMoments(v, &L));
        VD_RETURN_IF_ERROR(L.solver.AssembleFromMoments(L.x0));
      } else {
        VD_RETURN_IF_ERROR(ctx.Reserve(&L.cons, std::max<size_t>(nc, 1)));
        VD_RETURN_IF_ERROR(ocl::RestrictConstraints(ctx, nc, fine_.constraints(), fine_active_->compact, v.vol,
                                                    fine_.positions(), s, L.active.compact, L.vol, L.x0, L.cons));
        VD_RETURN_IF_ERROR(L.solver.SetupConstraints(L.vol, L.active, L.cons, nc));
      }
      // Rotations warm-started from the fine ones (the mean of the last frame's around each point)
      // and refined for the restricted state first, then the flip-flop.
      VD_RETURN_IF_ERROR(L.solver.InitState(L.x0, L.rot0));
      VD_RETURN_IF_ERROR(L.solver.RotationStep());
      VD_ASSIGN_OR_RETURN(SolverSummary ls, L.solver.Solve(params.coarse_flip_flop_iterations, false));

      summary.pcg_iterations += ls.pcg_iterations;
      VD_RETURN_IF_ERROR(ocl::ProlongateIncrement(ctx, fine_active_->count, fine_active_->list, v.vol, s,
                                                  L.active.compact, L.vol, L.solver.positions(), L.x0,
                                                  fine_.mutable_positions()));
    }
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

}  // namespace vd
