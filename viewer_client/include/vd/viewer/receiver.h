#pragma once
// The viewer's receiving side: subscribes to the server's meshes and status on one LCM instance,
// decodes and keeps the latest live and canonical meshes, saves PLY files and CPU-rendered PNGs,
// and asks the server for its current meshes at start-up so a late joiner shows them at once.
// Bad messages are counted and logged once per kind; nothing thrown escapes a handler.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>
#include <vdeform/mesh_t.hpp>
#include <vdeform/server_status_t.hpp>

#include "vd/common/mesh.h"
#include "vd/common/messages.h"
#include "vd/common/output_auth.h"
#include "vd/common/status.h"
#include "vd/viewer/render.h"

namespace vd {

struct ReceiverOptions {
  // Directory for frame-%06d.mesh.ply / .canonical.ply / .png and final.png; empty saves nothing.
  // Created when missing.
  std::string save_dir;
  // Also write CPU-rendered PNGs of every live mesh (needs save_dir).
  bool write_png = false;
  // Size and look of the PNGs.
  RenderOptions render;
  // Colouring of the PNGs; kCanonical falls back to the mesh colour without a matching canonical.
  ColorMode color_mode = ColorMode::kCanonical;
  // Publish COMMAND_REQUEST_MESH on creation (and once more when the server first shows up),
  // so a viewer that joins late does not wait for the next processed frame.
  bool request_mesh = true;
  // The stream's channels (--stream NAME; today's names by default).
  StreamChannels channels;
  // control_t.sender, so the server's log says who asked.
  std::string sender = "vdeform-viewer";
  // Mesh messages LCM keeps queued while we render or write (its own default is 30; beyond the
  // capacity it drops). Saving wants a deeper queue than showing: 0 keeps LCM's default.
  int mesh_queue_capacity = 0;
  // The server's output key (--key-file, ReadOutputKey): only meshes and status that verify under
  // it and are newer than the last one taken are shown and saved; the others are counted by
  // reason. Empty: every message is taken, as without signing.
  std::string output_key;
  Status Validate() const;
};

struct ReceiverStats {
  // Messages on the mesh channel, decodable or not.
  int64_t mesh_messages = 0;
  // Meshes decoded and kept (repeats included).
  int64_t meshes_decoded = 0;
  // Mesh messages refused: malformed wire bytes, bad fields, undecodable Draco/PLY data.
  int64_t meshes_failed = 0;
  // New LIVE meshes (repeats of the seq already held are not counted).
  int64_t live_meshes = 0;
  // New CANONICAL meshes.
  int64_t canonical_meshes = 0;
  // TRACKED meshes (a server with --track-mesh): saved with --save-dir, not shown.
  int64_t tracked_meshes = 0;
  // Vertex count of the latest tracked mesh (constant over a run).
  int64_t last_tracked_vertices = 0;
  // Meshes whose kind and seq equal those already held: answers to some viewer's REQUEST_MESH.
  int64_t repeated_meshes = 0;
  // Wire bytes of all mesh messages.
  int64_t mesh_bytes = 0;
  // seq of the latest live mesh (-1: none yet).
  int64_t last_live_seq = -1;
  // Size of the latest live mesh.
  int64_t last_live_vertices = 0;
  int64_t last_live_triangles = 0;
  // Status messages decoded / refused.
  int64_t status_messages = 0;
  int64_t status_failed = 0;
  // REQUEST_MESH control messages published.
  int64_t requests_sent = 0;
  // Files written / writes that failed (disk full, permissions).
  int64_t files_written = 0;
  int64_t write_failures = 0;
  // Handler failures other than the above (allocation, OpenCV), counted so none goes unseen.
  int64_t internal_errors = 0;
  // Whether an output key checks what arrives (ReceiverOptions::output_key).
  bool verifying = false;
  // Meshes and status messages that decoded but were refused under the output key, by reason
  // (not counted as decoded or failed above; nothing of them is shown or saved).
  OutputRefusals meshes_refused;
  OutputRefusals status_refused;
};

struct RunOptions {
  // Return once stats().live_meshes reaches this (new live meshes, repeats not counted); 0: no limit.
  int64_t count = 0;
  // Fail with DeadlineExceeded when neither a mesh nor a status message arrived for this many
  // seconds; 0: wait forever.
  double timeout_s = 0.0;
  // Longest wait inside LCM per iteration; bounds how late stop requests and ticks are seen.
  int poll_ms = 100;
  Status Validate() const;
};

class MeshReceiver {
 public:
  using Clock = std::chrono::steady_clock;

