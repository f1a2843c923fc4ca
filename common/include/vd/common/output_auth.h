#pragma once
// What a receiver of the server's output (vdeform-viewer, vdeform-web, a lockstep vdeform-capture)
// does with a mesh or status under the server's output key: it takes only messages that verify and
// are newer than the last one it took of the same kind, and counts the others by reason.
#include <cstdint>
#include <string>

#include <vdeform/mesh_t.hpp>
#include <vdeform/server_status_t.hpp>

#include "vd/common/status.h"

namespace vd {

// What OutputVerifier::Check decided about one message.
enum class OutputVerdict { kTaken, kUnsigned, kBadSignature, kReplayed };
// "taken", "unsigned", "bad signature", "replayed".
const char* OutputVerdictName(OutputVerdict verdict);

// Messages of one kind refused under the output key, by reason.
struct OutputRefusals {
  // auth_size 0: no signature at all (a forger without the key, or a server without the key).
  int64_t unsigned_messages = 0;
  // A signature that does not verify under the key: forged, corrupted, or a server with another key.
  int64_t bad_signature = 0;
  // Verifies, but is not newer than the last message taken: an out_seq not after the last one of
  // the same epoch, or another epoch whose utime is not after the last one taken (an earlier
  // server run played back; a real restart is later).
  int64_t replayed = 0;

  int64_t total() const { return unsigned_messages + bad_signature + replayed; }
  // Counts a refusal under its reason (kTaken counts nothing).
  void Add(OutputVerdict verdict);
  OutputRefusals& operator+=(const OutputRefusals& other);
  // "2 unsigned, 1 bad signature, 0 replayed".
  std::string ToString() const;
};

struct OutputCheck {
  OutputVerdict verdict = OutputVerdict::kTaken;
  // Ok when taken; PermissionDenied saying why otherwise (for the receiver's log).
  Status status;
  bool ok() const { return verdict == OutputVerdict::kTaken; }
};

class OutputVerifier {
 public:
  // `key`: the output key's bytes (ReadOutputKey); it must not be empty.
  explicit OutputVerifier(std::string key);

  // Taken when the message verifies and is newer than the last one of its kind taken (it becomes
  // the last); otherwise refused, saying why, and counted in mesh_refused() / status_refused().
  OutputCheck Check(const vdeform::mesh_t& msg);
  OutputCheck Check(const vdeform::server_status_t& msg);

  const OutputRefusals& mesh_refused() const { return mesh_.refused; }
  const OutputRefusals& status_refused() const { return status_.refused; }

 private:
  // The last message taken of one kind (meshes and status arrive on separate channels, so their
  // orders are checked apart), and what was refused of that kind.
  struct Kind {
    bool any = false;
    int64_t epoch = 0;
    int64_t out_seq = 0;
    // The newest utime taken: orders epochs, which are random.
    int64_t utime = 0;
    OutputRefusals refused;
  };
  // Decides (Decide), counts the refusal or makes the message the kind's last.
  OutputCheck Take(const Status& verified, int32_t auth_size, int64_t epoch, int64_t out_seq, int64_t utime,
                   const char* what, Kind* kind);
  static OutputCheck Decide(const Status& verified, int32_t auth_size, int64_t epoch, int64_t out_seq, int64_t utime,
                            const char* what, const Kind& kind);

  std::string key_;
  Kind mesh_;
  Kind status_;
};

}  // namespace vd
