#pragma once
// CPU rasteriser for the viewer: z-buffered triangles, per-vertex colour, Lambert shading with a
// headlight, seen from the live camera (the mesh is in camera coordinates, the camera at the
// origin looking along +z, y down) with intrinsics fitted to the mesh's projection. Needs no
// display and no GPU, so headless PNGs and the window share one image.
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "vd/common/camera.h"
#include "vd/common/mesh.h"
#include "vd/common/status.h"

namespace vd {

// How surface points are coloured.
enum class ColorMode {
  // Position in the canonical pose, normalised to the canonical bounding box (VolumeDeform
  // Fig. 8); falls back to kVertex when no canonical mesh of the same frame is known.
  kCanonical = 0,
  // The mesh's own per-vertex colour (grey when it has none).
  kVertex = 1,
  // Uniform grey: shape only.
  kShade = 2,
};
const char* ColorModeName(ColorMode mode);
// "canonical", "vertex" or "shade".
StatusOr<ColorMode> ParseColorMode(const std::string& name);
// kCanonical -> kVertex -> kShade -> kCanonical (the window's colour key).
ColorMode NextColorMode(ColorMode mode);

struct RenderOptions {
  // Image size in pixels; 16..8192 keeps the buffers reasonable.
  int width = 640;
  int height = 480;
  // Fraction of the image left free on each side when the intrinsics are fitted to the mesh.
  float margin = 0.05f;
  // Light that faces seen edge-on still get, so silhouettes stay visible.
  float ambient = 0.2f;
  // BGR background; tests count pixels that differ from it.
  cv::Vec3b background = cv::Vec3b(40, 32, 28);
  Status Validate() const;
};

// User navigation on top of the live camera's viewpoint: an orbit about the mesh's bounding-box
// centre and a zoom of the fitted focal length. The defaults are the live camera itself.
struct ViewParams {
  // Rotation about the image's vertical axis through the centre, radians.
  float yaw = 0.f;
  // Rotation about the image's horizontal axis through the centre, radians.
  float pitch = 0.f;
  // Focal length multiplier; > 1 magnifies.
  float zoom = 1.f;
};

struct RenderResult {
  // CV_8UC3 BGR.
  cv::Mat image;
  // CV_32FC1 camera-space depth of the visible surface, metres; 0 where nothing was drawn.
  cv::Mat depth;
  // Pixels that show the mesh.
  int64_t covered_pixels = 0;
  // The intrinsics the image was rendered with (fitted to the mesh's projection).
  Intrinsics intrinsics;
  // How far the viewpoint moved back along +z (0 when the live camera saw the mesh in front).
  float eye_offset_z = 0.f;
};

// Renders `mesh` with `rgb` (3 bytes per vertex, r g b; empty: uniform grey). An empty mesh
// gives a background-only image. Invalid meshes or colour counts are refused.
StatusOr<RenderResult> RenderMesh(const TriangleMesh& mesh, const std::vector<uint8_t>& rgb,
                                  const RenderOptions& options, const ViewParams& view = {});

// Colours each vertex by its position normalised to the mesh's bounding box: r, g, b = x, y, z
// mapped to 0..255 (axes of zero extent map to the middle, 128).
std::vector<uint8_t> CanonicalColors(const TriangleMesh& canonical);

// The colours a live mesh is drawn with, and which source they came from.
struct VertexColors {
  std::vector<uint8_t> rgb;
  // The mode actually used (kVertex when kCanonical was asked for but had no match).
  ColorMode used = ColorMode::kVertex;
};

// Picks the colours for `live` (frame live_seq) in `mode`. In kCanonical: the canonical positions
// the live mesh carries itself (TriangleMesh::canonical, every frame from servers since issue 16),
// else canonical / canonical_seq: the latest canonical mesh (null if none), used only when its seq
// equals live_seq and its vertex count equals the live mesh's, because only then do vertex i of
// both meshes correspond; else the vertex colours.
VertexColors SelectVertexColors(const TriangleMesh& live, int64_t live_seq, const TriangleMesh* canonical,
                                int64_t canonical_seq, ColorMode mode);

}  // namespace vd
