// What a viewer does with the bytes of a VDEFORM_MESH message: DecodeLcm, the output key's check
// (vdeform-viewer --key-file), then MessageToMesh (Draco or PLY inside). A decoded message
// re-encodes to the same bytes; the verifier refuses without throwing, by one reason, and what it
// takes verifies and is signed again to the same bytes, and is refused a second time (a replay);
// an accepted mesh has the counts the message declares and passes the common mesh checks.
#include "fuzz_util.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vd::fuzz::Quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto msg = vd::DecodeLcm<vdeform::mesh_t>(data, size);
  if (!msg.ok()) return 0;
  vd::fuzz::CheckLcmRoundTrip(*msg);
  vd::fuzz::CheckOutputVerify(*msg, &vd::OutputVerifier::mesh_refused, &vd::SignMesh);
  auto mesh = vd::MessageToMesh(*msg);
  if (!mesh.ok()) return 0;
  VD_FUZZ_CHECK(mesh->num_vertices() == static_cast<size_t>(msg->num_vertices));
  VD_FUZZ_CHECK(mesh->num_triangles() == static_cast<size_t>(msg->num_triangles));
  VD_FUZZ_CHECK(mesh->empty() == (msg->data_size == 0));
  vd::fuzz::CheckDecodedMesh(*mesh);
  return 0;
}
