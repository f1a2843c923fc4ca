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

std::string OutputRefusals::ToString() const {
  return std::to_string(unsigned_messages) + " unsigned, " + std::to_string(bad_signature) + " bad signature, " +
         std::to_string(replayed) + " replayed";
}

OutputVerifier::OutputVerifier(std::string key) : key_(std::move(key)) { assert(!key_.empty()); }

Status OutputVerifier::Check(const vdeform::mesh_t& msg) {
  // An unsigned message is classified before any hashing (VerifyMesh would not hash it either).
  const Status verified = msg.auth_size == 0 ? Status::Ok() : VerifyMesh(key_, msg);
  return Take(verified, msg.auth_size, msg.epoch, msg.out_seq, msg.utime, "mesh", &mesh_);
}

Status OutputVerifier::Check(const vdeform::server_status_t& msg) {
  const Status verified = msg.auth_size == 0 ? Status::Ok() : VerifyStatus(key_, msg);
  return Take(verified, msg.auth_size, msg.epoch, msg.out_seq, msg.utime, "status", &status_);
}

Status OutputVerifier::Take(const Status& verified, int32_t auth_size, int64_t epoch, int64_t out_seq, int64_t utime,
                            const char* what, Kind* kind) {
  if (auth_size == 0) {
    ++kind->refused.unsigned_messages;
    return PermissionDenied(std::string("unsigned ") + what + " (the server's output must carry an HMAC under the key)");
  }
  if (!verified.ok()) {
    ++kind->refused.bad_signature;
    return PermissionDenied(verified.message());
  }
  if (kind->any) {
    const bool same_run = epoch == kind->epoch;
    if (same_run ? out_seq <= kind->out_seq : utime <= kind->utime) {
      ++kind->refused.replayed;
      return PermissionDenied(std::string(what) + " replayed: " +
                              (same_run ? "out_seq " + std::to_string(out_seq) + " is not after " +
                                              std::to_string(kind->out_seq) + " of this server run"
                                        : "epoch " + std::to_string(epoch) + " is an earlier server run (utime " +
                                              std::to_string(utime) + " not after " + std::to_string(kind->utime) +
                                              ")"));
    }
  }
  kind->any = true;
  kind->epoch = epoch;
  kind->out_seq = out_seq;
  kind->utime = std::max(kind->utime, utime);
  return Status::Ok();
}

}  // namespace vd
