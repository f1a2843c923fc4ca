// Lossless depth codecs: raw little-endian uint16, 16-bit PNG, and RVL (A. D. Wilson, "Fast
// Lossless Depth Image Compression", ISS 2017). Every decoder checks the declared size first and
// bounds every read and write, so truncated, oversized or random bytes give an error Status.
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "vd/common/codecs.h"

namespace vd {
namespace {

// Same bound as Intrinsics::Validate: no sensor we support is larger, and it caps allocations.
constexpr int kMaxSide = 8192;
// "RVL1": identifies our RVL stream and its version.
constexpr uint8_t kRvlMagic[4] = {'R', 'V', 'L', '1'};
// Magic, width, height.
constexpr size_t kRvlHeaderBytes = 12;

Status CheckDeclaredSize(int width, int height) {
  if (width <= 0 || width > kMaxSide || height <= 0 || height > kMaxSide)
    return InvalidArgument("depth size " + std::to_string(width) + "x" + std::to_string(height) +
                           " violates 0 < width, height <= " + std::to_string(kMaxSide));
  return Status::Ok();
}

Status CheckDepthImage(const cv::Mat& depth) {
  if (depth.empty()) return InvalidArgument("depth image is empty");
  if (depth.type() != CV_16UC1) return InvalidArgument("depth image must be CV_16UC1");
  return CheckDeclaredSize(depth.cols, depth.rows);
}

void PutLe32(uint32_t v, uint8_t* p) {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
  p[2] = static_cast<uint8_t>(v >> 16);
  p[3] = static_cast<uint8_t>(v >> 24);
}

uint32_t GetLe32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | static_cast<uint32_t>(p[1]) << 8 | static_cast<uint32_t>(p[2]) << 16 |
         static_cast<uint32_t>(p[3]) << 24;
}

uint32_t GetBe32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) << 24 | static_cast<uint32_t>(p[1]) << 16 | static_cast<uint32_t>(p[2]) << 8 |
         static_cast<uint32_t>(p[3]);
}

// ---- RAW16 ----

std::vector<uint8_t> EncodeRaw16(const cv::Mat& depth) {
  std::vector<uint8_t> out(static_cast<size_t>(depth.cols) * depth.rows * 2);
  uint8_t* dst = out.data();
  for (int y = 0; y < depth.rows; ++y) {
    const uint16_t* src = depth.ptr<uint16_t>(y);
    for (int x = 0; x < depth.cols; ++x) {
      *dst++ = static_cast<uint8_t>(src[x]);
      *dst++ = static_cast<uint8_t>(src[x] >> 8);
    }
  }
  return out;
}

StatusOr<cv::Mat> DecodeRaw16(const uint8_t* data, size_t size, int width, int height) {
  const size_t expected = static_cast<size_t>(width) * height * 2;
  if (size != expected)
    return DataLoss("RAW16 depth has " + std::to_string(size) + " bytes, " + std::to_string(width) + "x" +
                    std::to_string(height) + " needs " + std::to_string(expected));
  cv::Mat depth(height, width, CV_16UC1);
  const uint8_t* src = data;
  for (int y = 0; y < height; ++y) {
    uint16_t* dst = depth.ptr<uint16_t>(y);
    for (int x = 0; x < width; ++x, src += 2) dst[x] = static_cast<uint16_t>(src[0] | src[1] << 8);
  }
  return depth;
}

// ---- PNG16 ----

StatusOr<std::vector<uint8_t>> EncodePng16(const cv::Mat& depth) {
  std::vector<uint8_t> out;
  try {
    if (!cv::imencode(".png", depth, out)) return Internal("OpenCV could not PNG-encode the depth image");
  } catch (const std::exception& e) {
    return Internal(std::string("PNG encoding failed: ") + e.what());
  }
  return out;
}

// Checks the PNG signature and IHDR before handing the bytes to libpng, so a stream declaring a
// huge image cannot make the decoder allocate for it.
Status CheckPngHeader(const uint8_t* data, size_t size, int width, int height) {
  static const uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  if (size < 33 || std::memcmp(data, kSignature, 8) != 0) return DataLoss("depth PNG: missing PNG signature");
  if (GetBe32(data + 8) != 13 || std::memcmp(data + 12, "IHDR", 4) != 0) return DataLoss("depth PNG: no IHDR chunk");
  const uint32_t png_width = GetBe32(data + 16);
  const uint32_t png_height = GetBe32(data + 20);
  if (png_width != static_cast<uint32_t>(width) || png_height != static_cast<uint32_t>(height))
    return DataLoss("depth PNG is " + std::to_string(png_width) + "x" + std::to_string(png_height) + ", expected " +
                    std::to_string(width) + "x" + std::to_string(height));
  if (data[24] != 16 || data[25] != 0)
    return DataLoss("depth PNG has bit depth " + std::to_string(data[24]) + " colour type " + std::to_string(data[25]) +
                    ", expected 16-bit greyscale");
  return Status::Ok();
}

