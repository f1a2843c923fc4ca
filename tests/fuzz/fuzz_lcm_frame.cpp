// What the server does with the bytes of a VDEFORM_FRAMES message before tracking: DecodeLcm,
// then MessageToFrame. A decoded message re-encodes to the same bytes; an accepted frame agrees
// with its message, and goes out again through FrameToMessage with the same codecs and comes back
// with identical depth (lossless) and colour of the same size.
#include "fuzz_util.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vd::fuzz::Quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto msg = vd::DecodeLcm<vdeform::rgbd_frame_t>(data, size);
  if (!msg.ok()) return 0;
  vd::fuzz::CheckLcmRoundTrip(*msg);
  auto frame = vd::MessageToFrame(*msg);
  if (!frame.ok()) return 0;
  VD_FUZZ_CHECK(frame->Validate().ok());
  VD_FUZZ_CHECK(frame->source_id == msg->source_id && frame->seq == msg->seq && frame->utime == msg->utime);
  VD_FUZZ_CHECK(frame->intrinsics.width == msg->width && frame->intrinsics.height == msg->height);
  VD_FUZZ_CHECK(frame->depth.type() == CV_16UC1 && frame->depth.cols == msg->width && frame->depth.rows == msg->height);
  VD_FUZZ_CHECK(frame->color.empty() == (msg->color_encoding == vdeform::rgbd_frame_t::COLOR_NONE));
  if (!frame->color.empty()) VD_FUZZ_CHECK(frame->color.type() == CV_8UC3 && frame->color.size() == frame->depth.size());
  VD_FUZZ_CHECK(frame->depth_scale == msg->depth_scale);

  vd::FrameEncodeOptions options;
  options.depth = static_cast<vd::DepthEncoding>(msg->depth_encoding);
  if (!frame->color.empty()) options.color = static_cast<vd::ColorEncoding>(msg->color_encoding);
  auto resent = vd::FrameToMessage(*frame, options);
  // Re-encoding may only fail by outgrowing the payload limit (raw codecs on a large frame).
  if (!resent.ok()) {
    VD_FUZZ_CHECK(resent.status().code() == vd::StatusCode::kOutOfRange);
    return 0;
  }
  auto back = vd::MessageToFrame(*resent);
  VD_FUZZ_CHECK(back.ok());
  VD_FUZZ_CHECK(vd::fuzz::SameImage(back->depth, frame->depth));
  VD_FUZZ_CHECK(back->color.size() == frame->color.size());
  return 0;
}
