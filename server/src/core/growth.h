#pragma once
// Growth of a deforming model on the bricks (issue 17; docs/SPARSE_VOLUME.md "Growth"). In the
// non-rigid path only the active set is fused, and the active set follows the fused surface: it
// grows by its one-ring, about a voxel a frame. Surface that enters the view faster (a part of
// the object that was out of view, a new object) would never be fused. PlanGrowth finds the depth
// the live model does not explain, maps it into the canonical space through the motion of the
// nearest rendered surface (its triangle's rotation and translation; none where no surface is
// near: a new object is taken where the camera sees it), and names the bricks it falls in; the
// engine allocates those that are missing, starts their field at that motion and fuses them once
// through it, after which they are part of the surface like any other.
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "shared/vd_types.h"

namespace vd {

struct GrowthParams {
  // Depth is sampled every `stride` pixels in x and y (the bricks are 8 voxels a side: a coarse
  // sampling finds them all).
  int stride = 4;
  // A sample is explained when the surface rendered at its pixel lies within this many truncation
  // distances of it along the ray.
  float explained_truncations = 2.f;
  // Samples farther than this (in samples) from any rendered surface take no displacement.
  int search = 16;
  // Samples nearer than this (in samples) to the rendered surface are its edge, not new surface.
  int min_gap = 3;
  // Samples a brick needs before it is grown (a lone noisy pixel grows nothing).
  int min_samples = 4;
  // Unexplained samples a frame needs before anything grows: a small patch (a part turning into
  // view at the surface's edge) is taken in by the active set's one-ring within a few frames, and
  // its canonical place, from a displacement without the field's rotation, is the less accurate;
  // a region entering faster than the ring grows is larger.
  int min_frame_samples = 16;
  // Bricks grown at most per frame (bounds the frame's cost when much enters at once).
  int max_bricks = 512;
};

struct GrowthBrick {
  uint32_t key = 0;
  // The rigid motion (canonical world metres -> deformed world metres) of the rendered triangle
  // nearest to the first sample that named it.
  VdPose motion{};
  int samples = 0;
};

// depth: the frame's raw depth (CV_16UC1, 0 = none), inv_scale metres per unit, samples outside
// [min_depth, max_depth] ignored. ids: the rendered live model's triangle per pixel
// (VD_RASTER_EMPTY: none) at cam_to_world; tris its faces; deformed (world metres) and grid
// (canonical grid units) its vertices. The bricks (keys, global grid of voxel_size) that
// unexplained samples fall in, most samples first, at most params.max_bricks.
// The rigid motion of a triangle from its canonical corners c (metres) to its deformed ones d: the
// rotation of the frame of its first edge and normal, and the translation of its first corner;
// only the translation for a degenerate triangle.
VdPose TriangleMotion(const vd_float4 c[3], const vd_float4 d[3]);

std::vector<GrowthBrick> PlanGrowth(const cv::Mat& depth, float inv_scale, float min_depth, float max_depth,
                                    const VdCamera& cam, const VdPose& cam_to_world, const uint32_t* ids,
                                    const int32_t* tris, size_t num_triangles, const vd_float4* deformed,
                                    const vd_float4* grid, float voxel_size, float truncation,
                                    const GrowthParams& params);

}  // namespace vd
