// Draco mesh codec. Positions are quantised (DracoOptions::position_bits); colours are uint8 and
// kept exactly; normals optional. A mesh with zero triangles is refused with a clear error by
// both EncodeMeshDraco and DecodeMeshDraco (Draco itself crashes on an empty mesh); the message
// layer (MeshToMessage) sends an empty mesh as zero bytes instead.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <exception>
#include <memory>
#include <string>
#include <vector>

#include <draco/compression/config/compression_shared.h>
#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>

#include "vd/common/codecs.h"
#include "vd/common/log.h"

namespace vd {
namespace {

// Octahedral normal quantisation: 10 bits keeps normals within about a degree, enough for shading.
constexpr int kNormalBits = 10;
// Fixed unique ids of the attributes, so a decoder that asks by id (the web page's DRACOLoader)
// finds the canonical positions, a GENERIC attribute, without reading the file's metadata.
constexpr uint32_t kPositionId = 0, kColorId = 1, kNormalId = 2;

template <typename T>
int AddAttribute(draco::Mesh* mesh, draco::GeometryAttribute::Type type, draco::DataType data_type, bool normalized,
                 const T* values, size_t num_points, uint32_t unique_id) {
  draco::GeometryAttribute attribute;
  attribute.Init(type, nullptr, 3, data_type, normalized, 3 * sizeof(T), 0);
  const int id = mesh->AddAttribute(attribute, true, static_cast<uint32_t>(num_points));
  draco::PointAttribute* added = mesh->attribute(id);
  added->set_unique_id(unique_id);
  for (size_t i = 0; i < num_points; ++i)
    added->SetAttributeValue(draco::AttributeValueIndex(static_cast<uint32_t>(i)), values + 3 * i);
  return id;
}

// Draco quantises positions relative to the bounding box, in float: an extent that overflows
// (coordinates of both signs near FLT_MAX) makes it cast infinity to an integer and crash, and a
// box reaching near FLT_MAX dequantises to infinity on the other side. Metres never come near:
// refuse coordinates and extents beyond kMaxDracoCoordinate.
Status CheckCoordinates(const std::vector<float>& xyz, const char* what) {
  TriangleMesh points;
  points.positions = xyz;
  float min_xyz[3], max_xyz[3];
  points.Bounds(min_xyz, max_xyz);
  for (int a = 0; a < 3; ++a)
    if (!(max_xyz[a] - min_xyz[a] <= kMaxDracoCoordinate) || !(std::fabs(min_xyz[a]) <= kMaxDracoCoordinate) ||
        !(std::fabs(max_xyz[a]) <= kMaxDracoCoordinate)) {
      char text[200];
      std::snprintf(text, sizeof(text),
                    "cannot Draco-encode a %s whose coordinates along axis %d (%g .. %g) exceed %g in magnitude "
                    "or extent",
                    what, a, min_xyz[a], max_xyz[a], double(kMaxDracoCoordinate));
      return InvalidArgument(text);
    }
  return Status::Ok();
}

StatusOr<std::vector<uint8_t>> Encode(const draco::Mesh& mesh, const DracoOptions& options, bool sequential,
                                      size_t* num_points, size_t* num_faces) {
  draco::Encoder encoder;
  encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, options.position_bits);
  encoder.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, kNormalBits);
  // The canonical positions are positions too: the same precision.
  encoder.SetAttributeQuantization(draco::GeometryAttribute::GENERIC, options.position_bits);
  encoder.SetSpeedOptions(options.speed, options.speed);
  encoder.SetTrackEncodedProperties(true);
  if (sequential) encoder.SetEncodingMethod(draco::MESH_SEQUENTIAL_ENCODING);
  draco::EncoderBuffer buffer;
  const draco::Status status = encoder.EncodeMeshToBuffer(mesh, &buffer);
  if (!status.ok()) return Internal(std::string("Draco encoding failed: ") + status.error_msg());
  *num_points = encoder.num_encoded_points();
  *num_faces = encoder.num_encoded_faces();
  return std::vector<uint8_t>(buffer.data(), buffer.data() + buffer.size());
}

