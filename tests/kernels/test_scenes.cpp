#include "test_scenes.h"

#include <cmath>
#include <cstdlib>
#include <memory>

namespace vd::test {

StatusOr<std::unique_ptr<ocl::Context>> ContextWithLanes(const ocl::Context& like, const char* lanes) {
  setenv("VD_LANES", lanes, 1);
  auto ctx = ocl::Context::Create(like.device().device_name);
  unsetenv("VD_LANES");
  return ctx;
}

ocl::Context* SharedContext(std::string* error) {
  static std::string failure;
  static std::unique_ptr<ocl::Context> ctx = [] {
    auto devices = ocl::ListDevices();
    if (!devices.ok() || devices->empty()) return std::unique_ptr<ocl::Context>();
    auto c = ocl::Context::Create(std::getenv("VD_TEST_DEVICE") ? std::getenv("VD_TEST_DEVICE") : "");
    if (!c.ok()) {
      failure = c.status().ToString();
      return std::unique_ptr<ocl::Context>();
    }
    return std::move(c).value();
  }();
  *error = failure;
  return ctx.get();
}

VdCamera TestCamera(int width, int height) {
  VdCamera c{};
  c.width = width;
  c.height = height;
  c.fx = c.fy = 0.8f * width;
  c.cx = 0.5f * (width - 1);
  c.cy = 0.5f * (height - 1);
  return c;
}

VdPose IdentityPose() {
  VdPose p;
  p.r0 = VD_F4(1, 0, 0, 0);
  p.r1 = VD_F4(0, 1, 0, 0);
  p.r2 = VD_F4(0, 0, 1, 0);
  return p;
}

std::vector<float> SphereDepth(const VdCamera& cam, float cz, float r, float wall_z) {
  std::vector<float> d(static_cast<size_t>(cam.width) * cam.height, 0.f);
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      // Ray direction (x', y', 1); intersect |t * dir - (0, 0, cz)| = r.
      const double dx = (x - cam.cx) / cam.fx, dy = (y - cam.cy) / cam.fy;
      const double a = dx * dx + dy * dy + 1.0, b = -2.0 * cz, c = double(cz) * cz - double(r) * r;
      const double disc = b * b - 4 * a * c;
      double z = wall_z;
      if (disc >= 0) z = std::min<double>(wall_z, (-b - std::sqrt(disc)) / (2 * a));
      // Holes: a deterministic sparse pattern of invalid pixels.
      if ((x * 7 + y * 13) % 97 == 0) z = 0;
      d[static_cast<size_t>(y) * cam.width + x] = float(z);
    }
  }
  return d;
}

std::vector<uint16_t> SphereDepthRaw(const VdCamera& cam, float cz, float r, float wall_z) {
  auto d = SphereDepth(cam, cz, r, wall_z);
  std::vector<uint16_t> raw(d.size());
  for (size_t i = 0; i < d.size(); ++i) raw[i] = static_cast<uint16_t>(std::lround(d[i] * 1000.f));
  return raw;
}

std::vector<uint32_t> TestColors(const VdCamera& cam) {
  std::vector<uint32_t> c(static_cast<size_t>(cam.width) * cam.height);
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x)
      c[static_cast<size_t>(y) * cam.width + x] =
          vd_pack_rgba(float((x * 5) % 256), float((y * 3) % 256), float(((x + y) * 2) % 256), 255.f);
  return c;
}

std::vector<float> Flatten(const std::vector<vd_float4>& v) {
  std::vector<float> out;
  out.reserve(4 * v.size());
  for (const auto& f : v) out.insert(out.end(), {f.x, f.y, f.z, f.w});
  return out;
}

::testing::AssertionResult AllClose(const std::vector<float>& a, const std::vector<float>& b, float atol, float rtol) {
  if (a.size() != b.size()) return ::testing::AssertionFailure() << "sizes " << a.size() << " vs " << b.size();
  size_t bad = 0, worst = 0;
  double worst_err = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    const bool both_nan = std::isnan(a[i]) && std::isnan(b[i]);
    const double err = std::fabs(double(a[i]) - b[i]);
    if (!both_nan && !(err <= atol + rtol * std::fabs(b[i]))) {
      ++bad;
      if (!(err <= worst_err)) {
        worst_err = err;
        worst = i;
      }
    }
  }
  if (bad == 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << bad << " of " << a.size() << " differ; worst at " << worst << ": " << a[worst]
                                       << " vs " << b[worst];
}

}  // namespace vd::test
