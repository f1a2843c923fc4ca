/* The brick table of the sparse volume (issue 17; docs/SPARSE_VOLUME.md): a device-side spatial
 * hash from 8^3-brick coordinates to slots of a brick pool. Open addressing with linear probing
 * over a power-of-two table of 32-bit keys (10 signed bits per axis: bricks -512..511, +-16 m at
 * 4 mm voxels), so an insert is one compare-and-swap of OpenCL 1.2's core 32-bit atomics. The
 * winner of an insert takes the next pool slot; an insert that finds its key already there takes
 * nothing. Slots are read by separate lookup passes, never in the launch that inserts (a key's
 * winner may not have written its slot yet). */
#ifndef VD_BRICK_HASH_H
#define VD_BRICK_HASH_H

#include "tsdf.h"
#include "vd_types.h"

#define VD_BRICK_EMPTY 0xffffffffu
#define VD_BRICK_COORD_MIN (-512)
#define VD_BRICK_COORD_MAX 511
/* Probes before an insert or lookup gives up: at the load factors the pool allows (at most half
 * the table) a run this long does not happen; an insert that meets it counts as a failure. */
#define VD_BRICK_MAX_PROBE 64
/* Counters the kernels keep (one uint each): pool slots taken (may pass the pool size: those
 * inserts failed), inserts that found no table entry or no pool slot. */
#define VD_BRICK_COUNT_TAKEN 0
#define VD_BRICK_COUNT_FAILED 1
/* Bricks listed for this frame (vd_brick_list_pixel). */
#define VD_BRICK_COUNT_VISIBLE 2
/* Bricks listed for this frame without a slot (the pool had no room): surface not fused. */
#define VD_BRICK_COUNT_UNFUSED 3
/* Bricks this frame's band reaches beyond the coordinates a key can name (VD_BRICK_COORD_MIN/MAX),
 * counted at every visit of AllocateAndList's walk (the same brick may count more than once). */
#define VD_BRICK_COUNT_OUT_OF_RANGE 4
#define VD_BRICK_COUNTERS 5

VD_INLINE int vd_brick_coords_valid(int bx, int by, int bz) {
  return bx >= VD_BRICK_COORD_MIN && bx <= VD_BRICK_COORD_MAX && by >= VD_BRICK_COORD_MIN && by <= VD_BRICK_COORD_MAX &&
         bz >= VD_BRICK_COORD_MIN && bz <= VD_BRICK_COORD_MAX;
}

/* Brick coordinates as one key (valid coordinates only: never VD_BRICK_EMPTY). */
VD_INLINE vd_uint vd_brick_pack(int bx, int by, int bz) {
  return (vd_uint)(bx - VD_BRICK_COORD_MIN) | ((vd_uint)(by - VD_BRICK_COORD_MIN) << 10) |
         ((vd_uint)(bz - VD_BRICK_COORD_MIN) << 20);
}

VD_INLINE void vd_brick_unpack(vd_uint key, int* bx, int* by, int* bz) {
  *bx = (int)(key & 1023u) + VD_BRICK_COORD_MIN;
  *by = (int)((key >> 10) & 1023u) + VD_BRICK_COORD_MIN;
  *bz = (int)((key >> 20) & 1023u) + VD_BRICK_COORD_MIN;
}

/* First table entry probed for a key (capacity: a power of two). Multiplicative hashing spreads
 * neighbouring bricks, whose keys differ in low bits, over the table. */
VD_INLINE vd_uint vd_brick_home(vd_uint key, vd_uint capacity) {
  vd_uint h = key * 2654435761u;
  h ^= h >> 15;
  return h & (capacity - 1u);
}

/* The table entry that holds a key, or -1 when the table does not hold it. */
VD_INLINE int vd_brick_entry(VD_GLOBAL const vd_uint* keys, vd_uint capacity, vd_uint key) {
  vd_uint h = vd_brick_home(key, capacity);
  for (int p = 0; p < VD_BRICK_MAX_PROBE; ++p) {
    vd_uint k = keys[h];
    if (k == key) return (int)h;
    if (k == VD_BRICK_EMPTY) return -1;
    h = (h + 1u) & (capacity - 1u);
  }
  return -1;
}

