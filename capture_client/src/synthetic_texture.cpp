// Procedural solid texture of the synthetic scenes and the counter-based random numbers.
#include <algorithm>
#include <cmath>

#include "synthetic_internal.h"

namespace vd::synthetic_internal {
namespace {

inline uint32_t Mix32(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

inline uint32_t CellHash(int32_t i, int32_t j, int32_t k, uint32_t layer) {
  uint32_t h = Mix32(static_cast<uint32_t>(i) * 0x9E3779B1u ^ layer);
  h = Mix32(h ^ (static_cast<uint32_t>(j) * 0x85EBCA77u));
  return Mix32(h ^ (static_cast<uint32_t>(k) * 0xC2B2AE3Du));
}

inline double Unit(uint32_t h) { return (h >> 8) * (1.0 / 16777216.0); }

// Saturated colours spread over the whole luminance range, so the grey image SIFT sees keeps
// strong contrast between neighbouring patches.
constexpr int kPaletteSize = 9;
const float kColourful[kPaletteSize][3] = {
    {20, 20, 25},    // black
    {240, 240, 235}, // white
    {30, 40, 210},   // red
    {30, 215, 245},  // yellow
    {200, 70, 20},   // blue
    {50, 180, 40},   // green
    {20, 140, 250},  // orange
    {150, 40, 120},  // purple
    {220, 200, 70},  // cyan
};
// Warm greys from near black to near white.
const float kMuted[kPaletteSize][3] = {
    {28, 30, 34}, {58, 62, 68}, {88, 94, 102}, {118, 126, 134}, {148, 156, 165},
    {176, 184, 192}, {202, 210, 216}, {226, 232, 236}, {244, 248, 250},
};

inline float Luminance(const Eigen::Vector3f& bgr) { return 0.114f * bgr[0] + 0.587f * bgr[1] + 0.299f * bgr[2]; }

inline Eigen::Vector3f PaletteColor(uint32_t index, bool muted) {
  // Decayed to pointers before choosing: GCC 12 with -fsanitize=undefined miscompiles indexing
  // a conditional expression of array type (it always read row 0).
  const float(*table)[3] = muted ? kMuted : kColourful;
  const float* c = table[index % kPaletteSize];
  return Eigen::Vector3f(c[0], c[1], c[2]);
}

// Chooses a palette colour from the hash whose luminance differs from `under` by at least 70.
Eigen::Vector3f ContrastingColor(uint32_t h, const Eigen::Vector3f& under, bool muted) {
  for (uint32_t attempt = 0; attempt < kPaletteSize; ++attempt) {
    const Eigen::Vector3f c = PaletteColor(h + attempt, muted);
    if (std::fabs(Luminance(c) - Luminance(under)) >= 70.f) return c;
  }
  return Luminance(under) > 128.f ? PaletteColor(0, muted) : PaletteColor(kPaletteSize - 1, muted);
}

// One dot per occupied cell: a sphere kept inside its cell, so only the cell containing q matters.
// Returns the coverage in [0, 1] (anti-aliased over ~0.4 mm) and the cell's hash.
double DotCoverage(const Eigen::Vector3d& q, double cell, uint32_t layer, double occupancy, uint32_t* hash) {
  const int32_t ci[3] = {static_cast<int32_t>(std::floor(q[0] / cell)), static_cast<int32_t>(std::floor(q[1] / cell)),
                         static_cast<int32_t>(std::floor(q[2] / cell))};
  const uint32_t h = CellHash(ci[0], ci[1], ci[2], layer);
  *hash = h;
  if (Unit(h) >= occupancy) return 0.0;
  const double r = cell * (0.22 + 0.23 * Unit(Mix32(h + 1)));
  double d2 = 0.0;
  for (int a = 0; a < 3; ++a) {
    const double c = cell * ci[a] + r + (cell - 2.0 * r) * Unit(Mix32(h + 2 + a));
    d2 += (q[a] - c) * (q[a] - c);
  }
  const double edge = std::min(0.0004, 0.2 * r);
  return std::clamp((r - std::sqrt(d2)) / edge + 0.5, 0.0, 1.0);
}

// Trilinear value noise in [-1, 1] with smooth weights.
double ValueNoise(const Eigen::Vector3d& q, double cell, uint32_t layer) {
  const Eigen::Vector3d s = q / cell;
  const int32_t i = static_cast<int32_t>(std::floor(s[0]));
  const int32_t j = static_cast<int32_t>(std::floor(s[1]));
  const int32_t k = static_cast<int32_t>(std::floor(s[2]));
  const double fx = SmoothStep(s[0] - i), fy = SmoothStep(s[1] - j), fz = SmoothStep(s[2] - k);
  double sum = 0.0;
  for (int c = 0; c < 8; ++c) {
    const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
    const double wgt = (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy) * (dz ? fz : 1 - fz);
    sum += wgt * (2.0 * Unit(CellHash(i + dx, j + dy, k + dz, layer)) - 1.0);
  }
  return sum;
}

}  // namespace

Eigen::Vector3f SolidTexture(const Eigen::Vector3d& p, const Texture& texture) {
  // A generic rotation and a seed-dependent offset keep planar charts from slicing the cell
  // lattice along its own planes (which would miss every dot).
  static const Eigen::Matrix3d kTilt =
      (Eigen::AngleAxisd(0.61, Eigen::Vector3d(0.3, 0.8, 0.52).normalized()) *
       Eigen::AngleAxisd(0.37, Eigen::Vector3d::UnitZ()))
          .toRotationMatrix();
  const uint32_t s = Mix32(texture.seed * 0x27d4eb2du + 0x165667b1u);
  const bool muted = texture.muted;
  const Eigen::Vector3d offset(Unit(Mix32(s + 11)), Unit(Mix32(s + 12)), Unit(Mix32(s + 13)));
  const Eigen::Vector3d q = kTilt * p + offset;

  const double base_cell = 0.045;
  const Eigen::Vector3i bc(static_cast<int>(std::floor(q[0] / base_cell)), static_cast<int>(std::floor(q[1] / base_cell)),
                           static_cast<int>(std::floor(q[2] / base_cell)));
  Eigen::Vector3f color = PaletteColor(CellHash(bc[0], bc[1], bc[2], s ^ 0x1u), muted);

  uint32_t h = 0;
  double a = DotCoverage(q, 0.018, s ^ 0x2u, 0.75, &h);
  if (a > 0.0) color += float(a) * (ContrastingColor(Mix32(h + 9), color, muted) - color);
  a = DotCoverage(q, 0.007, s ^ 0x3u, 0.6, &h);
  if (a > 0.0) color += float(a) * (ContrastingColor(Mix32(h + 9), color, muted) - color);

  const float grain = float(18.0 * ValueNoise(q, 0.005, s ^ 0x4u));
  for (int c = 0; c < 3; ++c) color[c] = std::clamp(color[c] + grain, 0.f, 255.f);
  return color;
}

uint64_t HashKey(uint64_t a, uint64_t b, uint64_t c) {
  auto split_mix = [](uint64_t z) {
    z += 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  };
  return split_mix(split_mix(split_mix(a) ^ b) ^ c);
}

double UniformFromKey(uint64_t key) { return (key >> 11) * (1.0 / 9007199254740992.0); }

}  // namespace vd::synthetic_internal
