// DecodeColor with the JPEG encoding (see image_fuzz.h for the input layout and the checks).
#include "image_fuzz.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vd::fuzz::Quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return vd::fuzz::FuzzColor(vd::ColorEncoding::kJpeg, data, size);
}
