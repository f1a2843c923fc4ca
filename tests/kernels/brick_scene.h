#pragma once
// A sparse volume fused from the kernel tests' sphere scene, and the dense grid over the same
// voxel lattice, shared by the brick-table and sparse-mesh parity tests.
#include <algorithm>
#include <optional>
#include <vector>

#include "cpu_ref/brick_hash_ref.h"
#include "ocl/brick_hash_ocl.h"
#include "test_scenes.h"

namespace vd::test {

struct FusedBricks {
  VdCamera cam = TestCamera(160, 120);
  std::vector<float> depth = SphereDepth(cam, 0.8f, 0.2f, 1.2f);
  std::vector<uint32_t> rgba = TestColors(cam);
  VdPose cam_to_world = IdentityPose(), world_to_cam = IdentityPose();
  VdVolume vol{};
  float brick = 0.f;
  std::optional<ocl::BrickTable> table;
  std::optional<ocl::BrickPool> pool;
  ocl::Buffer<float> dd;
  ocl::Buffer<uint32_t> dc;
  ocl::BrickCounts counts;
  int frames = 0;

  // The pool's voxels of the slots in use (downloaded).
  struct Voxels {
    std::vector<float> tsdf, weight;
    std::vector<uint32_t> color;
  };
  Voxels Download(ocl::Context* ctx) const {
    const size_t n = size_t(counts.used) * VD_BRICK_VOXELS;
    return {FromDevice(ctx, pool->tsdf, n), FromDevice(ctx, pool->weight, n), FromDevice(ctx, pool->color, n)};
  }

  // The table as the CPU reference holds it (downloaded).
  cpu::BrickTable Reference(ocl::Context* ctx) const {
    cpu::BrickTable ref(table->capacity(), table->pool());
    ref.keys = FromDevice(ctx, table->keys(), table->capacity());
    ref.slots = FromDevice(ctx, table->slots(), table->capacity());
    ref.slot_keys = FromDevice(ctx, table->slot_keys(), table->pool());
    ref.counters[VD_BRICK_COUNT_TAKEN] = counts.used;
    return ref;
  }

  // A dense grid over the bricks' bounding box grown by `margin` voxels, its origin on the same
  // global lattice (its first point's coordinates a multiple of `align`), with the same frames fused
  // by the CPU reference; *lo: its first point's global grid coordinates.
  VdVolume DenseOver(const cpu::BrickTable& ref, int margin, std::vector<float>* tsdf, std::vector<float>* weight,
                     std::vector<uint32_t>* color, int lo[3], int align = 1) const {
    int hi[3] = {-(1 << 30), -(1 << 30), -(1 << 30)};
    lo[0] = lo[1] = lo[2] = 1 << 30;
    for (uint32_t s = 0; s < counts.used; ++s) {
      if (ref.slot_keys[s] == VD_BRICK_EMPTY) continue;
      for (int corner : {0, VD_BRICK_VOXELS - 1}) {
        int g[3];
        vd_brick_voxel(ref.slot_keys[s], corner, &g[0], &g[1], &g[2]);
        for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], g[a] - margin), hi[a] = std::max(hi[a], g[a] + margin);
      }
    }
    for (int a = 0; a < 3; ++a) lo[a] = lo[a] >= 0 ? lo[a] / align * align : -((-lo[a] + align - 1) / align) * align;
    VdVolume dense = vol;
    dense.origin = VD_F4(lo[0] * vol.voxel_size, lo[1] * vol.voxel_size, lo[2] * vol.voxel_size, 1.f);
    dense.dim_x = hi[0] - lo[0] + 1, dense.dim_y = hi[1] - lo[1] + 1, dense.dim_z = hi[2] - lo[2] + 1;
    const size_t nd = size_t(dense.dim_x) * dense.dim_y * dense.dim_z;
    tsdf->assign(nd, 1.f);
    weight->assign(nd, 0.f);
    color->assign(nd, 0u);
    for (int f = 0; f < frames; ++f)
      cpu::IntegrateTsdf(tsdf->data(), weight->data(), color->data(), dense, cam, world_to_cam, depth.data(),
                         rgba.data());
    return dense;
  }
};

// The sphere scene at 8 mm fused `frames` times into a fresh table and pool (with_field: with a
// deformation field at rest) (the camera about 5 cm
// right, 10 cm up and 20 cm forward of the world origin: not round numbers, since with them whole
// slices of voxels project exactly onto pixel boundaries).
inline void FuseSphere(ocl::Context* ctx, int frames, FusedBricks* f, bool with_field = false) {
  f->cam_to_world.r0.w = 0.0513f, f->cam_to_world.r1.w = -0.1037f, f->cam_to_world.r2.w = 0.2071f;
  f->world_to_cam.r0.w = -0.0513f, f->world_to_cam.r1.w = 0.1037f, f->world_to_cam.r2.w = -0.2071f;
  f->vol.voxel_size = 0.008f;
  f->vol.truncation = 0.032f;
  f->vol.max_weight = 64.f;
  f->brick = VD_BRICK * f->vol.voxel_size;
  f->frames = frames;
  auto table = ocl::BrickTable::Create(*ctx, 1 << 11);
  ASSERT_TRUE(table.ok());
  f->table = std::move(table).value();
  f->dd = ToDevice(ctx, f->depth);
  f->dc = ToDevice(ctx, f->rgba);
  ASSERT_TRUE(f->table->AllocateFromDepth(*ctx, f->dd, f->cam, f->cam_to_world, f->vol.truncation, f->brick).ok());
  auto pool = ocl::BrickPool::Create(*ctx, f->table->pool(), with_field);
  ASSERT_TRUE(pool.ok());
  f->pool = std::move(pool).value();
  auto allocated = f->table->Counts(*ctx);
  ASSERT_TRUE(allocated.ok());
  ASSERT_TRUE(f->pool->RestField(*ctx, *f->table, 0, allocated->used, f->vol.voxel_size).ok());
  for (int frame = 0; frame < frames; ++frame) {
    ASSERT_TRUE(f->table->ListVisible(*ctx, f->dd, f->cam, f->cam_to_world, f->vol.truncation, f->brick).ok());
    ASSERT_TRUE(ocl::IntegrateBricks(*ctx, *f->table, *f->pool, f->vol, f->cam, f->world_to_cam, f->dd, f->dc).ok());
  }
  auto counts = f->table->Counts(*ctx);
  ASSERT_TRUE(counts.ok());
  f->counts = *counts;
}

}  // namespace vd::test
