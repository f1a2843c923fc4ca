#include "vd/common/camera.h"

#include <cmath>
#include <fstream>
#include <sstream>
#include <vector>

namespace vd {

Status Intrinsics::Validate() const {
  auto bad = [](const char* field, double v, const char* bound) {
    std::ostringstream os;
    os << "intrinsics." << field << " = " << v << " violates " << bound;
    return InvalidArgument(os.str());
  };
  if (!(width > 0 && width <= 8192)) return bad("width", width, "0 < width <= 8192");
  if (!(height > 0 && height <= 8192)) return bad("height", height, "0 < height <= 8192");
  if (!std::isfinite(fx) || !(fx > 1.f && fx < 1e5f)) return bad("fx", fx, "1 < fx < 1e5");
  if (!std::isfinite(fy) || !(fy > 1.f && fy < 1e5f)) return bad("fy", fy, "1 < fy < 1e5");
  // The principal point may sit off-centre but not far outside the image.
  if (!std::isfinite(cx) || !(cx > -0.5f * width && cx < 1.5f * width))
    return bad("cx", cx, "-width/2 < cx < 1.5*width");
  if (!std::isfinite(cy) || !(cy > -0.5f * height && cy < 1.5f * height))
    return bad("cy", cy, "-height/2 < cy < 1.5*height");
  return Status::Ok();
}

Intrinsics Intrinsics::Scaled(int level) const {
  Intrinsics k = *this;
  for (int i = 0; i < level; ++i) {
    k.fx *= 0.5f;
    k.fy *= 0.5f;
    // Pixel centres at integer coordinates: x' = (x + 0.5) / 2 - 0.5.
    k.cx = (k.cx + 0.5f) * 0.5f - 0.5f;
    k.cy = (k.cy + 0.5f) * 0.5f - 0.5f;
    k.width /= 2;
    k.height /= 2;
  }
  return k;
}

std::string Intrinsics::ToString() const {
  std::ostringstream os;
  os << "fx=" << fx << " fy=" << fy << " cx=" << cx << " cy=" << cy << " " << width << "x" << height;
  return os.str();
}

StatusOr<Intrinsics> ParseIntrinsicsFlag(const std::string& text, int width, int height) {
  std::vector<float> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      size_t used = 0;
      v.push_back(std::stof(item, &used));
      if (used != item.size()) return InvalidArgument("--intrinsics: '" + item + "' is not a number");
    } catch (const std::exception&) {
      return InvalidArgument("--intrinsics: '" + item + "' is not a number");
    }
  }
  if (v.size() != 4) return InvalidArgument("--intrinsics expects fx,fy,cx,cy (4 numbers), got '" + text + "'");
  Intrinsics k;
  k.fx = v[0];
  k.fy = v[1];
  k.cx = v[2];
  k.cy = v[3];
  k.width = width;
  k.height = height;
  return k;
}

StatusOr<Intrinsics> LoadIntrinsicsFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) return NotFound("cannot open intrinsics file '" + path + "'");
  std::vector<double> v;
  std::string tok;
  while (in >> tok) {
    try {
      size_t used = 0;
      double d = std::stod(tok, &used);
      if (used != tok.size()) return InvalidArgument("intrinsics file '" + path + "': bad number '" + tok + "'");
      v.push_back(d);
    } catch (const std::exception&) {
      return InvalidArgument("intrinsics file '" + path + "': bad number '" + tok + "'");
    }
    if (v.size() > 64) break;
  }
  Intrinsics k;
  if (v.size() == 9 || v.size() == 16) {
    const int n = v.size() == 9 ? 3 : 4;
    k.fx = static_cast<float>(v[0]);
    k.cx = static_cast<float>(v[2]);
    k.fy = static_cast<float>(v[n + 1]);
    k.cy = static_cast<float>(v[n + 2]);
  } else if (v.size() == 4) {
    k.fx = static_cast<float>(v[0]);
    k.fy = static_cast<float>(v[1]);
    k.cx = static_cast<float>(v[2]);
    k.cy = static_cast<float>(v[3]);
  } else {
    return InvalidArgument("intrinsics file '" + path + "': expected a 3x3 or 4x4 matrix or 'fx fy cx cy', found " +
                           std::to_string(v.size()) + " numbers");
  }
  return k;
}

}  // namespace vd
