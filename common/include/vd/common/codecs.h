#pragma once
// Lossless depth codecs, JPEG colour, and the Draco mesh codec. Every decoder checks sizes,
// encodings and lengths and returns a clear error on truncated, oversized or random bytes.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "vd/common/mesh.h"
#include "vd/common/status.h"

namespace vd {

// Values match vdeform::rgbd_frame_t::DEPTH_*.
enum class DepthEncoding : int8_t { kInvalid = -1, kRaw16 = 0, kPng16 = 1, kRvl = 2 };
// Values match vdeform::rgbd_frame_t::COLOR_*.
enum class ColorEncoding : int8_t { kInvalid = -1, kNone = 0, kRawBgr8 = 1, kJpeg = 2 };

StatusOr<DepthEncoding> ParseDepthEncoding(const std::string& name);  // "raw", "png", "rvl"
StatusOr<ColorEncoding> ParseColorEncoding(const std::string& name);  // "none", "raw", "jpeg"
const char* DepthEncodingName(DepthEncoding e);
const char* ColorEncodingName(ColorEncoding e);

// depth: CV_16UC1. Lossless for every encoding.
StatusOr<std::vector<uint8_t>> EncodeDepth(const cv::Mat& depth, DepthEncoding encoding);
// Returns a CV_16UC1 image of exactly width x height or an error.
StatusOr<cv::Mat> DecodeDepth(const uint8_t* data, size_t size, DepthEncoding encoding, int width, int height);

// colour: CV_8UC3 BGR. jpeg_quality in [1, 100].
StatusOr<std::vector<uint8_t>> EncodeColor(const cv::Mat& color, ColorEncoding encoding, int jpeg_quality = 90);
// Returns a CV_8UC3 image of exactly width x height (empty Mat for kNone) or an error.
StatusOr<cv::Mat> DecodeColor(const uint8_t* data, size_t size, ColorEncoding encoding, int width, int height);

struct DracoOptions {
  // Quantisation bits for positions; 14 bits over a 1 m box is ~0.06 mm.
  int position_bits = 14;
  // Draco speed 0 (smallest) .. 10 (fastest); 7 measured 17 ms for 100k triangles.
  int speed = 7;
  // Normals cost bytes and the viewer can recompute them.
  bool include_normals = false;
  Status Validate() const;
};

// Largest coordinate magnitude and extent EncodeMeshDraco accepts (far beyond any scene in metres,
// far enough below FLT_MAX that quantisation cannot overflow).
inline constexpr float kMaxDracoCoordinate = 1e30f;
// Unique id of the GENERIC attribute carrying TriangleMesh::canonical (x, y, z, quantised like the
// positions); a decoder that does not know it ignores it (Debian's draco_decoder does).
inline constexpr uint32_t kDracoCanonicalId = 3;
StatusOr<std::vector<uint8_t>> EncodeMeshDraco(const TriangleMesh& mesh, const DracoOptions& options = {});
StatusOr<TriangleMesh> DecodeMeshDraco(const uint8_t* data, size_t size);

// Binary little-endian PLY: float xyz, optional float normals, uchar rgb, int32 faces.
Status WritePly(const std::string& path, const TriangleMesh& mesh);
StatusOr<std::vector<uint8_t>> EncodePly(const TriangleMesh& mesh);
// Reads binary little-endian and ASCII PLY with float/double xyz, optional normals and colour.
StatusOr<TriangleMesh> ReadPly(const std::string& path);
StatusOr<TriangleMesh> DecodePly(const uint8_t* data, size_t size);

}  // namespace vd
