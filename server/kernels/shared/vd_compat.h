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
typedef ulong vd_ulong;
typedef uchar vd_uchar;
typedef ushort vd_ushort;
#define VD_F4(x, y, z, w) ((float4)((x), (y), (z), (w)))
#define VD_ATOMIC_MIN_U32(ptr, v) atomic_min((ptr), (v))
/* cl_khr_int64_extended_atomics (the host checks for it, ocl.cpp); enabled by the kernel file. */
#define VD_ATOMIC_MIN_U64(ptr, v) atom_min((ptr), (v))
/* Compare-and-swap and increment of a 32-bit word; both return the old value. */
#define VD_ATOMIC_CMPXCHG_U32(ptr, expected, v) atomic_cmpxchg((ptr), (expected), (v))
#define VD_ATOMIC_INC_U32(ptr) atomic_inc(ptr)
#define VD_ATOMIC_XCHG_U32(ptr, v) atomic_xchg((ptr), (v))
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
typedef uint64_t vd_ulong;
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
template <typename U>
inline void VdAtomicMin(U* p, U v) {
  U cur = __atomic_load_n(p, __ATOMIC_RELAXED);
  while (v < cur && !__atomic_compare_exchange_n(p, &cur, v, true, __ATOMIC_RELAXED, __ATOMIC_RELAXED)) {
  }
}
inline void VD_ATOMIC_MIN_U32(vd_uint* p, vd_uint v) { VdAtomicMin(p, v); }
inline void VD_ATOMIC_MIN_U64(vd_ulong* p, vd_ulong v) { VdAtomicMin(p, v); }
inline vd_uint VD_ATOMIC_CMPXCHG_U32(vd_uint* p, vd_uint expected, vd_uint v) {
  __atomic_compare_exchange_n(p, &expected, v, false, __ATOMIC_RELAXED, __ATOMIC_RELAXED);
  return expected;
}
inline vd_uint VD_ATOMIC_INC_U32(vd_uint* p) { return __atomic_fetch_add(p, 1u, __ATOMIC_RELAXED); }
inline vd_uint VD_ATOMIC_XCHG_U32(vd_uint* p, vd_uint v) { return __atomic_exchange_n(p, v, __ATOMIC_RELAXED); }
#endif

/* Lanes: a kernel written over vd_lf / vd_li runs VD_LANES consecutive items per work item, as
 * explicit SIMD. PoCL does not vectorise across work items once its front end has packed a kernel
 * body into short vectors (its SLP pass runs first; the loop vectoriser then refuses vector-typed
 * instructions), so on a CPU device the host builds with VD_LANES = the device's preferred float
 * vector width (16 with AVX-512, 8 with AVX2) and launches ceil(items / VD_LANES) work items (a
 * Kernel handle marked kLaned, ocl/kernel.h). A GPU and the host reference use one lane: vd_lf is
 * float there and the same math runs per item. Lane conditions are vd_li masks: combine them with
 * & and |, and pick with vd_lsel(a, b, c) = c ? b : a, lane by lane. vd_lu holds unsigned lanes (packed
 * colours); vd_lu_to_lf, vd_lf_to_lu and vd_lf_to_li convert as C's casts do (truncating). */
#ifdef __OPENCL_C_VERSION__
#ifndef VD_LANES
#define VD_LANES 1
#endif
#if VD_LANES == 1
typedef float vd_lf;
typedef int vd_li;
typedef uint vd_lu;
#define vd_lu_to_lf(v) convert_float(v)
#define vd_lf_to_lu(v) convert_uint(v)
#define vd_lf_to_li(v) convert_int(v)
#define vd_lload(p) ((p)[0])
#define vd_lstore(v, p) ((p)[0] = (v))
#elif VD_LANES == 4
typedef float4 vd_lf;
typedef int4 vd_li;
typedef uint4 vd_lu;
#define vd_lu_to_lf(v) convert_float4(v)
#define vd_lf_to_lu(v) convert_uint4(v)
#define vd_lf_to_li(v) convert_int4(v)
#define vd_lload(p) vload4(0, (p))
#define vd_lstore(v, p) vstore4((v), 0, (p))
#elif VD_LANES == 8
typedef float8 vd_lf;
typedef int8 vd_li;
typedef uint8 vd_lu;
#define vd_lu_to_lf(v) convert_float8(v)
#define vd_lf_to_lu(v) convert_uint8(v)
#define vd_lf_to_li(v) convert_int8(v)
#define vd_lload(p) vload8(0, (p))
#define vd_lstore(v, p) vstore8((v), 0, (p))
#elif VD_LANES == 16
typedef float16 vd_lf;
typedef int16 vd_li;
typedef uint16 vd_lu;
#define vd_lu_to_lf(v) convert_float16(v)
#define vd_lf_to_lu(v) convert_uint16(v)
#define vd_lf_to_li(v) convert_int16(v)
#define vd_lload(p) vload16(0, (p))
#define vd_lstore(v, p) vstore16((v), 0, (p))
#else
#error "VD_LANES must be 1, 4, 8 or 16"
#endif
#define vd_lsel(a, b, c) select((a), (b), (c))
#else
#define VD_LANES 1
typedef float vd_lf;
typedef int vd_li;
inline float vd_lsel(float a, float b, int c) { return c ? b : a; }
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
