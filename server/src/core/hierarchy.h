#pragma once
// The nested coarse-to-fine solver (VolumeDeform section 7.2; docs/NONRIGID.md "Hierarchy"):
// coarse levels of 2^l times the voxel spacing are built from the fine active set every frame,
// solve for an increment of the field with all constraints re-expressed on their grid
// (shared/hierarchy.h), and jump-start the finer solve by prolongating that increment. With
// B^T B cached on the coarse levels (the default) a coarse system's moments are gathered from the
// fine constraints in place, without re-expressing or re-sorting them per level.
#include <memory>
#include <vector>

#include "core/solver.h"

namespace vd {

class HierarchicalSolver {
 public:
  // params are validated by the caller (EngineParams::Validate at start-up).
  HierarchicalSolver(DeviceOps* ops, const SolverParams& params)
      : ops_(ops), params_(params), fine_(ops, params, params.cache_btb_fine) {}

  // Builds levels 1 .. params.levels-1 from the fine active set (once per frame: M changes per
  // frame only), on the dense grid of v or on any fine lattice (the pool's bricks: `slots` of
  // them hold points; unused on a dense grid).
  Status Prepare(const DeviceVolume& v, const DeviceActiveSet& fine) {
    return Prepare(DeviceLattice::Dense(v.vol), 0, fine);
  }
  Status Prepare(const DeviceLattice& lattice, uint32_t slots, const DeviceActiveSet& fine);
  // One non-linear solve from the field's current state (def_pos / def_rot, indexed by the fine
  // lattice's entries): coarse levels first, then the fine level. With `energies`, the summary
  // has the fine level's E_total before and after (else 0).
  StatusOr<SolverSummary> Solve(const DeviceVolume& v, const ocl::Buffer<VdCorrespondence>& per_pixel, size_t n,
                                bool energies = true) {
    if (!v.has_deformation()) return FailedPrecondition("the solver needs a grid with a deformation field");
    return Solve(v.def_pos, v.def_rot, per_pixel, n, energies);
  }
  StatusOr<SolverSummary> Solve(const ocl::Buffer<vd_float4>& def_pos, const ocl::Buffer<vd_float4>& def_rot,
                                const ocl::Buffer<VdCorrespondence>& per_pixel, size_t n, bool energies = true);
  Status WriteBack(DeviceVolume& v) { return fine_.WriteBack(v); }
  Status WriteBack(ocl::Buffer<vd_float4>& def_pos, ocl::Buffer<vd_float4>& def_rot) {
    return fine_.WriteBack(def_pos, def_rot);
  }

  // Levels the next Prepare builds and the solve after it uses, 1 .. params.levels (0: all of
  // params.levels): the engine solves a static field on the fine level alone
  // (EngineParams::static_levels).
  void set_levels(int levels) { levels_in_use_ = levels; }
  // Levels of the last Prepare.
  int num_levels() const { return 1 + coarse_; }
  // Active points of level l (0 = fine).
  size_t active_points(int l) const { return l == 0 ? (fine_active_ ? fine_active_->count : 0) : levels_[l - 1]->active.count; }
  DeviceSolver& fine() { return fine_; }
  // Level l >= 1 (tests).
  const DeviceActiveSet& level_active(int l) const { return levels_[l - 1]->active; }
  const DeviceLattice& level_lattice(int l) const { return levels_[l - 1]->lattice; }

 private:
  struct Level {
    Level(DeviceOps* ops, const SolverParams& params) : solver(ops, params, params.cache_btb_coarse) {}
    int spacing = 2;
    DeviceLattice lattice;
    DeviceActiveSet active;
    ocl::Buffer<uint8_t> member;
    ocl::Buffer<uint32_t> row_count, row_offset;
    // Restricted starting positions, warm-start rotations, and the constraints re-expressed on
    // this level. With cached B^T B, shift is where its system (moments taken at the solve's
    // start) is assembled: x0 less the coarser levels' increments at its points.
    ocl::Buffer<vd_float4> x0, rot0, shift;
    ocl::Buffer<VdCorrespondence> cons;
    DeviceSolver solver;
  };
  Status BuildLevel(uint32_t slots, const DeviceActiveSet& fine, Level* level);
  // The coarse levels with cached B^T B (params.cache_btb_coarse), coarsest first; nc fine
  // constraints.
  Status SolveCoarseFromMoments(const DeviceActiveSet& fine, size_t nc, SolverSummary* summary);
  // Level L's system set up: its flip-flop from x0 and rot0, the increment added to the fine state.
  Status SolveLevel(const DeviceActiveSet& fine, Level& L, SolverSummary* summary);

  DeviceOps* ops_;
  const SolverParams params_;
  DeviceSolver fine_;
  const DeviceActiveSet* fine_active_ = nullptr;
  DeviceLattice lattice_;
  std::vector<std::unique_ptr<Level>> levels_;
  // set_levels' request, and the coarse levels (of levels_) the last Prepare built.
  int levels_in_use_ = 0;
  int coarse_ = 0;
};

}  // namespace vd