/* The pool slot of a key, or -1 when the table does not hold it. */
VD_INLINE int vd_brick_find(VD_GLOBAL const vd_uint* keys, VD_GLOBAL const int* slots, vd_uint capacity, vd_uint key) {
  int h = vd_brick_entry(keys, capacity, key);
  return h >= 0 ? slots[h] : -1;
}

/* After the slots a batch of inserts handed out were put in key order (slot_keys rewritten), the
 * entry of slot `slot`'s key takes that slot. */
VD_INLINE void vd_brick_reslot(int slot, VD_GLOBAL const vd_uint* slot_keys, VD_GLOBAL const vd_uint* keys,
                               VD_GLOBAL int* slots, vd_uint capacity) {
  int h = vd_brick_entry(keys, capacity, slot_keys[slot]);
  if (h >= 0) slots[h] = slot;
}

/* Inserts a key: returns the table entry that holds it and sets *fresh when this call put it
 * there (the caller then writes the entry's slot), or returns -1 when VD_BRICK_MAX_PROBE entries
 * from its home are all taken by other keys. */
VD_INLINE int vd_brick_insert(VD_GLOBAL vd_uint* keys, vd_uint capacity, vd_uint key, int* fresh) {
  vd_uint h = vd_brick_home(key, capacity);
  *fresh = 0;
  for (int p = 0; p < VD_BRICK_MAX_PROBE; ++p) {
    vd_uint old = VD_ATOMIC_CMPXCHG_U32(&keys[h], VD_BRICK_EMPTY, key);
    if (old == VD_BRICK_EMPTY) {
      *fresh = 1;
      return (int)h;
    }
    if (old == key) return (int)h;
    h = (h + 1u) & (capacity - 1u);
  }
  return -1;
}

/* Gives the entry h a key was just inserted into the next pool slot and records the key as the
 * slot's; -1 and a failure when the pool is used up. Returns 0 on a failure, else 1. */
VD_INLINE int vd_brick_give_slot(int h, VD_GLOBAL int* slots, VD_GLOBAL vd_uint* slot_keys, vd_uint pool,
                                 VD_GLOBAL vd_uint* counters, vd_uint key) {
  vd_uint slot = VD_ATOMIC_INC_U32(&counters[VD_BRICK_COUNT_TAKEN]);
  if (slot >= pool) {
    slots[h] = -1;
    VD_ATOMIC_INC_U32(&counters[VD_BRICK_COUNT_FAILED]);
    return 0;
  }
  slots[h] = (int)slot;
  slot_keys[slot] = key;
  return 1;
}

/* Inserts a key and, when it is new, gives its entry the next pool slot and records the key as
 * the slot's (slot_keys: one per pool slot); -1 and a failure when the pool of `pool` slots is
 * used up. Returns 0 on a failure, else 1. */
VD_INLINE int vd_brick_allocate(VD_GLOBAL vd_uint* keys, VD_GLOBAL int* slots, VD_GLOBAL vd_uint* slot_keys,
                                vd_uint capacity, vd_uint pool, VD_GLOBAL vd_uint* counters, vd_uint key) {
  int fresh = 0;
  int h = vd_brick_insert(keys, capacity, key, &fresh);
  if (h < 0) {
    VD_ATOMIC_INC_U32(&counters[VD_BRICK_COUNT_FAILED]);
    return 0;
  }
  if (!fresh) return 1;
  return vd_brick_give_slot(h, slots, slot_keys, pool, counters, key);
}

/* vd_brick_allocate for the brick at brick coordinates (x, y, z); beyond the keys' reach counts a
 * failure too. Returns 1 on a failure, else 0 (to sum a walk's failures). */
VD_INLINE int vd_brick_allocate_at(VD_GLOBAL vd_uint* keys, VD_GLOBAL int* slots, VD_GLOBAL vd_uint* slot_keys,
                                   vd_uint capacity, vd_uint pool, VD_GLOBAL vd_uint* counters, int x, int y, int z) {
  if (!vd_brick_coords_valid(x, y, z)) {
    VD_ATOMIC_INC_U32(&counters[VD_BRICK_COUNT_FAILED]);
    return 1;
  }
  return !vd_brick_allocate(keys, slots, slot_keys, capacity, pool, counters, vd_brick_pack(x, y, z));
}

