// DecodeLcm<control_t>, the first step of the server's VDEFORM_CONTROL handler. A decoded message
// has an auth array of its declared size and re-encodes to the same bytes, so the fields the server
// checks (and the HMAC covers) are the fields it acts on.
#include "fuzz_util.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vd::fuzz::Quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto msg = vd::DecodeLcm<vdeform::control_t>(data, size);
  if (!msg.ok()) return 0;
  VD_FUZZ_CHECK(msg->auth_size >= 0 && msg->auth.size() == static_cast<size_t>(msg->auth_size));
  vd::fuzz::CheckLcmRoundTrip(*msg);
  return 0;
}
