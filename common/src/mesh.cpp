#include "vd/common/mesh.h"

#include <algorithm>
#include <cmath>

namespace vd {

Status TriangleMesh::Validate() const {
  if (positions.size() % 3) return InvalidArgument("mesh positions not a multiple of 3");
  if (triangles.size() % 3) return InvalidArgument("mesh triangle indices not a multiple of 3");
  if (!colors.empty() && colors.size() != positions.size())
    return InvalidArgument("mesh has " + std::to_string(colors.size() / 3) + " colours for " +
                           std::to_string(num_vertices()) + " vertices");
  if (!normals.empty() && normals.size() != positions.size())
    return InvalidArgument("mesh normal count differs from vertex count");
  if (!canonical.empty() && canonical.size() != positions.size())
    return InvalidArgument("mesh has " + std::to_string(canonical.size() / 3) + " canonical positions for " +
                           std::to_string(num_vertices()) + " vertices");
  const int32_t n = static_cast<int32_t>(num_vertices());
  for (int32_t idx : triangles)
    if (idx < 0 || idx >= n) return OutOfRange("mesh triangle index " + std::to_string(idx) + " out of range");
  for (float p : positions)
    if (!std::isfinite(p)) return InvalidArgument("mesh has a non-finite vertex coordinate");
  for (float p : canonical)
    if (!std::isfinite(p)) return InvalidArgument("mesh has a non-finite canonical coordinate");
  return Status::Ok();
}

void TriangleMesh::Bounds(float mn[3], float mx[3]) const {
  for (int a = 0; a < 3; ++a) mn[a] = mx[a] = 0.f;
  if (positions.empty()) return;
  for (int a = 0; a < 3; ++a) mn[a] = mx[a] = positions[a];
  for (size_t i = 0; i < positions.size(); i += 3)
    for (int a = 0; a < 3; ++a) {
      mn[a] = std::min(mn[a], positions[i + a]);
      mx[a] = std::max(mx[a], positions[i + a]);
    }
}

}  // namespace vd