/* Puts a key back into pool slot `slot` (restoring a table from its slots' keys, as a checkpoint
 * stores them): returns 0 and counts a failure when the key is not a brick's, is there already
 * (a duplicate) or finds no entry. */
VD_INLINE int vd_brick_restore(VD_GLOBAL vd_uint* keys, VD_GLOBAL int* slots, VD_GLOBAL vd_uint* slot_keys,
                               vd_uint capacity, VD_GLOBAL vd_uint* counters, vd_uint key, int slot) {
  int fresh = 0;
  int h = (key >> 30) == 0u ? vd_brick_insert(keys, capacity, key, &fresh) : -1;
  if (h < 0 || !fresh) {
    VD_ATOMIC_INC_U32(&counters[VD_BRICK_COUNT_FAILED]);
    return 0;
  }
  slots[h] = slot;
  slot_keys[slot] = key;
  return 1;
}

/* The brick holding world point p for bricks of `brick_size` metres. */
VD_INLINE void vd_brick_of(vd_float4 p, float brick_size, int* bx, int* by, int* bz) {
  *bx = (int)floor(p.x / brick_size);
  *by = (int)floor(p.y / brick_size);
  *bz = (int)floor(p.z / brick_size);
}

/* A 3D DDA over the brick grid along the segment from a to b (world, metres): every brick the
 * segment passes through, in order, so a brick it only clips at a corner is not skipped. */
typedef struct {
  int cell[3], step[3];
  float t_max[3], t_delta[3];
} VdBrickWalk;

VD_INLINE void vd_brick_walk_begin(VdBrickWalk* w, vd_float4 a, vd_float4 b, float brick_size) {
  float pa[3] = {a.x / brick_size, a.y / brick_size, a.z / brick_size};
  float dir[3] = {b.x / brick_size - pa[0], b.y / brick_size - pa[1], b.z / brick_size - pa[2]};
  for (int k = 0; k < 3; ++k) {
    w->cell[k] = (int)floor(pa[k]);
    w->step[k] = dir[k] > 0.0f ? 1 : -1;
    float boundary = dir[k] > 0.0f ? (float)(w->cell[k] + 1) : (float)w->cell[k];
    w->t_max[k] = dir[k] != 0.0f ? (boundary - pa[k]) / dir[k] : 3.4e38f;
    w->t_delta[k] = dir[k] != 0.0f ? fabs(1.0f / dir[k]) : 3.4e38f;
  }
}

/* Moves to the next brick; 0 when the segment ends in the current one. */
VD_INLINE int vd_brick_walk_next(VdBrickWalk* w) {
  int k = w->t_max[0] < w->t_max[1] ? (w->t_max[0] < w->t_max[2] ? 0 : 2) : (w->t_max[1] < w->t_max[2] ? 1 : 2);
  if (w->t_max[k] > 1.0f) return 0;
  w->cell[k] += w->step[k];
  w->t_max[k] += w->t_delta[k];
  return 1;
}

/* The segment between depths near_d and far_d, in world coordinates, of the ray through image
 * point (u, v) (pixel-edge coordinates). */
VD_INLINE void vd_brick_ray_segment(float u, float v, float near_d, float far_d, VdCamera cam, VdPose cam_to_world,
                                    vd_float4* a, vd_float4* b) {
  float rx = (u - cam.cx) / cam.fx, ry = (v - cam.cy) / cam.fy;
  *a = vd_pose_apply(cam_to_world, VD_F4(rx * near_d, ry * near_d, near_d, 1.0f));
  *b = vd_pose_apply(cam_to_world, VD_F4(rx * far_d, ry * far_d, far_d, 1.0f));
}

/* Whether `key` is among the *n_seen keys of seen[] (the bricks this item's other rays already
 * took; neighbouring rays mostly cross the same bricks); remembers it (up to 16) when not. */