// Checks a decoded attribute is (type x 3) and covers every point.
Status CheckAttribute(const draco::PointAttribute* attribute, const char* name, draco::DataType type, size_t num_points) {
  if (attribute->data_type() != type || attribute->num_components() != 3)
    return DataLoss(std::string("Draco ") + name + " attribute has type " + std::to_string(attribute->data_type()) +
                    " x" + std::to_string(attribute->num_components()) + ", expected type " + std::to_string(type) + " x3");
  if (!attribute->is_mapping_identity() && attribute->indices_map_size() < num_points)
    return DataLoss(std::string("Draco ") + name + " attribute does not cover every point");
  return Status::Ok();
}

template <typename T>
Status CopyAttribute(const draco::PointAttribute* attribute, const char* name, size_t num_points, std::vector<T>* out) {
  out->resize(3 * num_points);
  std::array<T, 3> value;
  for (size_t i = 0; i < num_points; ++i) {
    const draco::AttributeValueIndex index = attribute->mapped_index(draco::PointIndex(static_cast<uint32_t>(i)));
    if (index.value() >= attribute->size() || !attribute->GetValue<T, 3>(index, &value))
      return DataLoss(std::string("Draco ") + name + " value out of range");
    for (int k = 0; k < 3; ++k) (*out)[3 * i + k] = value[k];
  }
  return Status::Ok();
}

// Draco trusts the element counts at the start of a mesh's connectivity and allocates for them
// before reading any data: a 300-byte stream declaring hundreds of millions of faces made it
// allocate over 3 GB. CheckDeclaredCounts reads those counts first, as Draco 1.5 lays them out in
// mesh bitstream 2.2 (the version it writes), and refuses counts no stream of that size holds.
// The most compressible mesh measured, a flat regular one-colour grid, took 1.3 bits per face
// (6.2 faces per byte); 64 elements per byte leaves a wide margin. The absolute cap is about what
// a kMaxPayloadBytes message of such a grid could carry.
constexpr uint64_t kMaxDracoElementsPerByte = 64;
constexpr uint64_t kMaxDracoElements = uint64_t{1} << 24;
// "DRACO", version major and minor, encoder type, method, flags (uint16 little-endian).
constexpr size_t kDracoHeaderBytes = 11;

class HeaderReader {
 public:
  HeaderReader(const uint8_t* data, size_t size, size_t pos) : data_(data), size_(size), pos_(pos) {}
  bool Byte(uint8_t* out) {
    if (pos_ >= size_) return false;
    *out = data_[pos_++];
    return true;
  }
  // Draco's varint: 7 bits per byte, least significant group first, at most 5 bytes, the value
  // taken modulo 2^32 as Draco's decoder does.
  bool Varint(uint32_t* out) {
    uint64_t value = 0;
    for (int i = 0; i < 5; ++i) {
      uint8_t byte;
      if (!Byte(&byte)) return false;
      value |= static_cast<uint64_t>(byte & 0x7F) << (7 * i);
      if (!(byte & 0x80)) {
        *out = static_cast<uint32_t>(value);
        return true;
      }
    }
    return false;
  }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t pos_;
};

Status CheckDeclaredCounts(const uint8_t* data, size_t size) {
  if (size < kDracoHeaderBytes) return DataLoss("Draco header: " + std::to_string(size) + " bytes is too short");
  const int major = data[5], minor = data[6], method = data[8];
  const int flags = data[9] | data[10] << 8;
  if (major != draco::kDracoMeshBitstreamVersionMajor || minor != draco::kDracoMeshBitstreamVersionMinor)
    return DataLoss("Draco mesh bitstream version " + std::to_string(major) + "." + std::to_string(minor) +
                    " is not the one accepted (" + std::to_string(draco::kDracoMeshBitstreamVersionMajor) + "." +
                    std::to_string(draco::kDracoMeshBitstreamVersionMinor) + ")");
  if (flags & METADATA_FLAG_MASK) return DataLoss("Draco mesh carries metadata, which is not accepted");
  HeaderReader reader(data, size, kDracoHeaderBytes);
  uint32_t faces = 0;
  uint64_t vertices = 0;
  bool complete = false;
  if (method == draco::MESH_SEQUENTIAL_ENCODING) {
    uint32_t points = 0;
    complete = reader.Varint(&faces) && reader.Varint(&points);
    vertices = points;
  } else if (method == draco::MESH_EDGEBREAKER_ENCODING) {
    uint8_t traversal = 0, attribute_data = 0;
    uint32_t encoded_vertices = 0, symbols = 0, split_symbols = 0;
    complete = reader.Byte(&traversal) && reader.Varint(&encoded_vertices) && reader.Varint(&faces) &&
               reader.Byte(&attribute_data) && reader.Varint(&symbols) && reader.Varint(&split_symbols);
    // Each split symbol adds a vertex while decoding.
    vertices = uint64_t{encoded_vertices} + split_symbols;
  } else {
    return DataLoss("Draco mesh encoding method " + std::to_string(method) + " is unknown");
  }
  if (!complete) return DataLoss("Draco connectivity header ends early");
  const uint64_t limit = std::min<uint64_t>(kMaxDracoElements, kMaxDracoElementsPerByte * size);
  if (faces > limit || vertices > limit)
    return DataLoss("Draco stream of " + std::to_string(size) + " bytes declares " + std::to_string(faces) +
                    " faces and " + std::to_string(vertices) + " vertices, above the " + std::to_string(limit) +
                    " it can hold");
  return Status::Ok();
}

