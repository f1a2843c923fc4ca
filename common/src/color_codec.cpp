// Colour codecs: none, raw BGR8, JPEG (libjpeg-turbo, called directly: BGR in and out without
// OpenCV's per-pixel swap, same bytes and pixels). The JPEG frame header is checked before
// decoding so a stream declaring a huge image is refused without allocating for it.
#include <algorithm>
#include <climits>
#include <csetjmp>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <vector>

// After <cstdio>: jpeglib.h uses FILE without including it.
#include <jpeglib.h>
// After jpeglib.h: the warning codes (JWRN_*) and ERREXIT.
#include <jerror.h>

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

// libjpeg reports a fatal error by calling error_exit, which must not return: it jumps back to
// the *Rows function that called setjmp. Warnings are sorted by emit_message: corrupt or truncated
// data (which libjpeg would fill with grey) marks the image corrupt; the benign ones do not.
struct JpegErrors {
  jpeg_error_mgr mgr;
  std::jmp_buf fatal;
  // The fatal error's or the first corrupting warning's text ("" when none).
  char first_message[JMSG_LENGTH_MAX];
  // A warning that means part of the image is not what was encoded.
  bool corrupt;
};

[[noreturn]] void JpegFatal(j_common_ptr cinfo) {
  auto* errors = reinterpret_cast<JpegErrors*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, errors->first_message);
  std::longjmp(errors->fatal, 1);
}

// Replaces libjpeg's printing of warnings and traces (level >= 0: traces, never printed). Benign:
// bytes between segments (webcam MJPEG often has them). Anything else (a bad Huffman code, data
// ending before the image is complete, ...) is corrupt.
void JpegWarning(j_common_ptr cinfo, int level) {
  if (level >= 0) return;
  if (cinfo->err->msg_code == JWRN_EXTRANEOUS_DATA) return;
  auto* errors = reinterpret_cast<JpegErrors*>(cinfo->err);
  if (!errors->corrupt) (*cinfo->err->format_message)(cinfo, errors->first_message);
  errors->corrupt = true;
}

void InitJpegErrors(JpegErrors* errors) {
  jpeg_std_error(&errors->mgr);
  errors->mgr.error_exit = JpegFatal;
  errors->mgr.emit_message = JpegWarning;
  errors->first_message[0] = 0;
  errors->corrupt = false;
}

// A progressive JPEG may hold any number of scans, and libjpeg decodes every one: a few kilobytes of
// tiny scans cost seconds of CPU (libjpeg-turbo's djpeg -maxscans guards against the same). Our
// capture sends baseline JPEG (1 scan); libjpeg's simple progression has 10; 3 components with one
// AC coefficient per scan would need 190. Beyond kMaxJpegScans the frame is refused.
constexpr int kMaxJpegScans = 200;

void JpegScanLimit(j_common_ptr cinfo) {
  if (!cinfo->is_decompressor) return;
  const int scans = reinterpret_cast<j_decompress_ptr>(cinfo)->input_scan_number;
  if (scans <= kMaxJpegScans) return;
  auto* errors = reinterpret_cast<JpegErrors*>(cinfo->err);
  std::snprintf(errors->first_message, sizeof(errors->first_message), "more than %d scans", kMaxJpegScans);
  std::longjmp(errors->fatal, 1);
}

// The decode proper, between setjmp and the longjmp of a fatal error: only plain data lives in
// this frame, so the jump skips no destructor, and every libjpeg call that can fail (creation
// included) comes after the setjmp. Rows go straight into `out` (BGR, `step` bytes a row):
// libjpeg-turbo converts to BGR itself (JCS_EXT_BGR), where OpenCV 4.6's imdecode asks for RGB and
// swaps every pixel in a scalar loop, 1.8 ms of the server's receive thread per 640x480 frame
// (docs/BENCHMARKS.md, "Session 31").
bool DecodeJpegRows(jpeg_decompress_struct* cinfo, JpegErrors* errors, jpeg_progress_mgr* progress,
                    const uint8_t* data, size_t size, uint8_t* out, size_t step, int width, int height) {
  if (setjmp(errors->fatal)) return false;
  jpeg_create_decompress(cinfo);
  cinfo->progress = progress;
  jpeg_mem_src(cinfo, data, static_cast<unsigned long>(size));
  if (jpeg_read_header(cinfo, TRUE) != JPEG_HEADER_OK) return false;
  if (static_cast<int>(cinfo->image_width) != width || static_cast<int>(cinfo->image_height) != height) return false;
  cinfo->out_color_space = JCS_EXT_BGR;
  jpeg_start_decompress(cinfo);
  if (cinfo->output_components != 3) return false;
  while (cinfo->output_scanline < cinfo->output_height) {
    JSAMPROW row = out + static_cast<size_t>(cinfo->output_scanline) * step;
    if (jpeg_read_scanlines(cinfo, &row, 1) != 1) return false;
  }
  jpeg_finish_decompress(cinfo);
  return true;
}