VD_INLINE int vd_brick_seen(vd_uint key, vd_uint* seen, int* n_seen) {
  for (int j = 0; j < *n_seen; ++j)
    if (seen[j] == key) return 1;
  if (*n_seen < 16) seen[(*n_seen)++] = key;
  return 0;
}

/* What a pass over the depth's bricks does with each: allocate it, or list its slot once per frame
 * (after the allocation, when every slot is written): stamp[slot] takes `frame`, and a slot whose
 * stamp did not hold it already goes into visible[] (counted by counters[VD_BRICK_COUNT_VISIBLE]). */
#define VD_BRICK_ALLOCATE 0
#define VD_BRICK_LIST 1
/* Both in one pass: each brick is allocated and its table entry listed once per frame (stamp: one
 * per table entry, since a slot an other item is handing out may not be written yet); a second
 * pass turns the entries into slots (vd_brick_entry_slot). */
#define VD_BRICK_ALLOCATE_LIST 2

/* One brick of a pass; returns 1 on a failure. */
VD_INLINE int vd_brick_take(int mode, int bx, int by, int bz, VD_GLOBAL vd_uint* keys, VD_GLOBAL int* slots,
                            VD_GLOBAL vd_uint* slot_keys, vd_uint capacity, vd_uint pool, VD_GLOBAL vd_uint* stamp,
                            vd_uint frame, VD_GLOBAL int* visible, VD_GLOBAL vd_uint* counters, vd_uint* seen,
                            int* n_seen) {
  if (!vd_brick_coords_valid(bx, by, bz)) {
    if (mode == VD_BRICK_LIST) return 0;
    VD_ATOMIC_INC_U32(&counters[VD_BRICK_COUNT_FAILED]);
    if (mode == VD_BRICK_ALLOCATE_LIST) VD_ATOMIC_INC_U32(&counters[VD_BRICK_COUNT_OUT_OF_RANGE]);
    return 1;
  }
  vd_uint key = vd_brick_pack(bx, by, bz);
  if (vd_brick_seen(key, seen, n_seen)) return 0;
  if (mode == VD_BRICK_ALLOCATE) return !vd_brick_allocate(keys, slots, slot_keys, capacity, pool, counters, key);
  if (mode == VD_BRICK_ALLOCATE_LIST) {
    int fresh = 0;
    int h = vd_brick_insert(keys, capacity, key, &fresh);
    if (h < 0) {
      VD_ATOMIC_INC_U32(&counters[VD_BRICK_COUNT_FAILED]);
      return 1;
    }
    int failure = fresh ? !vd_brick_give_slot(h, slots, slot_keys, pool, counters, key) : 0;
    if (VD_ATOMIC_XCHG_U32(&stamp[h], frame) != frame)
      visible[VD_ATOMIC_INC_U32(&counters[VD_BRICK_COUNT_VISIBLE])] = h;
    return failure;
  }
  int slot = vd_brick_find(keys, slots, capacity, key);
  if (slot >= 0 && VD_ATOMIC_XCHG_U32(&stamp[slot], frame) != frame)
    visible[VD_ATOMIC_INC_U32(&counters[VD_BRICK_COUNT_VISIBLE])] = slot;
  return 0;
}

/* The second pass of VD_BRICK_ALLOCATE_LIST, one listed entry i: visible[i] becomes the entry's
 * slot (-1 when the pool had no room for it: counted as unfused) and the slot's stamp the frame. */
VD_INLINE void vd_brick_entry_slot(int i, VD_GLOBAL int* visible, VD_GLOBAL const int* slots,
                                   VD_GLOBAL vd_uint* slot_stamp, vd_uint frame, VD_GLOBAL vd_uint* counters) {
  int slot = slots[visible[i]];
  visible[i] = slot;
  if (slot >= 0)
    slot_stamp[slot] = frame;
  else
    VD_ATOMIC_INC_U32(&counters[VD_BRICK_COUNT_UNFUSED]);
}

