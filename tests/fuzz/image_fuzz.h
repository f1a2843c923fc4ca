#pragma once
// The depth and colour decoder targets: a declared size (fuzz_util.h) and the encoded bytes.
#include "fuzz_util.h"
#include "vd/common/codecs.h"

namespace vd::fuzz {

// Every depth codec is lossless: an accepted stream is an image of the declared size that encodes
// and decodes back to itself. RAW16 is a bijection, so its bytes must come back unchanged.
inline int FuzzDepth(DepthEncoding encoding, const uint8_t* data, size_t size) {
  SizedInput in;
  if (!TakeSizePrefix(data, size, &in)) return 0;
  auto depth = DecodeDepth(in.data, in.size, encoding, in.width, in.height);
  if (!depth.ok()) return 0;
  VD_FUZZ_CHECK(depth->type() == CV_16UC1);
  VD_FUZZ_CHECK(depth->cols == in.width && depth->rows == in.height);
  auto encoded = EncodeDepth(*depth, encoding);
  VD_FUZZ_CHECK(encoded.ok());
  if (encoding == DepthEncoding::kRaw16)
    VD_FUZZ_CHECK(encoded->size() == in.size && std::memcmp(encoded->data(), in.data, in.size) == 0);
  auto again = DecodeDepth(encoded->data(), encoded->size(), encoding, in.width, in.height);
  VD_FUZZ_CHECK(again.ok());
  VD_FUZZ_CHECK(SameImage(*depth, *again));
  return 0;
}

// An accepted colour stream is a BGR8 image of the declared size. Raw BGR8 round-trips byte for
// byte; JPEG is lossy, so its re-encoding must only decode again at the same size.
inline int FuzzColor(ColorEncoding encoding, const uint8_t* data, size_t size) {
  SizedInput in;
  if (!TakeSizePrefix(data, size, &in)) return 0;
  auto color = DecodeColor(in.data, in.size, encoding, in.width, in.height);
  if (!color.ok()) return 0;
  VD_FUZZ_CHECK(color->type() == CV_8UC3);
  VD_FUZZ_CHECK(color->cols == in.width && color->rows == in.height);
  auto encoded = EncodeColor(*color, encoding, 90);
  VD_FUZZ_CHECK(encoded.ok());
  if (encoding == ColorEncoding::kRawBgr8)
    VD_FUZZ_CHECK(encoded->size() == in.size && std::memcmp(encoded->data(), in.data, in.size) == 0);
  auto again = DecodeColor(encoded->data(), encoded->size(), encoding, in.width, in.height);
  VD_FUZZ_CHECK(again.ok());
  VD_FUZZ_CHECK(again->type() == CV_8UC3 && again->size() == color->size());
  if (encoding == ColorEncoding::kRawBgr8) VD_FUZZ_CHECK(SameImage(*color, *again));
  return 0;
}

}  // namespace vd::fuzz
