// DecodeMeshDraco on arbitrary bytes. An accepted mesh has triangles, passes the common mesh
// checks (fuzz_util.h), and encodes again: EncodeMeshDraco keeps vertex and triangle counts
// (edgebreaker may reorder; it falls back to sequential coding when counts would change), and the
// attributes present stay present. Its only excuse: coordinates beyond kMaxDracoCoordinate.
#include <cmath>

#include "fuzz_util.h"
#include "vd/common/codecs.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vd::fuzz::Quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto mesh = vd::DecodeMeshDraco(data, size);
  if (!mesh.ok()) return 0;
  VD_FUZZ_CHECK(!mesh->empty());
  vd::fuzz::CheckDecodedMesh(*mesh);
  vd::DracoOptions options;
  options.include_normals = true;
  auto encoded = vd::EncodeMeshDraco(*mesh, options);
  if (!encoded.ok()) {
    // The one mesh it may refuse: coordinates or an extent beyond kMaxDracoCoordinate, which
    // Draco cannot quantise and dequantise in float.
    float min_xyz[3], max_xyz[3];
    mesh->Bounds(min_xyz, max_xyz);
    bool overflows = false;
    for (int a = 0; a < 3; ++a)
      overflows |= !(max_xyz[a] - min_xyz[a] <= vd::kMaxDracoCoordinate) ||
                   !(std::fabs(min_xyz[a]) <= vd::kMaxDracoCoordinate) || !(std::fabs(max_xyz[a]) <= vd::kMaxDracoCoordinate);
    VD_FUZZ_CHECK(overflows && encoded.status().code() == vd::StatusCode::kInvalidArgument);
    return 0;
  }
  auto again = vd::DecodeMeshDraco(encoded->data(), encoded->size());
  VD_FUZZ_CHECK(again.ok());
  VD_FUZZ_CHECK(again->num_vertices() == mesh->num_vertices());
  VD_FUZZ_CHECK(again->num_triangles() == mesh->num_triangles());
  VD_FUZZ_CHECK(again->colors.size() == mesh->colors.size());
  VD_FUZZ_CHECK(again->normals.size() == mesh->normals.size());
  return 0;
}
