// Names and parsing of the depth and colour encodings.
#include "vd/common/codecs.h"

namespace vd {

StatusOr<DepthEncoding> ParseDepthEncoding(const std::string& name) {
  if (name == "raw") return DepthEncoding::kRaw16;
  if (name == "png") return DepthEncoding::kPng16;
  if (name == "rvl") return DepthEncoding::kRvl;
  return InvalidArgument("unknown depth encoding '" + name + "' (expected raw, png or rvl)");
}

StatusOr<ColorEncoding> ParseColorEncoding(const std::string& name) {
  if (name == "none") return ColorEncoding::kNone;
  if (name == "raw") return ColorEncoding::kRawBgr8;
  if (name == "jpeg") return ColorEncoding::kJpeg;
  return InvalidArgument("unknown colour encoding '" + name + "' (expected none, raw or jpeg)");
}

const char* DepthEncodingName(DepthEncoding e) {
  switch (e) {
    case DepthEncoding::kRaw16: return "raw";
    case DepthEncoding::kPng16: return "png";
    case DepthEncoding::kRvl: return "rvl";
    case DepthEncoding::kInvalid: break;
  }
  return "invalid";
}

const char* ColorEncodingName(ColorEncoding e) {
  switch (e) {
    case ColorEncoding::kNone: return "none";
    case ColorEncoding::kRawBgr8: return "raw";
    case ColorEncoding::kJpeg: return "jpeg";
    case ColorEncoding::kInvalid: break;
  }
  return "invalid";
}

}  // namespace vd
