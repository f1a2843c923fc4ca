// DecodeLcm<server_status_t> and the output key's check, what viewers and lockstep capture clients
// run on VDEFORM_STATUS. A decoded message has arrays of its declared counts and re-encodes to the
// same bytes; the verifier behaves as in fuzz_lcm_mesh.
#include "fuzz_util.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vd::fuzz::Quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto msg = vd::DecodeLcm<vdeform::server_status_t>(data, size);
  if (!msg.ok()) return 0;
  VD_FUZZ_CHECK(msg->num_reject_reasons >= 0 && msg->num_stages >= 0);
  const size_t reasons = static_cast<size_t>(msg->num_reject_reasons);
  const size_t stages = static_cast<size_t>(msg->num_stages);
  VD_FUZZ_CHECK(msg->reject_reason.size() == reasons && msg->reject_count.size() == reasons);
  VD_FUZZ_CHECK(msg->stage_name.size() == stages && msg->stage_ms_last.size() == stages &&
                msg->stage_ms_mean.size() == stages);
  vd::fuzz::CheckLcmRoundTrip(*msg);
  vd::fuzz::CheckOutputVerify(*msg, &vd::OutputVerifier::status_refused, &vd::SignStatus);
  return 0;
}
