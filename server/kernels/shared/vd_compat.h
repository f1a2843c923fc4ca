/* One vocabulary for OpenCL C 1.2 and C++17. All #ifdefs for the two worlds live here; the
 * shared per-item math headers include only this file and each other. */
#ifndef VD_COMPAT_H
#define VD_COMPAT_H

#ifdef __OPENCL_C_VERSION__
/* ---------------- OpenCL C ---------------- */
/* Same float results as the host reference: no contraction into fused multiply-adds. */
#pragma OPENCL FP_CONTRACT OFF
#define VD_GLOBAL __global
#define VD_CONSTANT __constant
/* Inlined everywhere: a call left in a kernel body keeps PoCL from vectorising across work items. */
#define VD_INLINE inline __attribute__((always_inline))
/* Full unrolling of a short loop with a constant trip count (static indices into private arrays). */
#define VD_UNROLL _Pragma("unroll")
#define VD_KERNEL_SIDE 1
typedef float4 vd_float4;
typedef uint vd_uint;
typedef long vd_long;
typedef uchar vd_uchar;
typedef ushort vd_ushort;
#define VD_F4(x, y, z, w) ((float4)((x), (y), (z), (w)))
#define VD_ATOMIC_MIN_U32(ptr, v) atomic_min((ptr), (v))
#define VD_FLOAT_AS_UINT(f) as_uint(f)

#else
/* ---------------- C++17 host ---------------- */
#include <math.h>
#include <stdint.h>
#include <string.h>

#define VD_GLOBAL
#define VD_CONSTANT static const
#define VD_INLINE inline
#define VD_UNROLL _Pragma("GCC unroll 64")
typedef uint32_t vd_uint;
typedef int64_t vd_long;
typedef uint8_t vd_uchar;
typedef uint16_t vd_ushort;

struct alignas(16) vd_float4 {
  float x, y, z, w;
};
inline vd_float4 VD_F4(float x, float y, float z, float w) { return vd_float4{x, y, z, w}; }
inline vd_float4 operator+(vd_float4 a, vd_float4 b) { return {a.x + b.x, a.y + b.y, a.z + b.z, a.w + b.w}; }
inline vd_float4 operator-(vd_float4 a, vd_float4 b) { return {a.x - b.x, a.y - b.y, a.z - b.z, a.w - b.w}; }
inline vd_float4 operator-(vd_float4 a) { return {-a.x, -a.y, -a.z, -a.w}; }
inline vd_float4 operator*(vd_float4 a, float s) { return {a.x * s, a.y * s, a.z * s, a.w * s}; }
inline vd_float4 operator*(float s, vd_float4 a) { return {a.x * s, a.y * s, a.z * s, a.w * s}; }
inline vd_float4 operator*(vd_float4 a, vd_float4 b) { return {a.x * b.x, a.y * b.y, a.z * b.z, a.w * b.w}; }
inline vd_float4 operator/(vd_float4 a, float s) { return {a.x / s, a.y / s, a.z / s, a.w / s}; }
inline vd_float4& operator+=(vd_float4& a, vd_float4 b) { a = a + b; return a; }
inline vd_uint VD_FLOAT_AS_UINT(float f) { vd_uint u; memcpy(&u, &f, 4); return u; }
/* The host reference runs single-threaded or with OpenMP; a relaxed atomic keeps it race-free. */
inline void VD_ATOMIC_MIN_U32(vd_uint* p, vd_uint v) {
  vd_uint cur = __atomic_load_n(p, __ATOMIC_RELAXED);
  while (v < cur && !__atomic_compare_exchange_n(p, &cur, v, true, __ATOMIC_RELAXED, __ATOMIC_RELAXED)) {
  }
}
#endif

VD_INLINE int vd_min_i(int a, int b) { return a < b ? a : b; }
VD_INLINE int vd_max_i(int a, int b) { return a > b ? a : b; }
VD_INLINE float vd_clampf(float v, float lo, float hi) { return v < lo ? lo : (v > hi ? hi : v); }

/* 3-vector helpers on float4 (w ignored), identical in both worlds. */
VD_INLINE float vd_dot3(vd_float4 a, vd_float4 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
VD_INLINE vd_float4 vd_cross3(vd_float4 a, vd_float4 b) {
  return VD_F4(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x, 0.0f);
}
VD_INLINE float vd_length3(vd_float4 a) { return sqrt(vd_dot3(a, a)); }
VD_INLINE vd_float4 vd_normalize3(vd_float4 a) {
  float n = vd_length3(a);
  float inv = n > 0.0f ? 1.0f / n : 0.0f;
  return VD_F4(a.x * inv, a.y * inv, a.z * inv, 0.0f);
}

#endif /* VD_COMPAT_H */
