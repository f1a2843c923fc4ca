#pragma once
// Shared by the libFuzzer targets: invariant checks that abort (libFuzzer then saves the input as a
// crash), the declared-size prefix the image decoders take, and the checks every decoded LCM
// message and mesh must pass. Header-only so a target is one .cpp file.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include <unistd.h>

#include <opencv2/core.hpp>

#include "vd/common/auth.h"
#include "vd/common/log.h"
#include "vd/common/messages.h"
#include "vd/common/mesh.h"
#include "vd/common/output_auth.h"

// A decoder that accepted its input broke a promise it makes: stop so libFuzzer records the input.
#define VD_FUZZ_CHECK(cond)                                             \
  do {                                                                  \
    if (!(cond)) ::vd::fuzz::InvariantViolated(__FILE__, __LINE__, #cond); \
  } while (0)

namespace vd::fuzz {

// run_fuzz.sh closes the targets' stderr (-close_fd_mask=2), since libpng and libjpeg print a line
// for every bad input. libFuzzer and the sanitizers keep a copy of it, and so does this one, taken
// during static initialisation, before libFuzzer closes it.
inline const int kReportFd = ::dup(2);

[[noreturn]] inline void InvariantViolated(const char* file, int line, const char* condition) {
  ::dprintf(kReportFd >= 0 ? kReportFd : 2, "%s:%d: fuzz invariant violated: %s\n", file, line, condition);
  std::abort();
}

// Decoders log warnings for every bad input; at thousands of inputs per second that is noise.
inline void Quiet() { SetLogLevel(LogLevel::kQuiet); }

// Image decoders are told the size to expect. The first 4 input bytes give it: width and height as
// little-endian int16, so zero, negative and oversized declarations reach the size checks too.
inline constexpr size_t kSizePrefixBytes = 4;

struct SizedInput {
  int width = 0;
  int height = 0;
  const uint8_t* data = nullptr;
  size_t size = 0;
};

inline bool TakeSizePrefix(const uint8_t* data, size_t size, SizedInput* out) {
  if (size < kSizePrefixBytes) return false;
  out->width = static_cast<int16_t>(static_cast<uint16_t>(data[0] | data[1] << 8));
  out->height = static_cast<int16_t>(static_cast<uint16_t>(data[2] | data[3] << 8));
  out->data = data + kSizePrefixBytes;
  out->size = size - kSizePrefixBytes;
  return true;
}

inline std::vector<uint8_t> WithSizePrefix(int width, int height, const std::vector<uint8_t>& payload) {
  std::vector<uint8_t> out = {static_cast<uint8_t>(width), static_cast<uint8_t>(width >> 8),
                              static_cast<uint8_t>(height), static_cast<uint8_t>(height >> 8)};
  out.insert(out.end(), payload.begin(), payload.end());
  return out;
}

inline bool SameImage(const cv::Mat& a, const cv::Mat& b) {
  if (a.type() != b.type() || a.size() != b.size()) return false;
  const size_t row_bytes = static_cast<size_t>(a.cols) * a.elemSize();
  for (int y = 0; y < a.rows; ++y)
    if (std::memcmp(a.ptr(y), b.ptr(y), row_bytes) != 0) return false;
  return true;
}

// Bitwise, so NaN normals (which Validate allows) compare equal to themselves.
template <typename T>
bool SameBits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

inline bool SameMesh(const TriangleMesh& a, const TriangleMesh& b) {
  return SameBits(a.positions, b.positions) && SameBits(a.colors, b.colors) && SameBits(a.normals, b.normals) &&
         SameBits(a.triangles, b.triangles);
}

// What every mesh a decoder returns must satisfy: sound on its own, and the PLY writer and reader
// (used for snapshots and --save-dir) carry it unchanged.
inline void CheckDecodedMesh(const TriangleMesh& mesh) {
  VD_FUZZ_CHECK(mesh.Validate().ok());
  auto ply = EncodePly(mesh);
  VD_FUZZ_CHECK(ply.ok());
  auto back = DecodePly(ply->data(), ply->size());
  VD_FUZZ_CHECK(back.ok());
  VD_FUZZ_CHECK(SameMesh(mesh, *back));
}

// A message DecodeLcm accepted must encode to exactly getEncodedSize() bytes and decode again to
// the same bytes: what the server logs or forwards is what it checked.
template <typename Msg>
void CheckLcmRoundTrip(const Msg& msg) {
  const int size = msg.getEncodedSize();
  VD_FUZZ_CHECK(size > 0);
  std::vector<uint8_t> first(static_cast<size_t>(size));
  VD_FUZZ_CHECK(msg.encode(first.data(), 0, size) == size);
  auto again = DecodeLcm<Msg>(first.data(), first.size());
  VD_FUZZ_CHECK(again.ok());
  VD_FUZZ_CHECK(again->getEncodedSize() == size);
  std::vector<uint8_t> second(static_cast<size_t>(size));
  VD_FUZZ_CHECK(again->encode(second.data(), 0, size) == size);
  VD_FUZZ_CHECK(first == second);
}

// The server's output key that make_seeds.cpp signs the mesh and status seeds with, so the
// fuzzer starts from messages the verifier takes.
inline const std::string kOutputKey(kFrameKeyBytes, 'o');

// The output key's check on a decoded mesh or status (vdeform-viewer --key-file, a lockstep
// capture's --output-key-file): a refusal is PermissionDenied counted under exactly one reason,
// unsigned exactly when auth_size is 0; what it takes was signed under the key (signing it again
// gives the same auth bytes) and is refused as a replay when it comes again.
template <typename Msg>
void CheckOutputVerify(const Msg& msg, const OutputRefusals& (OutputVerifier::*refused)() const,
                       Status (*sign)(const std::string&, Msg*)) {
  OutputVerifier verifier(kOutputKey);
  const OutputCheck first = verifier.Check(msg);
  const OutputRefusals& counts = (verifier.*refused)();
  if (!first.ok()) {
    VD_FUZZ_CHECK(first.status.code() == StatusCode::kPermissionDenied);
    VD_FUZZ_CHECK(counts.total() == 1 && counts.replayed == 0);
    VD_FUZZ_CHECK((first.verdict == OutputVerdict::kUnsigned) == (msg.auth_size == 0));
    VD_FUZZ_CHECK((counts.unsigned_messages == 1) == (msg.auth_size == 0));
    return;
  }
  VD_FUZZ_CHECK(first.status.ok());
  VD_FUZZ_CHECK(counts.total() == 0 && msg.auth_size == 32 && msg.auth.size() == 32);
  Msg again = msg;
  VD_FUZZ_CHECK(sign(kOutputKey, &again).ok());
  VD_FUZZ_CHECK(again.auth == msg.auth);
  VD_FUZZ_CHECK(verifier.Check(msg).verdict == OutputVerdict::kReplayed);
  VD_FUZZ_CHECK(counts.replayed == 1 && counts.total() == 1);
}

}  // namespace vd::fuzz
