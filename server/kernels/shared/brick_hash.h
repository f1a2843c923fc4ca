/* The brick table of the sparse volume (issue 17; docs/SPARSE_VOLUME.md): a device-side spatial
 * hash from 8^3-brick coordinates to slots of a brick pool. Open addressing with linear probing
 * over a power-of-two table of 32-bit keys (10 signed bits per axis: bricks -512..511, +-16 m at
 * 4 mm voxels), so an insert is one compare-and-swap of OpenCL 1.2's core 32-bit atomics. The
 * winner of an insert takes the next pool slot; an insert that finds its key already there takes
 * nothing. Slots are read by separate lookup passes, never in the launch that inserts (a key's
 * winner may not have written its slot yet). */
#ifndef VD_BRICK_HASH_H
#define VD_BRICK_HASH_H

#include "vd_types.h"

#define VD_BRICK_EMPTY 0xffffffffu
#define VD_BRICK_COORD_MIN (-512)
#define VD_BRICK_COORD_MAX 511
/* Probes before an insert or lookup gives up: at the load factors the pool allows (at most half
 * the table) a run this long does not happen; an insert that meets it counts as a failure. */
#define VD_BRICK_MAX_PROBE 64
/* Counters the inserting kernels keep (one uint each): pool slots taken (may pass the pool size:
 * those inserts failed), inserts that found no table entry or no pool slot. */
#define VD_BRICK_COUNT_TAKEN 0
#define VD_BRICK_COUNT_FAILED 1
#define VD_BRICK_COUNTERS 2

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