StatusOr<TriangleMesh> DecodeUnchecked(const uint8_t* data, size_t size) {
  if (data == nullptr || size == 0) return DataLoss("Draco buffer is empty (an empty mesh is not Draco-encoded)");
  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(data), size);
  const auto type = draco::Decoder::GetEncodedGeometryType(&buffer);
  if (!type.ok()) return DataLoss(std::string("Draco header: ") + type.status().error_msg());
  if (type.value() != draco::TRIANGULAR_MESH) return DataLoss("Draco buffer holds a point cloud, not a triangle mesh");
  VD_RETURN_IF_ERROR(CheckDeclaredCounts(data, size));
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok()) return DataLoss(std::string("Draco decoding failed: ") + decoded.status().error_msg());
  const draco::Mesh& dm = *decoded.value();
  const size_t num_points = dm.num_points();
  const size_t num_faces = dm.num_faces();
  if (num_faces == 0) return DataLoss("Draco mesh has no triangles");
  if (num_points > static_cast<size_t>(INT32_MAX) || num_faces > static_cast<size_t>(INT32_MAX) / 3)
    return DataLoss("Draco mesh too large");

  TriangleMesh mesh;
  const draco::PointAttribute* position = dm.GetNamedAttribute(draco::GeometryAttribute::POSITION);
  if (position == nullptr) return DataLoss("Draco mesh has no POSITION attribute");
  VD_RETURN_IF_ERROR(CheckAttribute(position, "POSITION", draco::DT_FLOAT32, num_points));
  VD_RETURN_IF_ERROR(CopyAttribute(position, "POSITION", num_points, &mesh.positions));
  if (const draco::PointAttribute* color = dm.GetNamedAttribute(draco::GeometryAttribute::COLOR)) {
    VD_RETURN_IF_ERROR(CheckAttribute(color, "COLOR", draco::DT_UINT8, num_points));
    VD_RETURN_IF_ERROR(CopyAttribute(color, "COLOR", num_points, &mesh.colors));
  }
  if (const draco::PointAttribute* normal = dm.GetNamedAttribute(draco::GeometryAttribute::NORMAL)) {
    VD_RETURN_IF_ERROR(CheckAttribute(normal, "NORMAL", draco::DT_FLOAT32, num_points));
    VD_RETURN_IF_ERROR(CopyAttribute(normal, "NORMAL", num_points, &mesh.normals));
  }
  if (const draco::PointAttribute* canonical = dm.GetAttributeByUniqueId(kDracoCanonicalId);
      canonical != nullptr && canonical->attribute_type() == draco::GeometryAttribute::GENERIC) {
    VD_RETURN_IF_ERROR(CheckAttribute(canonical, "canonical", draco::DT_FLOAT32, num_points));
    VD_RETURN_IF_ERROR(CopyAttribute(canonical, "canonical", num_points, &mesh.canonical));
  }
  mesh.triangles.resize(3 * num_faces);
  for (size_t f = 0; f < num_faces; ++f) {
    const draco::Mesh::Face& face = dm.face(draco::FaceIndex(static_cast<uint32_t>(f)));
    for (int k = 0; k < 3; ++k) {
      if (face[k].value() >= num_points) return DataLoss("Draco face refers to a missing point");
      mesh.triangles[3 * f + k] = static_cast<int32_t>(face[k].value());
    }
  }
  VD_RETURN_IF_ERROR(mesh.Validate().WithContext("decoded Draco mesh"));
  return mesh;
}

}  // namespace