StatusOr<cv::Mat> DecodeJpeg(const uint8_t* data, size_t size, int width, int height) {
  VD_RETURN_IF_ERROR(CheckJpegHeader(data, size, width, height));
  if (size > static_cast<size_t>(ULONG_MAX)) return DataLoss("colour JPEG larger than libjpeg reads");
  // Some cameras' JPEG has no end marker. libjpeg reads ahead for one and would warn of a premature
  // end even when the data is complete, so the marker is added: complete data then decodes cleanly,
  // and data cut short still meets the marker too early (a corrupting warning).
  std::vector<uint8_t> ended;
  if (data[size - 2] != 0xFF || data[size - 1] != 0xD9) {
    ended.resize(size + 2);
    std::copy(data, data + size, ended.begin());
    ended[size] = 0xFF;
    ended[size + 1] = 0xD9;
    data = ended.data();
    size = ended.size();
  }
  cv::Mat color(height, width, CV_8UC3);
  JpegErrors errors;
  InitJpegErrors(&errors);
  jpeg_progress_mgr progress{};
  progress.progress_monitor = JpegScanLimit;
  // Zeroed: jpeg_destroy_decompress is a no-op on a struct creation never reached.
  jpeg_decompress_struct cinfo{};
  cinfo.err = &errors.mgr;
  const bool decoded = DecodeJpegRows(&cinfo, &errors, &progress, data, size, color.data, color.step, width, height);
  jpeg_destroy_decompress(&cinfo);
  const std::string why = errors.first_message[0] ? std::string(": ") + errors.first_message : std::string();
  if (!decoded) return DataLoss("colour JPEG could not be decoded (" + std::to_string(size) + " bytes)" + why);
  if (errors.corrupt) return DataLoss("colour JPEG is corrupt (" + std::to_string(size) + " bytes)" + why);
  return color;
}

// The encoder's output: a malloc'd buffer EncodeJpeg owns on every path (libjpeg's jpeg_mem_dest
// frees and replaces its buffer as it grows without telling the caller, so a failure midway would
// leave the caller a freed pointer). Growth failing is a libjpeg error (longjmp).
struct JpegSink {
  jpeg_destination_mgr mgr;
  unsigned char* data;
  size_t capacity;
  j_compress_ptr cinfo;
};

void SinkGrow(JpegSink* sink, size_t used) {
  const size_t capacity = std::max<size_t>(2 * sink->capacity, 64 * 1024);
  auto* grown = static_cast<unsigned char*>(std::realloc(sink->data, capacity));
  if (grown == nullptr) ERREXIT(sink->cinfo, JERR_OUT_OF_MEMORY);
  sink->data = grown;
  sink->capacity = capacity;
  sink->mgr.next_output_byte = grown + used;
  sink->mgr.free_in_buffer = capacity - used;
}

void SinkInit(j_compress_ptr cinfo) { SinkGrow(reinterpret_cast<JpegSink*>(cinfo->dest), 0); }

boolean SinkEmpty(j_compress_ptr cinfo) {
  auto* sink = reinterpret_cast<JpegSink*>(cinfo->dest);
  // libjpeg calls this when the whole buffer is full: everything in it is output so far.
  SinkGrow(sink, sink->capacity);
  return TRUE;
}

void SinkTerm(j_compress_ptr) {}

// The encode proper, between setjmp and the longjmp of a fatal error (plain data only, creation
// after the setjmp, as in DecodeJpegRows). libjpeg reads BGR rows directly (JCS_EXT_BGR), with the
// settings OpenCV 4.6's imencode uses (libjpeg's defaults at `quality`, baseline, standard Huffman
// tables), so the bytes are the same as imencode's without its per-pixel swap to RGB.
bool EncodeJpegRows(jpeg_compress_struct* cinfo, JpegErrors* errors, JpegSink* sink, const cv::Mat& color,
                    int quality) {
  if (setjmp(errors->fatal)) return false;
  jpeg_create_compress(cinfo);
  sink->cinfo = cinfo;
  cinfo->dest = &sink->mgr;
  cinfo->image_width = static_cast<JDIMENSION>(color.cols);
  cinfo->image_height = static_cast<JDIMENSION>(color.rows);
  cinfo->input_components = 3;
  cinfo->in_color_space = JCS_EXT_BGR;
  jpeg_set_defaults(cinfo);
  jpeg_set_quality(cinfo, quality, TRUE);
  jpeg_start_compress(cinfo, TRUE);
  while (cinfo->next_scanline < cinfo->image_height) {
    JSAMPROW row = const_cast<uint8_t*>(color.ptr<uint8_t>(static_cast<int>(cinfo->next_scanline)));
    if (jpeg_write_scanlines(cinfo, &row, 1) != 1) return false;
  }
  jpeg_finish_compress(cinfo);
  return true;
}

StatusOr<std::vector<uint8_t>> EncodeJpeg(const cv::Mat& color, int quality) {
  JpegErrors errors;
  InitJpegErrors(&errors);
  JpegSink sink{};
  sink.mgr.init_destination = SinkInit;
  sink.mgr.empty_output_buffer = SinkEmpty;
  sink.mgr.term_destination = SinkTerm;
  jpeg_compress_struct cinfo{};
  cinfo.err = &errors.mgr;
  const bool encoded = EncodeJpegRows(&cinfo, &errors, &sink, color, quality);
  jpeg_destroy_compress(&cinfo);
  std::vector<uint8_t> out;
  if (encoded) out.assign(sink.data, sink.data + (sink.capacity - sink.mgr.free_in_buffer));
  std::free(sink.data);
  if (!encoded) return Internal(std::string("JPEG encoding failed: ") + errors.first_message);
  return out;
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
  return EncodeJpeg(color, jpeg_quality);
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