  // `lcm` must outlive the receiver. Subscribes to the mesh and status channels, creates
  // save_dir, and publishes a REQUEST_MESH unless options.request_mesh is false (a failure to
  // publish is logged, not fatal: a log being replayed cannot take requests).
  static StatusOr<std::unique_ptr<MeshReceiver>> Create(lcm::LCM* lcm, const ReceiverOptions& options);
  ~MeshReceiver();
  MeshReceiver(const MeshReceiver&) = delete;
  MeshReceiver& operator=(const MeshReceiver&) = delete;

  // Publishes control_t COMMAND_REQUEST_MESH on the stream's control channel.
  Status RequestMesh();
  // Dispatches what arrives within timeout_ms (0: only what is already queued).
  Status Poll(int timeout_ms);
  // Polls until `count` new live meshes arrived, *stop became true (Ok) or nothing arrived for
  // timeout_s (DeadlineExceeded). `tick` (may be empty) runs after every poll: status lines, the
  // window. Call Finish() afterwards.
  Status Run(const RunOptions& options, const std::atomic<bool>* stop, const std::function<void()>& tick);
  // Writes the PNG still waiting for its canonical mesh and final.png of the latest live mesh.
  // Returns the first write error, after trying every write.
  Status Finish();

  const ReceiverStats& stats() const { return stats_; }
  // The latest server status, if one arrived.
  const std::optional<vdeform::server_status_t>& last_status() const { return last_status_; }
  // The latest live / canonical mesh and its seq (null / -1 before the first).
  const TriangleMesh* live_mesh() const { return live_ ? &*live_ : nullptr; }
  int64_t live_seq() const { return live_seq_; }
  const TriangleMesh* canonical_mesh() const { return canonical_ ? &*canonical_ : nullptr; }
  int64_t canonical_seq() const { return canonical_seq_; }
  // Grows whenever the live or canonical mesh changes, so a display re-renders only then.
  int64_t version() const { return version_; }
  // Every file written, in order.
  const std::vector<std::string>& written_paths() const { return written_paths_; }
  // When the last mesh or status message arrived (creation time before the first); with an output
  // key, the last one taken (forged traffic does not keep a run from timing out).
  Clock::time_point last_message_time() const { return last_message_time_; }

 private:
  MeshReceiver(lcm::LCM* lcm, const ReceiverOptions& options);
  void OnMesh(const lcm::ReceiveBuffer* buffer, const std::string& channel);
  void OnStatus(const lcm::ReceiveBuffer* buffer, const std::string& channel);
  void HandleMesh(const lcm::ReceiveBuffer* buffer);
  void HandleStatus(const lcm::ReceiveBuffer* buffer);
  // Renders the held live mesh (canonical colouring if it matches) to path.
  Status WritePng(const std::string& path);
  Status WriteMeshPly(const TriangleMesh& mesh, const std::string& path);
  // Renders the live frame whose PNG was deferred until its canonical mesh could arrive.
  void FlushPendingPng();
  std::string FramePath(int64_t seq, const char* suffix) const;
  // Logs the first failure of each kind as a warning; later ones are only counted.
  void LogOnce(const std::string& kind, const Status& status);

  lcm::LCM* lcm_;
  ReceiverOptions options_;
  lcm::Subscription* mesh_subscription_ = nullptr;
  lcm::Subscription* status_subscription_ = nullptr;
  ReceiverStats stats_;
  std::optional<vdeform::server_status_t> last_status_;
  std::optional<TriangleMesh> live_;
  int64_t live_seq_ = -1;
  std::optional<TriangleMesh> canonical_;
  int64_t canonical_seq_ = -1;
  int64_t version_ = 0;
  // The live frame's PNG waits for the canonical mesh of the same seq (the server may publish
  // it right after the live one) until the next live mesh or Finish().
  bool png_pending_ = false;
  std::vector<std::string> written_paths_;
  std::set<std::string> logged_kinds_;
  Clock::time_point last_message_time_;
  // Checks meshes and status under options_.output_key; unset without a key.
  std::optional<OutputVerifier> verifier_;
};

}  // namespace vd
