// DecodePly (what ReadPly and mesh_t's RAW encoding use) on arbitrary bytes, binary or ASCII. An
// accepted mesh passes the common mesh checks (fuzz_util.h), which include PLY re-encoding.
#include "fuzz_util.h"
#include "vd/common/codecs.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vd::fuzz::Quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto mesh = vd::DecodePly(data, size);
  if (!mesh.ok()) return 0;
  vd::fuzz::CheckDecodedMesh(*mesh);
  return 0;
}
