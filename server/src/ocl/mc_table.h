#pragma once
// The marching-cubes triangle table, generated from first principles instead of copied: for each
// of the 256 sign configurations, the iso-contour on each cube face is traced (ambiguous faces
// separate the inside corners, a rule that depends only on the face, so neighbouring cells agree
// and the mesh is watertight), the face segments are chained into closed loops, and each loop is
// fanned into triangles oriented with the outward normal towards positive distance.
#include <array>
#include <cstdint>

namespace vd {

// Largest number of triangles a cell can produce under this table.
inline constexpr int kMcMaxTrianglesPerCell = 5;

struct McTable {
  // Edge ids (see marching_cubes.h) of the triangles of each cube index, 3 per triangle, -1 after.
  std::array<int8_t, 256 * 16> triangles;
  // Number of triangles per cube index.
  std::array<uint8_t, 256> counts;
};

// Built once on first use; thread-safe.
const McTable& GetMcTable();

}  // namespace vd
