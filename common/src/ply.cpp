// PLY reader and writer. Writes binary little-endian; reads binary little-endian and ASCII with
// float/double xyz, optional normals and uchar colour, and triangle face lists. Anything else is
// refused with an error naming the line; every read is bounded by the buffer.
#include <algorithm>
#include <charconv>
#include <cstring>
#include <exception>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "vd/common/codecs.h"

namespace vd {
namespace {

// A header longer than this is not a mesh we wrote or would want to read.
constexpr size_t kMaxHeaderBytes = 64 * 1024;
// Files larger than this are refused before reading them into memory.
constexpr int64_t kMaxPlyFileBytes = int64_t{2} * 1024 * 1024 * 1024 - 1;

enum class Scalar { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

bool ParseScalar(const std::string& name, Scalar* out) {
  static const struct {
    const char* name;
    Scalar type;
  } kNames[] = {{"char", Scalar::kInt8},     {"int8", Scalar::kInt8},       {"uchar", Scalar::kUint8},
                {"uint8", Scalar::kUint8},   {"short", Scalar::kInt16},     {"int16", Scalar::kInt16},
                {"ushort", Scalar::kUint16}, {"uint16", Scalar::kUint16},   {"int", Scalar::kInt32},
                {"int32", Scalar::kInt32},   {"uint", Scalar::kUint32},     {"uint32", Scalar::kUint32},
                {"float", Scalar::kFloat32}, {"float32", Scalar::kFloat32}, {"double", Scalar::kFloat64},
                {"float64", Scalar::kFloat64}};
  for (const auto& entry : kNames)
    if (name == entry.name) {
      *out = entry.type;
      return true;
    }
  return false;
}

size_t ScalarBytes(Scalar s) {
  switch (s) {
    case Scalar::kInt8:
    case Scalar::kUint8: return 1;
    case Scalar::kInt16:
    case Scalar::kUint16: return 2;
    case Scalar::kInt32:
    case Scalar::kUint32:
    case Scalar::kFloat32: return 4;
    case Scalar::kFloat64: return 8;
  }
  return 0;
}

bool IsFloat(Scalar s) { return s == Scalar::kFloat32 || s == Scalar::kFloat64; }

// Where a vertex property goes.
enum class Slot { kX, kY, kZ, kNx, kNy, kNz, kRed, kGreen, kBlue, kAlpha };

struct VertexProperty {
  Slot slot;
  Scalar type;
};

struct Header {
  bool binary = false;
  int64_t num_vertices = -1;
  int64_t num_faces = 0;
  std::vector<VertexProperty> vertex_properties;
  Scalar face_count_type = Scalar::kUint8;
  Scalar face_index_type = Scalar::kInt32;
  // Vertices first (true) or faces first.
  bool vertices_first = true;
  bool has_normals = false;
  bool has_colors = false;
  // Offset of the first data byte.
  size_t data_offset = 0;
};

Status HeaderError(int line, const std::string& what) {
  return InvalidArgument("PLY header line " + std::to_string(line) + ": " + what);
}

Status ParseHeader(const uint8_t* data, size_t size, Header* header) {
  const size_t limit = std::min(size, kMaxHeaderBytes);
  std::vector<std::string> lines;
  size_t pos = 0;
  bool ended = false;
  while (pos < limit && !ended) {
    size_t eol = pos;
    while (eol < limit && data[eol] != '\n') ++eol;
    if (eol == limit) break;
    std::string line(reinterpret_cast<const char*>(data + pos), eol - pos);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    pos = eol + 1;
    lines.push_back(line);
    ended = line == "end_header";
  }
  if (!ended) return InvalidArgument("PLY header has no end_header line within " + std::to_string(kMaxHeaderBytes) + " bytes");
  header->data_offset = pos;
  if (lines[0] != "ply") return InvalidArgument("not a PLY file (first line is not 'ply')");

  enum class Current { kNone, kVertex, kFace } current = Current::kNone;
  bool have_format = false, have_face_list = false, seen_vertex = false, seen_face = false;
  bool slots[10] = {};
  for (size_t i = 1; i + 1 < lines.size(); ++i) {
    const int line_no = static_cast<int>(i) + 1;
    std::istringstream in(lines[i]);
    std::string keyword;
    in >> keyword;
    if (keyword.empty() || keyword == "comment" || keyword == "obj_info") continue;
    if (keyword == "format") {
      std::string format, version;
      in >> format >> version;
      if (version != "1.0") return HeaderError(line_no, "unsupported PLY version '" + version + "'");
      if (format == "binary_little_endian") header->binary = true;
      else if (format == "ascii") header->binary = false;
      else return HeaderError(line_no, "unsupported format '" + format + "' (binary_little_endian or ascii only)");
      have_format = true;
    } else if (keyword == "element") {
      std::string name, count_text;
      in >> name >> count_text;
      int64_t count = -1;
      const auto parsed = std::from_chars(count_text.data(), count_text.data() + count_text.size(), count);
      if (parsed.ec != std::errc() || parsed.ptr != count_text.data() + count_text.size() || count < 0 ||
          count > std::numeric_limits<int32_t>::max() / 3)
        return HeaderError(line_no, "bad element count '" + count_text + "'");
      if (name == "vertex" && !seen_vertex) {
        header->num_vertices = count;
        header->vertices_first = !seen_face;
        seen_vertex = true;
        current = Current::kVertex;
      } else if (name == "face" && !seen_face) {
        header->num_faces = count;
        seen_face = true;
        current = Current::kFace;
      } else {
        return HeaderError(line_no, "unsupported or repeated element '" + name + "' (vertex and face only)");
      }
    } else if (keyword == "property") {
      std::string type_name;
      in >> type_name;
      if (current == Current::kFace) {
        std::string count_type, index_type, name;
        in >> count_type >> index_type >> name;
        if (type_name != "list" || have_face_list)
          return HeaderError(line_no, "a face element must hold exactly one property list");
        if (name != "vertex_indices" && name != "vertex_index")
          return HeaderError(line_no, "unsupported face property '" + name + "'");
        if (!ParseScalar(count_type, &header->face_count_type) ||
            (header->face_count_type != Scalar::kUint8 && header->face_count_type != Scalar::kInt32 &&
             header->face_count_type != Scalar::kUint32))
          return HeaderError(line_no, "face count type '" + count_type + "' unsupported (uchar, int or uint)");
        if (!ParseScalar(index_type, &header->face_index_type) ||
            (header->face_index_type != Scalar::kInt32 && header->face_index_type != Scalar::kUint32))
          return HeaderError(line_no, "face index type '" + index_type + "' unsupported (int or uint)");
        have_face_list = true;
      } else if (current == Current::kVertex) {
        std::string name;
        in >> name;
        Scalar type;
        if (type_name == "list" || !ParseScalar(type_name, &type))
          return HeaderError(line_no, "unsupported vertex property type '" + type_name + "'");
        static const struct {
          const char* name;
          Slot slot;
        } kSlots[] = {{"x", Slot::kX},       {"y", Slot::kY},         {"z", Slot::kZ},       {"nx", Slot::kNx},
                      {"ny", Slot::kNy},     {"nz", Slot::kNz},       {"red", Slot::kRed},   {"green", Slot::kGreen},
                      {"blue", Slot::kBlue}, {"alpha", Slot::kAlpha}};
        bool found = false;
        for (const auto& entry : kSlots) {
          if (name != entry.name) continue;
          const bool colour = entry.slot >= Slot::kRed;
          if (colour && type != Scalar::kUint8)
            return HeaderError(line_no, "colour property '" + name + "' must be uchar");
          if (!colour && !IsFloat(type))
            return HeaderError(line_no, "property '" + name + "' must be float or double");
          if (slots[static_cast<int>(entry.slot)]) return HeaderError(line_no, "repeated property '" + name + "'");
          slots[static_cast<int>(entry.slot)] = true;
          header->vertex_properties.push_back({entry.slot, type});
          found = true;
        }
        if (!found) return HeaderError(line_no, "unsupported vertex property '" + name + "'");
      } else {
        return HeaderError(line_no, "property outside an element");
      }
    } else {
      return HeaderError(line_no, "unexpected '" + keyword + "'");
    }
  }
  if (!have_format) return InvalidArgument("PLY header has no format line");
  if (!seen_vertex) return InvalidArgument("PLY header has no vertex element");
  if (seen_face && !have_face_list && header->num_faces > 0) return InvalidArgument("PLY face element has no vertex_indices list");
  if (!slots[0] || !slots[1] || !slots[2]) return InvalidArgument("PLY vertex element lacks x, y or z");
  const int normals = slots[3] + slots[4] + slots[5];
  const int colours = slots[6] + slots[7] + slots[8];
  if (normals != 0 && normals != 3) return InvalidArgument("PLY vertex element has some but not all of nx, ny, nz");
  if (colours != 0 && colours != 3) return InvalidArgument("PLY vertex element has some but not all of red, green, blue");
  header->has_normals = normals == 3;
  header->has_colors = colours == 3;
  return Status::Ok();
}

// Little-endian scalar reads bounded by the buffer.
class BinaryCursor {
 public:
  BinaryCursor(const uint8_t* data, size_t size, size_t pos) : data_(data), size_(size), pos_(pos) {}
  size_t remaining() const { return size_ - pos_; }
  // Reads one scalar of the given type as a double (exact for every PLY integer type).
  bool Read(Scalar type, double* out) {
    const size_t n = ScalarBytes(type);
    if (n > remaining()) return false;
    uint64_t bits = 0;
    for (size_t k = 0; k < n; ++k) bits |= static_cast<uint64_t>(data_[pos_ + k]) << (8 * k);
    pos_ += n;
    switch (type) {
      case Scalar::kInt8: *out = static_cast<int8_t>(bits); break;
      case Scalar::kUint8: *out = static_cast<uint8_t>(bits); break;
      case Scalar::kInt16: *out = static_cast<int16_t>(bits); break;
      case Scalar::kUint16: *out = static_cast<uint16_t>(bits); break;
      case Scalar::kInt32: *out = static_cast<int32_t>(bits); break;
      case Scalar::kUint32: *out = static_cast<uint32_t>(bits); break;
      case Scalar::kFloat32: {
        const uint32_t b32 = static_cast<uint32_t>(bits);
        float f;
        std::memcpy(&f, &b32, 4);
        *out = f;
        break;
      }
      case Scalar::kFloat64: std::memcpy(out, &bits, 8); break;
    }
    return true;
  }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t pos_;
};

// Whitespace-separated ASCII numbers bounded by the buffer.
class AsciiCursor {
 public:
  AsciiCursor(const uint8_t* data, size_t size, size_t pos)
      : begin_(reinterpret_cast<const char*>(data)), end_(begin_ + size), at_(begin_ + pos) {}
  size_t remaining() const { return static_cast<size_t>(end_ - at_); }
  bool Read(Scalar type, double* out) {
    SkipSpace();
    const char* token_end = at_;
    while (token_end != end_ && !IsSpace(*token_end)) ++token_end;
    if (token_end == at_) return false;
    std::from_chars_result parsed;
    if (IsFloat(type)) {
      parsed = std::from_chars(at_, token_end, *out);
    } else {
      int64_t value = 0;
      parsed = std::from_chars(at_, token_end, value);
      *out = static_cast<double>(value);
    }
    if (parsed.ec != std::errc() || parsed.ptr != token_end) return false;
    at_ = token_end;
    return true;
  }
  bool AtEnd() {
    SkipSpace();
    return at_ == end_;
  }