StatusOr<cv::Mat> DecodePng16(const uint8_t* data, size_t size, int width, int height) {
  VD_RETURN_IF_ERROR(CheckPngHeader(data, size, width, height));
  if (size > static_cast<size_t>(INT32_MAX)) return DataLoss("depth PNG larger than 2 GB");
  cv::Mat depth;
  try {
    const cv::Mat buf(1, static_cast<int>(size), CV_8UC1, const_cast<uint8_t*>(data));
    depth = cv::imdecode(buf, cv::IMREAD_UNCHANGED);
  } catch (const std::exception& e) {
    return DataLoss(std::string("depth PNG decoding failed: ") + e.what());
  }
  if (depth.empty()) return DataLoss("depth PNG could not be decoded (" + std::to_string(size) + " bytes)");
  if (depth.type() != CV_16UC1 || depth.cols != width || depth.rows != height)
    return DataLoss("depth PNG decoded to " + std::to_string(depth.cols) + "x" + std::to_string(depth.rows) +
                    " type " + std::to_string(depth.type()) + ", expected CV_16UC1 " + std::to_string(width) + "x" +
                    std::to_string(height));
  return depth;
}

// ---- RVL ----
// Stream: magic, width, height (uint32 LE), then 32-bit little-endian words of 4-bit nibbles,
// first nibble in the high bits. The image alternates runs of zeros and of non-zeros; each run
// length, and each non-zero pixel's zig-zagged difference from the previous non-zero pixel, is a
// variable-length code of 3 data bits per nibble (least significant first, bit 3 = more follows).

class NibbleWriter {
 public:
  explicit NibbleWriter(std::vector<uint8_t>* out) : out_(out) {}
  void PutVle(uint32_t value) {
    do {
      uint32_t nibble = value & 7u;
      value >>= 3;
      if (value) nibble |= 8u;
      Put(nibble);
    } while (value);
  }
  void Flush() {
    if (count_ == 0) return;
    word_ <<= 4 * (8 - count_);
    Emit();
  }

 private:
  void Put(uint32_t nibble) {
    word_ = (word_ << 4) | nibble;
    if (++count_ == 8) Emit();
  }
  void Emit() {
    const size_t at = out_->size();
    out_->resize(at + 4);
    PutLe32(word_, out_->data() + at);
    word_ = 0;
    count_ = 0;
  }
  std::vector<uint8_t>* out_;
  uint32_t word_ = 0;
  int count_ = 0;
};

class NibbleReader {
 public:
  NibbleReader(const uint8_t* words, size_t num_words) : words_(words), num_words_(num_words) {}
  // False when the stream ends or a code is longer than any value the encoder writes.
  bool GetVle(uint32_t* value) {
    uint32_t v = 0;
    for (int shift = 0;; shift += 3) {
      // 10 nibbles carry 30 bits, more than any run length or difference we write.
      if (shift > 27) return false;
      uint32_t nibble;
      if (!Get(&nibble)) return false;
      v |= (nibble & 7u) << shift;
      if (!(nibble & 8u)) break;
    }
    *value = v;
    return true;
  }
  // True when every word was read and the padding of the last one is zero.
  bool AtCleanEnd() const { return next_ == num_words_ && word_ == 0; }

 private:
  bool Get(uint32_t* nibble) {
    if (left_ == 0) {
      if (next_ == num_words_) return false;
      word_ = GetLe32(words_ + 4 * next_++);
      left_ = 8;
    }
    *nibble = word_ >> 28;
    word_ <<= 4;
    --left_;
    return true;
  }
  const uint8_t* words_;
  size_t num_words_;
  size_t next_ = 0;
  uint32_t word_ = 0;
  int left_ = 0;
};

std::vector<uint8_t> EncodeRvl(const cv::Mat& depth) {
  const cv::Mat flat = depth.isContinuous() ? depth : depth.clone();
  const uint16_t* pixel = flat.ptr<uint16_t>(0);
  const uint16_t* const end = pixel + static_cast<size_t>(flat.cols) * flat.rows;
  std::vector<uint8_t> out(kRvlHeaderBytes);
  // Typical Kinect frames compress to ~1/3 of raw; reserving that avoids most regrowth.
  out.reserve(kRvlHeaderBytes + static_cast<size_t>(end - pixel) * 2 / 3);
  std::memcpy(out.data(), kRvlMagic, 4);
  PutLe32(static_cast<uint32_t>(flat.cols), out.data() + 4);
  PutLe32(static_cast<uint32_t>(flat.rows), out.data() + 8);
  NibbleWriter writer(&out);
  int32_t previous = 0;
  while (pixel != end) {
    const uint16_t* run = pixel;
    while (pixel != end && *pixel == 0) ++pixel;
    writer.PutVle(static_cast<uint32_t>(pixel - run));
    run = pixel;
    while (pixel != end && *pixel != 0) ++pixel;
    writer.PutVle(static_cast<uint32_t>(pixel - run));
    for (; run != pixel; ++run) {
      const int32_t delta = static_cast<int32_t>(*run) - previous;
      previous = *run;
      writer.PutVle((static_cast<uint32_t>(delta) << 1) ^ static_cast<uint32_t>(delta >> 31));
    }
  }
  writer.Flush();
  return out;
}

