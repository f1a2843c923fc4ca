#include "vd/common/output_auth.h"

#include <algorithm>
#include <cassert>
#include <utility>

#include "vd/common/auth.h"

namespace vd {

OutputRefusals& OutputRefusals::operator+=(const OutputRefusals& other) {
  unsigned_messages += other.unsigned_messages;
  bad_signature += other.bad_signature;
  replayed += other.replayed;
  return *this;
}

void OutputRefusals::Add(OutputVerdict verdict) {
  switch (verdict) {
    case OutputVerdict::kTaken:
      return;
    case OutputVerdict::kUnsigned:
      ++unsigned_messages;
      return;
    case OutputVerdict::kBadSignature:
      ++bad_signature;
      return;
    case OutputVerdict::kReplayed:
      ++replayed;
      return;
  }
}

std::string OutputRefusals::ToString() const {
  return std::to_string(unsigned_messages) + " unsigned, " + std::to_string(bad_signature) + " bad signature, " +
         std::to_string(replayed) + " replayed";
}

const char* OutputVerdictName(OutputVerdict verdict) {
  switch (verdict) {
    case OutputVerdict::kTaken:
      return "taken";
    case OutputVerdict::kUnsigned:
      return "unsigned";
    case OutputVerdict::kBadSignature:
      return "bad signature";
    case OutputVerdict::kReplayed:
      return "replayed";
  }
  return "unknown";
}

OutputVerifier::OutputVerifier(std::string key) : key_(std::move(key)) { assert(!key_.empty()); }

OutputCheck OutputVerifier::Check(const vdeform::mesh_t& msg) {
  // An unsigned message is classified before any hashing (VerifyMesh would not hash it either).
  const Status verified = msg.auth_size == 0 ? Status::Ok() : VerifyMesh(key_, msg);
  return Take(verified, msg.auth_size, msg.epoch, msg.out_seq, msg.utime, "mesh", &mesh_);
}

OutputCheck OutputVerifier::Check(const vdeform::server_status_t& msg) {
  const Status verified = msg.auth_size == 0 ? Status::Ok() : VerifyStatus(key_, msg);
  return Take(verified, msg.auth_size, msg.epoch, msg.out_seq, msg.utime, "status", &status_);
}

OutputCheck OutputVerifier::Take(const Status& verified, int32_t auth_size, int64_t epoch, int64_t out_seq,
                                 int64_t utime, const char* what, Kind* kind) {
  OutputCheck check = Decide(verified, auth_size, epoch, out_seq, utime, what, *kind);
  kind->refused.Add(check.verdict);
  if (!check.ok()) return check;
  kind->any = true;
  kind->epoch = epoch;
  kind->out_seq = out_seq;
  kind->utime = std::max(kind->utime, utime);
  return check;
}

OutputCheck OutputVerifier::Decide(const Status& verified, int32_t auth_size, int64_t epoch, int64_t out_seq,
                                   int64_t utime, const char* what, const Kind& kind) {
  if (auth_size == 0)
    return {OutputVerdict::kUnsigned,
            PermissionDenied(std::string("unsigned ") + what + " (the server's output must carry an HMAC under the key)")};
  if (!verified.ok()) return {OutputVerdict::kBadSignature, PermissionDenied(verified.message())};
  if (!kind.any) return {};
  if (epoch == kind.epoch && out_seq <= kind.out_seq)
    return {OutputVerdict::kReplayed, PermissionDenied(std::string(what) + " replayed: out_seq " +
                                                       std::to_string(out_seq) + " is not after " +
                                                       std::to_string(kind.out_seq) + " of this server run")};
  // Epochs are random; a restarted server's messages are later than any of its earlier run's.
  if (epoch != kind.epoch && utime <= kind.utime)
    return {OutputVerdict::kReplayed,
            PermissionDenied(std::string(what) + " replayed: epoch " + std::to_string(epoch) +
                             " is an earlier server run (utime " + std::to_string(utime) + " not after " +
                             std::to_string(kind.utime) + ")")};
  return {};
}

}  // namespace vd