 private:
  static bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }
  void SkipSpace() {
    while (at_ != end_ && IsSpace(*at_)) ++at_;
  }
  const char* begin_;
  const char* end_;
  const char* at_;
};

template <typename Cursor>
Status ReadVertices(Cursor* cursor, const Header& header, TriangleMesh* mesh) {
  const size_t n = static_cast<size_t>(header.num_vertices);
  mesh->positions.resize(3 * n);
  if (header.has_normals) mesh->normals.resize(3 * n);
  if (header.has_colors) mesh->colors.resize(3 * n);
  for (size_t i = 0; i < n; ++i) {
    for (const VertexProperty& property : header.vertex_properties) {
      double value;
      if (!cursor->Read(property.type, &value))
        return DataLoss("PLY vertex " + std::to_string(i) + " is truncated or malformed");
      const int slot = static_cast<int>(property.slot);
      if (property.slot <= Slot::kZ) {
        mesh->positions[3 * i + slot] = static_cast<float>(value);
      } else if (property.slot <= Slot::kNz) {
        mesh->normals[3 * i + slot - 3] = static_cast<float>(value);
      } else {
        if (!(value >= 0 && value <= 255)) return DataLoss("PLY vertex " + std::to_string(i) + " colour out of range");
        if (property.slot != Slot::kAlpha) mesh->colors[3 * i + slot - 6] = static_cast<uint8_t>(value);
      }
    }
  }
  return Status::Ok();
}

template <typename Cursor>
Status ReadFaces(Cursor* cursor, const Header& header, TriangleMesh* mesh) {
  const size_t n = static_cast<size_t>(header.num_faces);
  const double num_vertices = static_cast<double>(header.num_vertices);
  mesh->triangles.resize(3 * n);
  for (size_t f = 0; f < n; ++f) {
    double count;
    if (!cursor->Read(header.face_count_type, &count)) return DataLoss("PLY face " + std::to_string(f) + " is truncated");
    if (count != 3)
      return DataLoss("PLY face " + std::to_string(f) + " has " + std::to_string(static_cast<int64_t>(count)) +
                      " vertices; only triangles are supported");
    for (int k = 0; k < 3; ++k) {
      double index;
      if (!cursor->Read(header.face_index_type, &index)) return DataLoss("PLY face " + std::to_string(f) + " is truncated");
      if (!(index >= 0 && index < num_vertices))
        return DataLoss("PLY face " + std::to_string(f) + " refers to vertex " + std::to_string(static_cast<int64_t>(index)) +
                        " of " + std::to_string(header.num_vertices));
      mesh->triangles[3 * f + k] = static_cast<int32_t>(index);
    }
  }
  return Status::Ok();
}

template <typename Cursor>
Status ReadBody(Cursor* cursor, const Header& header, TriangleMesh* mesh) {
  if (header.vertices_first) {
    VD_RETURN_IF_ERROR(ReadVertices(cursor, header, mesh));
    return ReadFaces(cursor, header, mesh);
  }
  VD_RETURN_IF_ERROR(ReadFaces(cursor, header, mesh));
  return ReadVertices(cursor, header, mesh);
}

StatusOr<TriangleMesh> DecodeUnchecked(const uint8_t* data, size_t size) {
  Header header;
  VD_RETURN_IF_ERROR(ParseHeader(data, size, &header));
  const size_t body = size - header.data_offset;
  const size_t vertex_count = static_cast<size_t>(header.num_vertices);
  const size_t face_count = static_cast<size_t>(header.num_faces);
  TriangleMesh mesh;
  if (header.binary) {
    size_t vertex_bytes = 0;
    for (const VertexProperty& p : header.vertex_properties) vertex_bytes += ScalarBytes(p.type);
    const size_t face_bytes = ScalarBytes(header.face_count_type) + 3 * ScalarBytes(header.face_index_type);
    // Counts are below 2^31 and records below 100 bytes, so these products cannot overflow.
    const size_t expected = vertex_count * vertex_bytes + face_count * face_bytes;
    if (expected > body)
      return DataLoss("PLY body has " + std::to_string(body) + " bytes, the header's counts need " + std::to_string(expected));
    BinaryCursor cursor(data, size, header.data_offset);
    VD_RETURN_IF_ERROR(ReadBody(&cursor, header, &mesh));
    if (cursor.remaining() != 0)
      return DataLoss("PLY has " + std::to_string(cursor.remaining()) + " bytes after the last element");
  } else {
    // Every ASCII value takes at least two characters (digit and separator).
    if (vertex_count * header.vertex_properties.size() * 2 + face_count * 8 > body)
      return DataLoss("PLY body of " + std::to_string(body) + " bytes is too short for the header's counts");
    AsciiCursor cursor(data, size, header.data_offset);
    VD_RETURN_IF_ERROR(ReadBody(&cursor, header, &mesh));
    if (!cursor.AtEnd()) return DataLoss("PLY has data after the last element");
  }
  VD_RETURN_IF_ERROR(mesh.Validate().WithContext("PLY mesh"));
  return mesh;
}

void AppendText(std::vector<uint8_t>* out, const std::string& text) { out->insert(out->end(), text.begin(), text.end()); }

void AppendLe32(std::vector<uint8_t>* out, uint32_t v) {
  for (int k = 0; k < 4; ++k) out->push_back(static_cast<uint8_t>(v >> (8 * k)));
}

void AppendFloat(std::vector<uint8_t>* out, float f) {
  uint32_t bits;
  std::memcpy(&bits, &f, 4);
  AppendLe32(out, bits);
}

}  // namespace

StatusOr<std::vector<uint8_t>> EncodePly(const TriangleMesh& mesh) {
  VD_RETURN_IF_ERROR(mesh.Validate());
  const bool normals = !mesh.normals.empty();
  const bool colors = !mesh.colors.empty();
  std::ostringstream header;
  header << "ply\nformat binary_little_endian 1.0\ncomment vdeform\nelement vertex " << mesh.num_vertices()
         << "\nproperty float x\nproperty float y\nproperty float z\n";
  if (normals) header << "property float nx\nproperty float ny\nproperty float nz\n";
  if (colors) header << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  header << "element face " << mesh.num_triangles() << "\nproperty list uchar int vertex_indices\nend_header\n";
  std::vector<uint8_t> out;
  try {
    out.reserve(header.str().size() + mesh.num_vertices() * (12 + (normals ? 12 : 0) + (colors ? 3 : 0)) +
                mesh.num_triangles() * 13);
    AppendText(&out, header.str());
    for (size_t i = 0; i < mesh.num_vertices(); ++i) {
      for (int k = 0; k < 3; ++k) AppendFloat(&out, mesh.positions[3 * i + k]);
      if (normals)
        for (int k = 0; k < 3; ++k) AppendFloat(&out, mesh.normals[3 * i + k]);
      if (colors)
        for (int k = 0; k < 3; ++k) out.push_back(mesh.colors[3 * i + k]);
    }
    for (size_t f = 0; f < mesh.num_triangles(); ++f) {
      out.push_back(3);
      for (int k = 0; k < 3; ++k) AppendLe32(&out, static_cast<uint32_t>(mesh.triangles[3 * f + k]));
    }
  } catch (const std::exception& e) {
    return Internal(std::string("PLY encoding failed: ") + e.what());
  }
  return out;
}

StatusOr<TriangleMesh> DecodePly(const uint8_t* data, size_t size) {
  if (data == nullptr || size == 0) return DataLoss("PLY buffer is empty");
  try {
    return DecodeUnchecked(data, size);
  } catch (const std::exception& e) {
    return DataLoss(std::string("PLY decoding failed: ") + e.what());
  }
}

Status WritePly(const std::string& path, const TriangleMesh& mesh) {
  VD_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, EncodePly(mesh));
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return NotFound("cannot open '" + path + "' for writing");
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  out.close();
  if (!out) return Internal("writing '" + path + "' failed");
  return Status::Ok();
}

StatusOr<TriangleMesh> ReadPly(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) return NotFound("cannot open PLY file '" + path + "'");
  const std::streamoff size = in.tellg();
  if (size < 0 || size > kMaxPlyFileBytes) return InvalidArgument("PLY file '" + path + "' has an unsupported size");
  std::vector<uint8_t> bytes(static_cast<size_t>(size));
  in.seekg(0);
  if (size > 0 && !in.read(reinterpret_cast<char*>(bytes.data()), size)) return DataLoss("cannot read '" + path + "'");
  auto mesh = DecodePly(bytes.data(), bytes.size());
  if (!mesh.ok()) return mesh.status().WithContext(path);
  return mesh;
}

}  // namespace vd