StatusOr<cv::Mat> DecodeRvl(const uint8_t* data, size_t size, int width, int height) {
  if (size < kRvlHeaderBytes) return DataLoss("RVL depth: " + std::to_string(size) + " bytes is shorter than its header");
  if (std::memcmp(data, kRvlMagic, 4) != 0) return DataLoss("RVL depth: bad magic");
  const uint32_t rvl_width = GetLe32(data + 4);
  const uint32_t rvl_height = GetLe32(data + 8);
  if (rvl_width != static_cast<uint32_t>(width) || rvl_height != static_cast<uint32_t>(height))
    return DataLoss("RVL depth is " + std::to_string(rvl_width) + "x" + std::to_string(rvl_height) + ", expected " +
                    std::to_string(width) + "x" + std::to_string(height));
  if ((size - kRvlHeaderBytes) % 4 != 0) return DataLoss("RVL depth: payload is not whole 32-bit words");
  NibbleReader reader(data + kRvlHeaderBytes, (size - kRvlHeaderBytes) / 4);
  cv::Mat depth(height, width, CV_16UC1);
  uint16_t* out = depth.ptr<uint16_t>(0);
  const size_t total = static_cast<size_t>(width) * height;
  size_t filled = 0;
  int64_t previous = 0;
  const Status truncated = DataLoss("RVL depth: stream ends early or holds an over-long code");
  while (filled < total) {
    uint32_t zeros, nonzeros;
    if (!reader.GetVle(&zeros)) return truncated;
    if (zeros > total - filled) return DataLoss("RVL depth: zero run overruns the image");
    std::memset(out + filled, 0, zeros * sizeof(uint16_t));
    filled += zeros;
    if (!reader.GetVle(&nonzeros)) return truncated;
    if (nonzeros > total - filled) return DataLoss("RVL depth: value run overruns the image");
    for (uint32_t i = 0; i < nonzeros; ++i) {
      uint32_t code;
      if (!reader.GetVle(&code)) return truncated;
      const int64_t delta = (code & 1u) ? -static_cast<int64_t>(code >> 1) - 1 : static_cast<int64_t>(code >> 1);
      const int64_t value = previous + delta;
      if (value < 1 || value > 65535) return DataLoss("RVL depth: decoded value out of range");
      out[filled++] = static_cast<uint16_t>(value);
      previous = value;
    }
  }
  if (!reader.AtCleanEnd()) return DataLoss("RVL depth: trailing data after the last pixel");
  return depth;
}

}  // namespace

StatusOr<std::vector<uint8_t>> EncodeDepth(const cv::Mat& depth, DepthEncoding encoding) {
  VD_RETURN_IF_ERROR(CheckDepthImage(depth));
  switch (encoding) {
    case DepthEncoding::kRaw16: return EncodeRaw16(depth);
    case DepthEncoding::kPng16: return EncodePng16(depth);
    case DepthEncoding::kRvl: return EncodeRvl(depth);
    case DepthEncoding::kInvalid: break;
  }
  return InvalidArgument("cannot encode depth with encoding " + std::to_string(static_cast<int>(encoding)));
}

StatusOr<cv::Mat> DecodeDepth(const uint8_t* data, size_t size, DepthEncoding encoding, int width, int height) {
  VD_RETURN_IF_ERROR(CheckDeclaredSize(width, height));
  if (data == nullptr && size != 0) return InvalidArgument("depth data is null");
  static const uint8_t kEmpty = 0;
  if (data == nullptr) data = &kEmpty;
  try {
    switch (encoding) {
      case DepthEncoding::kRaw16: return DecodeRaw16(data, size, width, height);
      case DepthEncoding::kPng16: return DecodePng16(data, size, width, height);
      case DepthEncoding::kRvl: return DecodeRvl(data, size, width, height);
      case DepthEncoding::kInvalid: break;
    }
  } catch (const std::exception& e) {
    return Internal(std::string("depth decoding failed: ") + e.what());
  }
  return InvalidArgument("unknown depth encoding " + std::to_string(static_cast<int>(encoding)));
}

}  // namespace vd