/* Every brick the frustum of [u0, u1] x [v0, v1] reaches between near_d and far_d, through a
 * (k + 1)^2 grid of rays over the rectangle (and its centre ray when k is odd), k chosen so that
 * neighbouring rays are at most a quarter brick apart at far_d (at most 8), each a quarter brick
 * longer at both ends. Returns the failures. */
VD_INLINE int vd_brick_take_frustum(int mode, float u0, float v0, float u1, float v1, float near_d, float far_d,
                                    VdCamera cam, VdPose cam_to_world, float brick_size, VD_GLOBAL vd_uint* keys,
                                    VD_GLOBAL int* slots, VD_GLOBAL vd_uint* slot_keys, vd_uint capacity, vd_uint pool,
                                    VD_GLOBAL vd_uint* stamp, vd_uint frame, VD_GLOBAL int* visible,
                                    VD_GLOBAL vd_uint* counters, vd_uint* seen, int* n_seen) {
  float span = fmax((u1 - u0) * far_d / cam.fx, (v1 - v0) * far_d / cam.fy);
  int k = vd_min_i(8, vd_max_i(1, (int)ceil(span / (0.25f * brick_size))));
  /* A brick can reach into the space between the rays where they start or end: the segments run
   * a quarter brick further each way. */
  near_d = fmax(near_d - 0.25f * brick_size, 0.0f);
  far_d += 0.25f * brick_size;
  int rays = (k + 1) * (k + 1) + (k & 1);
  int failures = 0;
  for (int r = 0; r < rays; ++r) {
    float fu = r < (k + 1) * (k + 1) ? (float)(r % (k + 1)) / (float)k : 0.5f;
    float fv = r < (k + 1) * (k + 1) ? (float)(r / (k + 1)) / (float)k : 0.5f;
    vd_float4 a, b;
    vd_brick_ray_segment(u0 + fu * (u1 - u0), v0 + fv * (v1 - v0), near_d, far_d, cam, cam_to_world, &a, &b);
    VdBrickWalk w;
    vd_brick_walk_begin(&w, a, b, brick_size);
    /* At most 1 + the sum of |steps| over the axes; capped. */
    for (int n = 0; n < 64; ++n) {
      failures += vd_brick_take(mode, w.cell[0], w.cell[1], w.cell[2], keys, slots, slot_keys, capacity, pool, stamp,
                                frame, visible, counters, seen, n_seen);
      if (!vd_brick_walk_next(&w)) break;
    }
  }
  return failures;
}

/* A pass over depth tile `tile` (VD_DEPTH_TILE^2 pixels, shared/tsdf.h; depth in metres, 0 = none)
 * for bricks of brick_size metres: every brick that a fused grid point can lie in. Fusion sends a
 * grid point to the pixel its centre projects to, with |sdf| < truncation to count, so such a point
 * lies in that pixel's frustum between d - truncation and d + truncation. A tile whose valid depths
 * span at most 4 truncations is taken as one frustum over [min - truncation, max + truncation];
 * any other tile (a depth edge) by 2x2 groups of pixels under the same rule, and pixel by pixel
 * where a group straddles the edge. Each frustum through a grid of rays at most a
 * quarter brick apart: one ray per pixel left 15 of the 183115 fused near-surface points of the
 * parity test's scene (8 mm voxels) outside every brick, and a tile's four corners bricks of its
 * coarse test camera. Returns the failures. */