/* The pool slot of a key, or -1 when the table does not hold it. */
VD_INLINE int vd_brick_find(VD_GLOBAL const vd_uint* keys, VD_GLOBAL const int* slots, vd_uint capacity, vd_uint key) {
  vd_uint h = vd_brick_home(key, capacity);
  for (int p = 0; p < VD_BRICK_MAX_PROBE; ++p) {
    vd_uint k = keys[h];
    if (k == key) return slots[h];
    if (k == VD_BRICK_EMPTY) return -1;
    h = (h + 1u) & (capacity - 1u);
  }
  return -1;
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

/* The brick holding world point p for bricks of `brick_size` metres. */
VD_INLINE void vd_brick_of(vd_float4 p, float brick_size, int* bx, int* by, int* bz) {
  *bx = (int)floor(p.x / brick_size);
  *by = (int)floor(p.y / brick_size);
  *bz = (int)floor(p.z / brick_size);
}

/* The bricks the segment from a to b (world, metres) passes through, by a 3D DDA over the brick
 * grid (so a brick the segment only clips at a corner is not skipped), each inserted unless it is
 * among the `*n_seen` keys in seen[] (the bricks this pixel's other rays inserted; at most 16
 * remembered). Returns the failures. */
VD_INLINE int vd_brick_allocate_segment(vd_float4 a, vd_float4 b, float brick_size, VD_GLOBAL vd_uint* keys,
                                        VD_GLOBAL int* slots, VD_GLOBAL vd_uint* slot_keys, vd_uint capacity,
                                        vd_uint pool, VD_GLOBAL vd_uint* counters, vd_uint* seen, int* n_seen) {
  float pa[3] = {a.x / brick_size, a.y / brick_size, a.z / brick_size};
  float dir[3] = {b.x / brick_size - pa[0], b.y / brick_size - pa[1], b.z / brick_size - pa[2]};
  int cell[3], step[3];
  float t_max[3], t_delta[3];
  for (int k = 0; k < 3; ++k) {
    cell[k] = (int)floor(pa[k]);
    step[k] = dir[k] > 0.0f ? 1 : -1;
    float boundary = dir[k] > 0.0f ? (float)(cell[k] + 1) : (float)cell[k];
    t_max[k] = dir[k] != 0.0f ? (boundary - pa[k]) / dir[k] : 3.4e38f;
    t_delta[k] = dir[k] != 0.0f ? fabs(1.0f / dir[k]) : 3.4e38f;
  }
  int failures = 0;
  /* Bricks the segment crosses: at most 1 + the sum of |steps| over the axes; capped. */
  for (int n = 0; n < 64; ++n) {
    if (!vd_brick_coords_valid(cell[0], cell[1], cell[2])) {
      VD_ATOMIC_INC_U32(&counters[VD_BRICK_COUNT_FAILED]);
      ++failures;
    } else {
      vd_uint key = vd_brick_pack(cell[0], cell[1], cell[2]);
      int known = 0;
      for (int j = 0; j < *n_seen; ++j) known |= seen[j] == key;
      if (!known) {
        if (*n_seen < 16) seen[(*n_seen)++] = key;
        if (!vd_brick_allocate(keys, slots, slot_keys, capacity, pool, counters, key)) ++failures;
      }
    }
    int k = t_max[0] < t_max[1] ? (t_max[0] < t_max[2] ? 0 : 2) : (t_max[1] < t_max[2] ? 1 : 2);
    if (t_max[k] > 1.0f) break;
    cell[k] += step[k];
    t_max[k] += t_delta[k];
  }
  return failures;
}

/* Allocation from one depth pixel (u, v) at depth d (metres, > 0): every brick that the pixel's
 * frustum within its truncation band (depth d - truncation to d + truncation) reaches, through the
 * segments of its centre ray and its four corner rays. Fusion sends a grid point to the pixel its
 * centre projects to, so a point the pixel fuses lies inside that frustum, up to half a pixel off
 * the centre ray: the centre ray alone left 15 of the 183115 fused near-surface points of the
 * parity test's scene (8 mm voxels) outside every brick. Returns the failures. */
VD_INLINE int vd_brick_allocate_pixel(int u, int v, float d, VdCamera cam, VdPose cam_to_world, float truncation,
                                      float brick_size, VD_GLOBAL vd_uint* keys, VD_GLOBAL int* slots,
                                      VD_GLOBAL vd_uint* slot_keys, vd_uint capacity, vd_uint pool,
                                      VD_GLOBAL vd_uint* counters) {
  if (!(d > 0.0f)) return 0;
  float near_d = d - truncation, far_d = d + truncation;
  if (near_d < 0.0f) near_d = 0.0f;
  vd_uint seen[16];
  int n_seen = 0, failures = 0;
  for (int r = 0; r < 5; ++r) {
    float du = r == 0 ? 0.0f : ((r & 1) ? -0.5f : 0.5f), dv = r == 0 ? 0.0f : (r < 3 ? -0.5f : 0.5f);
    float rx = ((float)u + du - cam.cx) / cam.fx, ry = ((float)v + dv - cam.cy) / cam.fy;
    vd_float4 a = vd_pose_apply(cam_to_world, VD_F4(rx * near_d, ry * near_d, near_d, 1.0f));
    vd_float4 b = vd_pose_apply(cam_to_world, VD_F4(rx * far_d, ry * far_d, far_d, 1.0f));
    failures +=
        vd_brick_allocate_segment(a, b, brick_size, keys, slots, slot_keys, capacity, pool, counters, seen, &n_seen);
  }
  return failures;
}

/* Compaction, one old table entry: a key whose slot is kept goes into the new table with the slot
 * `offsets[old slot]` (the exclusive prefix sum of `keep` over the old slots, so the kept bricks
 * take slots 0..kept-1 in their old order, whatever order the entries are visited in), recorded
 * in the new slot_keys. */
VD_INLINE void vd_brick_reinsert(vd_uint entry, VD_GLOBAL const vd_uint* old_keys, VD_GLOBAL const int* old_slots,
                                 VD_GLOBAL const vd_uint* keep, VD_GLOBAL const vd_uint* offsets,
                                 VD_GLOBAL vd_uint* keys, VD_GLOBAL int* slots, VD_GLOBAL vd_uint* slot_keys,
                                 vd_uint capacity, VD_GLOBAL vd_uint* counters) {
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
}

#endif /* VD_BRICK_HASH_H */
