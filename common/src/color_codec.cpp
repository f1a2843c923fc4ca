// Colour codecs: none, raw BGR8, JPEG. The JPEG frame header is checked before decoding so a
// stream declaring a huge image is refused without allocating for it.
#include <algorithm>
#include <exception>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "vd/common/codecs.h"

namespace vd {
namespace {

// Same bound as Intrinsics::Validate.
constexpr int kMaxSide = 8192;

std::string SizeText(int width, int height) { return std::to_string(width) + "x" + std::to_string(height); }

// Walks the JPEG marker segments up to the first start-of-frame and checks its size and
// component count against the declared image.
Status CheckJpegHeader(const uint8_t* d, size_t n, int width, int height) {
  if (n < 4 || d[0] != 0xFF || d[1] != 0xD8) return DataLoss("colour JPEG: missing start-of-image marker");
  size_t pos = 2;
  while (pos + 4 <= n) {
    if (d[pos] != 0xFF) return DataLoss("colour JPEG: expected a marker at byte " + std::to_string(pos));
    const uint8_t marker = d[pos + 1];
    // Fill byte before a marker.
    if (marker == 0xFF) {
      ++pos;
      continue;
    }
    // Markers without a length field (TEM, RSTn).
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) {
      pos += 2;
      continue;
    }
    if (marker == 0xD8 || marker == 0xD9 || marker == 0xDA)
      return DataLoss("colour JPEG: no frame header before the image data");
    const size_t length = static_cast<size_t>(d[pos + 2]) << 8 | d[pos + 3];
    if (length < 2 || length > n - pos - 2) return DataLoss("colour JPEG: segment overruns the buffer");
    const bool start_of_frame = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
    if (start_of_frame) {
      if (length < 8) return DataLoss("colour JPEG: short frame header");
      const int jpeg_height = d[pos + 5] << 8 | d[pos + 6];
      const int jpeg_width = d[pos + 7] << 8 | d[pos + 8];
      const int components = d[pos + 9];
      if (jpeg_width != width || jpeg_height != height)
        return DataLoss("colour JPEG is " + SizeText(jpeg_width, jpeg_height) + ", expected " + SizeText(width, height));
      if (components != 3 && components != 1)
        return DataLoss("colour JPEG has " + std::to_string(components) + " components, expected 3 (or 1)");
      return Status::Ok();
    }
    pos += 2 + length;
  }
  return DataLoss("colour JPEG ends before its frame header");
}

StatusOr<cv::Mat> DecodeJpeg(const uint8_t* data, size_t size, int width, int height) {
  VD_RETURN_IF_ERROR(CheckJpegHeader(data, size, width, height));
  if (size > static_cast<size_t>(INT32_MAX)) return DataLoss("colour JPEG larger than 2 GB");
  cv::Mat color;
  try {
    const cv::Mat buf(1, static_cast<int>(size), CV_8UC1, const_cast<uint8_t*>(data));
    // EXIF orientation would rotate the image away from the depth grid.
    color = cv::imdecode(buf, cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
  } catch (const std::exception& e) {
    return DataLoss(std::string("colour JPEG decoding failed: ") + e.what());
  }
  if (color.empty()) return DataLoss("colour JPEG could not be decoded (" + std::to_string(size) + " bytes)");
  if (color.type() != CV_8UC3 || color.cols != width || color.rows != height)
    return DataLoss("colour JPEG decoded to " + SizeText(color.cols, color.rows) + " with " +
                    std::to_string(color.channels()) + " channels, expected " + SizeText(width, height) + " BGR");
  return color;
}

StatusOr<cv::Mat> DecodeRawBgr8(const uint8_t* data, size_t size, int width, int height) {
  const size_t expected = static_cast<size_t>(width) * height * 3;
  if (size != expected)
    return DataLoss("raw BGR8 colour has " + std::to_string(size) + " bytes, " + SizeText(width, height) + " needs " +
                    std::to_string(expected));
  cv::Mat color(height, width, CV_8UC3);
  for (int y = 0; y < height; ++y)
    std::copy(data + static_cast<size_t>(y) * width * 3, data + static_cast<size_t>(y + 1) * width * 3, color.ptr<uint8_t>(y));
  return color;
}

}  // namespace

StatusOr<std::vector<uint8_t>> EncodeColor(const cv::Mat& color, ColorEncoding encoding, int jpeg_quality) {
  if (encoding == ColorEncoding::kNone) return std::vector<uint8_t>();
  if (encoding != ColorEncoding::kRawBgr8 && encoding != ColorEncoding::kJpeg)
    return InvalidArgument("cannot encode colour with encoding " + std::to_string(static_cast<int>(encoding)));
  if (color.empty()) return InvalidArgument("colour image is empty");
  if (color.type() != CV_8UC3) return InvalidArgument("colour image must be CV_8UC3");
  if (color.cols > kMaxSide || color.rows > kMaxSide)
    return InvalidArgument("colour size " + SizeText(color.cols, color.rows) + " exceeds " + std::to_string(kMaxSide));
  if (encoding == ColorEncoding::kRawBgr8) {
    std::vector<uint8_t> out(static_cast<size_t>(color.cols) * color.rows * 3);
    const size_t row_bytes = static_cast<size_t>(color.cols) * 3;
    for (int y = 0; y < color.rows; ++y) std::copy(color.ptr<uint8_t>(y), color.ptr<uint8_t>(y) + row_bytes, out.data() + y * row_bytes);
    return out;
  }
  if (jpeg_quality < 1 || jpeg_quality > 100)
    return InvalidArgument("jpeg_quality = " + std::to_string(jpeg_quality) + " violates 1 <= jpeg_quality <= 100");
  std::vector<uint8_t> out;
  try {
    if (!cv::imencode(".jpg", color, out, {cv::IMWRITE_JPEG_QUALITY, jpeg_quality}))
      return Internal("OpenCV could not JPEG-encode the colour image");
  } catch (const std::exception& e) {
    return Internal(std::string("JPEG encoding failed: ") + e.what());
  }
  return out;
}

StatusOr<cv::Mat> DecodeColor(const uint8_t* data, size_t size, ColorEncoding encoding, int width, int height) {
  if (encoding == ColorEncoding::kNone) {
    if (size != 0) return DataLoss("colour encoding NONE carries " + std::to_string(size) + " bytes");
    return cv::Mat();
  }
  if (width <= 0 || width > kMaxSide || height <= 0 || height > kMaxSide)
    return InvalidArgument("colour size " + SizeText(width, height) + " violates 0 < width, height <= " +
                           std::to_string(kMaxSide));
  if (data == nullptr && size != 0) return InvalidArgument("colour data is null");
  static const uint8_t kEmpty = 0;
  if (data == nullptr) data = &kEmpty;
  try {
    switch (encoding) {
      case ColorEncoding::kRawBgr8: return DecodeRawBgr8(data, size, width, height);
      case ColorEncoding::kJpeg: return DecodeJpeg(data, size, width, height);
      case ColorEncoding::kNone:
      case ColorEncoding::kInvalid: break;
    }
  } catch (const std::exception& e) {
    return Internal(std::string("colour decoding failed: ") + e.what());
  }
  return InvalidArgument("unknown colour encoding " + std::to_string(static_cast<int>(encoding)));
}

}  // namespace vd