VD_INLINE int vd_brick_take_tile(int mode, int tile, VD_GLOBAL const float* depth, VdCamera cam, VdPose cam_to_world,
                                 float truncation, float brick_size, VD_GLOBAL vd_uint* keys, VD_GLOBAL int* slots,
                                 VD_GLOBAL vd_uint* slot_keys, vd_uint capacity, vd_uint pool, VD_GLOBAL vd_uint* stamp,
                                 vd_uint frame, VD_GLOBAL int* visible, VD_GLOBAL vd_uint* counters) {
  int tx = tile % vd_depth_tiles_x(cam), ty = tile / vd_depth_tiles_x(cam);
  int x0 = tx * VD_DEPTH_TILE, y0 = ty * VD_DEPTH_TILE;
  int x1 = vd_min_i(x0 + VD_DEPTH_TILE, cam.width), y1 = vd_min_i(y0 + VD_DEPTH_TILE, cam.height);
  vd_float4 range = vd_depth_tile(tile, depth, cam);
  if (!(range.x <= range.y)) return 0;
  vd_uint seen[16];
  int n_seen = 0;
  if (range.y - range.x <= 4.0f * truncation)
    return vd_brick_take_frustum(mode, (float)x0 - 0.5f, (float)y0 - 0.5f, (float)x1 - 0.5f, (float)y1 - 0.5f,
                                 fmax(range.x - truncation, 0.0f), range.y + truncation, cam, cam_to_world, brick_size,
                                 keys, slots, slot_keys, capacity, pool, stamp, frame, visible, counters, seen,
                                 &n_seen);
  /* A depth edge: each 2x2 group of pixels whose depths agree as a tile's must as one frustum, any
   * other group pixel by pixel (a pixel's frustum takes as many rays as a group's). */
  int failures = 0;
  for (int gy = y0; gy < y1; gy += 2)
    for (int gx = x0; gx < x1; gx += 2) {
      int gx1 = vd_min_i(gx + 2, x1), gy1 = vd_min_i(gy + 2, y1);
      vd_float4 g = vd_depth_range(depth, cam, gx, gy, gx1, gy1);
      if (!(g.x <= g.y)) continue;
      if (g.y - g.x <= 4.0f * truncation) {
        failures +=
            vd_brick_take_frustum(mode, (float)gx - 0.5f, (float)gy - 0.5f, (float)gx1 - 0.5f, (float)gy1 - 0.5f,
                                  fmax(g.x - truncation, 0.0f), g.y + truncation, cam, cam_to_world, brick_size, keys,
                                  slots, slot_keys, capacity, pool, stamp, frame, visible, counters, seen, &n_seen);
        continue;
      }
      for (int y = gy; y < gy1; ++y)
        for (int x = gx; x < gx1; ++x) {
          float d = depth[y * cam.width + x];
          if (!(d > 0.0f)) continue;
          failures +=
              vd_brick_take_frustum(mode, (float)x - 0.5f, (float)y - 0.5f, (float)x + 0.5f, (float)y + 0.5f,
                                    fmax(d - truncation, 0.0f), d + truncation, cam, cam_to_world, brick_size, keys,
                                    slots, slot_keys, capacity, pool, stamp, frame, visible, counters, seen, &n_seen);
        }
    }
  return failures;
}

/* Compaction, one old table entry: a key whose slot is kept goes into the new table with the slot
 * `offsets[old slot]` (the exclusive prefix sum of `keep` over the old slots, so the kept bricks
 * take slots 0..kept-1 in their old order, whatever order the entries are visited in), recorded
 * in the new slot_keys. */
VD_INLINE void vd_brick_reinsert(vd_uint entry, VD_GLOBAL const vd_uint* old_keys, VD_GLOBAL const int* old_slots,
                                 VD_GLOBAL const vd_uint* keep, VD_GLOBAL const vd_uint* offsets,
                                 VD_GLOBAL const vd_uint* old_stamp, VD_GLOBAL vd_uint* keys, VD_GLOBAL int* slots,
                                 VD_GLOBAL vd_uint* slot_keys, VD_GLOBAL vd_uint* stamp, vd_uint capacity,
                                 VD_GLOBAL vd_uint* counters) {
  vd_uint key = old_keys[entry];
  int slot = old_slots[entry];
  if (key == VD_BRICK_EMPTY || slot < 0 || !keep[slot]) return;
  int fresh = 0;
  int h = vd_brick_insert(keys, capacity, key, &fresh);
  if (h < 0) {
    VD_ATOMIC_INC_U32(&counters[VD_BRICK_COUNT_FAILED]);
    return;
  }
  slots[h] = (int)offsets[slot];
  slot_keys[offsets[slot]] = key;
  /* The frame it was last listed in moves with it (eviction drops the oldest). */
  stamp[offsets[slot]] = old_stamp[slot];
}

#endif /* VD_BRICK_HASH_H */
