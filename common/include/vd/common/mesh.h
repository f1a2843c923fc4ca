#pragma once
// An indexed triangle mesh with per-vertex colour (and optional normals), in metres.
#include <cstdint>
#include <vector>

#include "vd/common/status.h"

namespace vd {

struct TriangleMesh {
  // x, y, z per vertex.
  std::vector<float> positions;
  // r, g, b per vertex; empty or 3 per vertex.
  std::vector<uint8_t> colors;
  // nx, ny, nz per vertex; empty or 3 per vertex.
  std::vector<float> normals;
  // x, y, z per vertex of the same surface point in the canonical pose (a live mesh's colouring by
  // canonical position, VolumeDeform Fig. 8); empty or 3 per vertex.
  std::vector<float> canonical;
  // Three vertex indices per triangle, counter-clockwise seen from outside.
  std::vector<int32_t> triangles;

  size_t num_vertices() const { return positions.size() / 3; }
  size_t num_triangles() const { return triangles.size() / 3; }
  bool empty() const { return triangles.empty(); }
  // Sizes consistent, indices in range, coordinates finite.
  Status Validate() const;
  // Axis-aligned bounds; zeros for an empty mesh.
  void Bounds(float min_xyz[3], float max_xyz[3]) const;
};

}  // namespace vd