Status DracoOptions::Validate() const {
  // Draco's quantisation transform accepts 1..30 bits.
  if (position_bits < 1 || position_bits > 30)
    return InvalidArgument("DracoOptions.position_bits = " + std::to_string(position_bits) +
                           " violates 1 <= position_bits <= 30");
  if (speed < 0 || speed > 10)
    return InvalidArgument("DracoOptions.speed = " + std::to_string(speed) + " violates 0 <= speed <= 10");
  return Status::Ok();
}

StatusOr<std::vector<uint8_t>> EncodeMeshDraco(const TriangleMesh& mesh, const DracoOptions& options) {
  VD_RETURN_IF_ERROR(options.Validate());
  VD_RETURN_IF_ERROR(mesh.Validate());
  if (mesh.empty()) return InvalidArgument("cannot Draco-encode a mesh with no triangles");
  VD_RETURN_IF_ERROR(CheckCoordinates(mesh.positions, "mesh"));
  VD_RETURN_IF_ERROR(CheckCoordinates(mesh.canonical, "canonical positions"));
  const size_t num_points = mesh.num_vertices();
  if (num_points > static_cast<size_t>(INT32_MAX)) return InvalidArgument("mesh has too many vertices for Draco");
  try {
    draco::Mesh dm;
    dm.set_num_points(static_cast<uint32_t>(num_points));
    AddAttribute(&dm, draco::GeometryAttribute::POSITION, draco::DT_FLOAT32, false, mesh.positions.data(), num_points,
                 kPositionId);
    if (!mesh.colors.empty())
      AddAttribute(&dm, draco::GeometryAttribute::COLOR, draco::DT_UINT8, true, mesh.colors.data(), num_points,
                   kColorId);
    if (options.include_normals && !mesh.normals.empty())
      AddAttribute(&dm, draco::GeometryAttribute::NORMAL, draco::DT_FLOAT32, false, mesh.normals.data(), num_points,
                   kNormalId);
    if (!mesh.canonical.empty())
      AddAttribute(&dm, draco::GeometryAttribute::GENERIC, draco::DT_FLOAT32, false, mesh.canonical.data(),
                   num_points, kDracoCanonicalId);
    dm.SetNumFaces(mesh.num_triangles());
    for (size_t f = 0; f < mesh.num_triangles(); ++f) {
      draco::Mesh::Face face;
      for (int k = 0; k < 3; ++k) face[k] = draco::PointIndex(static_cast<uint32_t>(mesh.triangles[3 * f + k]));
      dm.SetFace(draco::FaceIndex(static_cast<uint32_t>(f)), face);
    }
    size_t encoded_points = 0, encoded_faces = 0;
    auto first = Encode(dm, options, options.speed == 10, &encoded_points, &encoded_faces);
    if (first.ok() && encoded_points == num_points && encoded_faces == mesh.num_triangles()) return first;
    // Edgebreaker drops unreferenced vertices and degenerate triangles and splits non-manifold
    // vertices, and fails outright when every triangle is degenerate. The receiver checks counts
    // against the message, so keep the mesh as it is with sequential connectivity coding (larger,
    // but exact in counts and order).
    if (first.ok())
      VD_LOG_DEBUG << "Draco edgebreaker changed the mesh (" << num_points << " -> " << encoded_points << " vertices, "
                   << mesh.num_triangles() << " -> " << encoded_faces << " triangles); using sequential coding";
    else
      VD_LOG_DEBUG << first.status().message() << "; using sequential coding";
    VD_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, Encode(dm, options, true, &encoded_points, &encoded_faces));
    if (encoded_points != num_points || encoded_faces != mesh.num_triangles())
      return Internal("Draco sequential coding changed the mesh (" + std::to_string(num_points) + " -> " +
                      std::to_string(encoded_points) + " vertices)");
    return bytes;
  } catch (const std::exception& e) {
    return Internal(std::string("Draco encoding failed: ") + e.what());
  }
}

StatusOr<TriangleMesh> DecodeMeshDraco(const uint8_t* data, size_t size) {
  try {
    return DecodeUnchecked(data, size);
  } catch (const std::exception& e) {
    return DataLoss(std::string("Draco decoding failed: ") + e.what());
  }
}

}  // namespace vd
