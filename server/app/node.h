#pragma once
// The LCM node: frames in, meshes and status out. A receive thread validates frames into a
// one-slot mailbox (a newer frame replaces an unprocessed one, counted as dropped); the worker
// runs the engine on the newest frame. No exception or bad message reaches past a handler.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "core/checkpoint.h"
#include "core/engine.h"
#include "gate.h"
#include "server_options.h"
#include "stats.h"
#include "vd/common/log.h"
#include "vd/common/messages.h"

namespace vd {

int64_t NowUs();
// Keeps a relative snapshot name inside the snapshot directory.
StatusOr<std::filesystem::path> SnapshotPath(const std::string& dir, const std::string& name);

class Node {
 public:
  Node(const ServerOptions& options, lcm::LCM* lcm, std::unique_ptr<Engine> engine, GateOptions gate = {})
      : options_(options), lcm_(lcm), engine_(std::move(engine)), gate_(std::move(gate)) {}

  void OnFrame(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    std::lock_guard<std::mutex> lock(mutex_);
    FrameDecision d = gate_.OnFrame(rbuf->data, rbuf->data_size);
    switch (d.verdict) {
      case FrameVerdict::kRejected:
        return Reject(d.status, d.reason);
      case FrameVerdict::kStale:
        // Re-sent or reordered: an older view of the scene than the model already holds.
        return;
      case FrameVerdict::kForeign:
        if (gate_.counters().foreign == 1) VD_LOG_WARNING << "ignoring frames: " << d.status.message();
        return;
      case FrameVerdict::kAccept:
        break;
    }
    if (mailbox_) ++dropped_;
    mailbox_ = std::move(d.frame);
    // Feature detection starts now, beside the frame the worker may be solving.
    engine_->Prefetch(*mailbox_);
    cv_.notify_one();
  }

  void OnControl(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    std::lock_guard<std::mutex> lock(mutex_);
    ControlDecision d = gate_.OnControl(rbuf->data, rbuf->data_size, NowUs());
    if (!d.status.ok()) {
      VD_LOG_WARNING << "control command refused (from '" << d.msg.sender << "'): " << d.status.ToString();
      return;
    }
    const auto* msg = &d.msg;
    switch (msg->command) {
      case vdeform::control_t::COMMAND_RESET:
        reset_requested_ = true;
        cv_.notify_one();
        break;
      case vdeform::control_t::COMMAND_SAVE_SNAPSHOT:
        snapshot_requests_.push_back(msg->path);
        cv_.notify_one();
        break;
      case vdeform::control_t::COMMAND_REQUEST_MESH:
        mesh_requested_ = true;
        break;
      default:
        break;  // the gate refuses unknown commands
    }
  }

  // Worker: runs the engine on the newest frame until *stop.
  void Work(const std::atomic<bool>* stop) {
    while (!*stop) {
      {
        std::unique_lock<std::mutex> lock(mutex_);
        cv_.wait_for(lock, std::chrono::milliseconds(100),
                     [&] { return mailbox_.has_value() || reset_requested_ || !snapshot_requests_.empty() || *stop; });
      }
      RunOnce();
    }
  }

  // One step of the worker: a pending reset, snapshots, then the waiting frame. Returns whether a
  // frame was processed. Tests call it directly.
  bool RunOnce() {
    MaybeCheckpoint(false);
    std::optional<RgbdFrame> frame;
    bool reset = false;
    std::vector<std::string> snapshots;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      frame.swap(mailbox_);
      reset = reset_requested_;
      reset_requested_ = false;
      snapshots.swap(snapshot_requests_);
    }
    if (reset) {
      engine_->Reset();
      std::lock_guard<std::mutex> lock(mutex_);
      last_live_.reset();
      last_canonical_.reset();
      model_frames_ = 0;
      state_ = vdeform::server_status_t::STATE_IDLE;
      message_ = "reset";
      VD_LOG_INFO << "model reset";
    }
    for (const auto& name : snapshots) {
      Snapshot(name);
      // A snapshot request is also a checkpoint request.
      MaybeCheckpoint(true);
    }
    if (frame) Process(*frame);
    return frame.has_value();
  }

  // Publishes status, and meshes on request; called from the receive loop.
  void Tick() {
    const auto now = std::chrono::steady_clock::now();
    bool send_meshes = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      send_meshes = mesh_requested_;
      mesh_requested_ = false;
    }
    if (send_meshes) PublishMeshes(true);
    if (now - last_status_ > std::chrono::milliseconds(500)) PublishStatus();
  }

  // Publishes a status message now (tests; the loop publishes twice a second via Tick).
  void PublishStatusNow() { PublishStatus(); }

  // Loads the newest valid checkpoint of --checkpoint DIR into the engine (--resume). Returns
  // false when one was refused or could not be restored (the server then starts a new model and
  // says so in the status); true when loaded or when there was none.
  bool Resume() {
    ResumeResult r = LoadLatestCheckpoint(options_.checkpoint_dir);
    std::string problems;
    for (const auto& p : r.problems) {
      VD_LOG_ERROR << "checkpoint refused: " << p;
      problems += (problems.empty() ? "" : "; ") + p;
    }
    if (!r.state) {
      if (r.problems.empty()) VD_LOG_INFO << "no checkpoint in '" << options_.checkpoint_dir << "'; starting a new model";
      std::lock_guard<std::mutex> lock(mutex_);
      checkpoint_message_ = problems.empty() ? "" : "resume failed: " + problems;
      return r.problems.empty();
    }
    FrameResult meshes;
    Status s = engine_->RestoreState(*r.state, &meshes);
    std::lock_guard<std::mutex> lock(mutex_);
    if (!s.ok()) {
      VD_LOG_ERROR << "cannot resume from " << r.loaded_path << ": " << s.ToString();
      checkpoint_message_ = "resume failed: " + s.message();
      return false;
    }
    model_frames_ = r.state->frames_fused;
    last_processed_seq_ = r.state->last_seq;
    last_source_id_ = r.state->source_id;
    auto live = MeshToMessage(meshes.live_mesh, NowUs(), r.state->last_seq, vdeform::mesh_t::KIND_LIVE);
    auto canonical = MeshToMessage(meshes.canonical_mesh, NowUs(), r.state->last_seq, vdeform::mesh_t::KIND_CANONICAL);
    if (live.ok()) last_live_ = std::move(live).value();
    if (canonical.ok()) last_canonical_ = std::move(canonical).value();
    canonical_changed_ = true;
    state_ = vdeform::server_status_t::STATE_TRACKING;
    message_ = "resumed";
    checkpoint_message_ = "resumed from " + r.loaded_path + (problems.empty() ? "" : " after refusing: " + problems);
    VD_LOG_INFO << "resumed " << model_frames_ << " fused frames from " << r.loaded_path << " ("
                << meshes.live_mesh.num_triangles() << " triangles)";
    return problems.empty();
  }

  // Writes a checkpoint when --checkpoint is set, the model changed since the last one, and
  // `force` or the interval has passed. Called by the worker between frames, and at shutdown.
  void MaybeCheckpoint(bool force) {
    if (options_.checkpoint_dir.empty() || !engine_->has_model()) return;
    const auto now = std::chrono::steady_clock::now();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!model_dirty_) return;
      if (!force && (options_.checkpoint_interval <= 0 ||
                     now - last_checkpoint_ < std::chrono::duration<double>(options_.checkpoint_interval)))
        return;
    }
    const auto t0 = std::chrono::steady_clock::now();
    EngineState state;
    Status s = engine_->SaveState(&state);
    size_t bytes = 0;
    int64_t frames = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      state.last_seq = last_processed_seq_;
      state.source_id = last_source_id_;
      frames = model_frames_;
    }
    if (s.ok()) s = WriteCheckpoint(options_.checkpoint_dir, state, &bytes);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    std::lock_guard<std::mutex> lock(mutex_);
    last_checkpoint_ = now;
    if (!s.ok()) {
      checkpoint_message_ = "checkpoint failed: " + s.message();
      VD_LOG_ERROR << checkpoint_message_;
      return;
    }
    model_dirty_ = false;
    checkpoint_utime_ = NowUs();
    ++checkpoints_written_;
    checkpoint_message_ = "checkpoint of " + std::to_string(frames) + " frames, " + std::to_string(bytes >> 10) +
                          " KiB, " + std::to_string(int(ms)) + " ms";
    VD_LOG_DEBUG << checkpoint_message_;
  }

  int64_t checkpoints_written() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return checkpoints_written_;
  }
  GateCounters gate_counters() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return gate_.counters();
  }

  void PrintSummary() const {
    std::lock_guard<std::mutex> lock(mutex_);
    const GateCounters& g = gate_.counters();
    std::printf("vdeform-server: received %lld, processed %lld, dropped %lld, rejected %lld, duplicate %lld, "
                "reordered %lld, lost %lld, foreign %lld frames; %lld control commands refused\n",
                (long long)g.received, (long long)processed_, (long long)dropped_, (long long)rejected_,
                (long long)g.duplicates, (long long)g.reordered, (long long)g.lost, (long long)g.foreign,
                (long long)g.control_refused);
    if (stats_.count()) std::printf("stages (mean ms): %s\n", stats_.Summary().c_str());
  }

 private:
  // Counts a refused frame under `reason` (derived from the error when empty); logs each reason once.
  void Reject(const Status& s, const std::string& given_reason = "") {
    ++rejected_;
    const std::string reason = given_reason.empty() ? RejectReason(s) : given_reason;
    if (reject_counts_[reason]++ == 0) VD_LOG_WARNING << "rejected a frame (" << reason << "): " << s.ToString();
  }

  void Process(const RgbdFrame& frame) {
    const auto t0 = std::chrono::steady_clock::now();
    auto result = engine_->Process(frame);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    std::unique_lock<std::mutex> lock(mutex_);
    if (!result.ok()) {
      // Bad input the validation could not see (e.g. a size change): counted, the model kept.
      Reject(result.status());
      message_ = result.status().ToString();
      return;
    }
    ++processed_;
    if (result->tracking_ok) {
      ++model_frames_;
      model_dirty_ = true;
    }
    last_processed_seq_ = frame.seq;
    last_source_id_ = frame.source_id;
    stats_.Add(result->times, ms);
    process_times_.push_back(std::chrono::steady_clock::now());
    while (process_times_.size() > 30) process_times_.pop_front();
    state_ = result->tracking_ok ? vdeform::server_status_t::STATE_TRACKING : vdeform::server_status_t::STATE_TRACKING_LOST;
    message_ = result->tracking_ok ? engine_->DeviceDescription() : result->tracking_message;
    dense_ = result->dense_correspondences;
    sparse_ = result->sparse_matches;
    energy_initial_ = float(result->energy_initial);
    energy_final_ = float(result->energy_final);
    active_voxels_ = result->active_voxels;
    auto live = MeshToMessage(result->live_mesh, NowUs(), frame.seq, vdeform::mesh_t::KIND_LIVE);
    auto canonical = MeshToMessage(result->canonical_mesh, NowUs(), frame.seq, vdeform::mesh_t::KIND_CANONICAL);
    if (live.ok()) last_live_ = std::move(live).value();
    else VD_LOG_WARNING << "cannot encode live mesh: " << live.status().ToString();
    if (canonical.ok()) last_canonical_ = std::move(canonical).value();
    canonical_changed_ = true;
    lock.unlock();
    PublishMeshes(false);
    PublishStatus();
  }

  // The live mesh always; the canonical one when it changed, at most once a second, or on request.
  void PublishMeshes(bool force_canonical) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (last_live_) lcm_->publish(kMeshChannel, &*last_live_);
    const auto now = std::chrono::steady_clock::now();
    if (last_canonical_ && (force_canonical || (canonical_changed_ && now - last_canonical_sent_ > std::chrono::seconds(1)))) {
      lcm_->publish(kMeshChannel, &*last_canonical_);
      last_canonical_sent_ = now;
      canonical_changed_ = false;
    }
  }

  void PublishStatus() {
    vdeform::server_status_t st;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      st.utime = NowUs();
      st.state = state_;
      st.message = message_;
      st.frames_received = gate_.counters().received;
      st.frames_processed = processed_;
      st.frames_dropped = dropped_;
      st.frames_rejected = rejected_;
      for (const auto& [reason, n] : reject_counts_) {
        st.reject_reason.push_back(reason);
        st.reject_count.push_back(n);
      }
      st.num_reject_reasons = int32_t(st.reject_reason.size());
      const GateCounters& g = gate_.counters();
      st.frames_duplicate = g.duplicates;
      st.frames_reordered = g.reordered;
      st.frames_lost = g.lost;
      st.frames_foreign = g.foreign;
      st.source_restarts = g.source_restarts;
      st.control_refused = g.control_refused;
      st.model_frames = model_frames_;
      st.checkpoint_utime = checkpoint_utime_;
      st.checkpoint_message = checkpoint_message_;
      st.last_processed_seq = last_processed_seq_;
      st.last_source_id = last_source_id_;
      for (int s = 0; s < StageTimes::kCount; ++s) {
        st.stage_name.push_back(StageTimes::kNames[s]);
        st.stage_ms_last.push_back(float(stats_.count() ? stats_.last().ms[s] : 0.0));
        st.stage_ms_mean.push_back(float(stats_.Mean(s)));
      }
      st.num_stages = StageTimes::kCount;
      st.fps = 0.f;
      if (process_times_.size() >= 2) {
        const double span = std::chrono::duration<double>(process_times_.back() - process_times_.front()).count();
        if (span > 0) st.fps = float((process_times_.size() - 1) / span);
      }
      st.active_voxels = active_voxels_;
      st.dense_correspondences = dense_;
      st.sparse_correspondences = sparse_;
      st.energy_initial = energy_initial_;
      st.energy_final = energy_final_;
      st.resident_memory_bytes = ResidentBytes();
      last_status_ = std::chrono::steady_clock::now();
    }
    lcm_->publish(kStatusChannel, &st);
  }

  void Snapshot(const std::string& name) {
    auto path = SnapshotPath(options_.snapshot_dir, name);
    if (!path.ok()) {
      VD_LOG_WARNING << "SAVE_SNAPSHOT refused: " << path.status().message();
      return;
    }
    std::optional<vdeform::mesh_t> live, canonical;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      live = last_live_;
      canonical = last_canonical_;
    }
    std::error_code ec;
    std::filesystem::create_directories(*path, ec);
    Status s = ec ? Unavailable("cannot create '" + path->string() + "': " + ec.message()) : Status::Ok();
    auto write_mesh = [&](const std::optional<vdeform::mesh_t>& m, const char* file) {
      if (!s.ok() || !m) return;
      auto mesh = MessageToMesh(*m);
      s = mesh.ok() ? WritePly((*path / file).string(), *mesh) : mesh.status();
    };
    write_mesh(live, "live.ply");
    write_mesh(canonical, "canonical.ply");
    if (s.ok() && engine_->has_model()) {
      std::vector<float> tsdf, weight;
      std::vector<uint32_t> color;
      s = engine_->DownloadVolume(&tsdf, &weight, &color);
      if (s.ok()) {
        // Written whole, then renamed: a reader never sees a torn file.
        const VdVolume v = engine_->volume();
        s = WriteFileAtomically(*path / "volume.bin", [&](std::ostream& out) {
          out.write("VDVOL001", 8);
          out.write(reinterpret_cast<const char*>(&v), sizeof(v));
          out.write(reinterpret_cast<const char*>(tsdf.data()), std::streamsize(tsdf.size() * sizeof(float)));
          out.write(reinterpret_cast<const char*>(weight.data()), std::streamsize(weight.size() * sizeof(float)));
          out.write(reinterpret_cast<const char*>(color.data()), std::streamsize(color.size() * sizeof(uint32_t)));
        });
      }
    }
    if (s.ok()) VD_LOG_INFO << "snapshot written to " << path->string();
    else VD_LOG_WARNING << "snapshot failed: " << s.ToString();
  }

  const ServerOptions& options_;
  lcm::LCM* lcm_;
  std::unique_ptr<Engine> engine_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::optional<RgbdFrame> mailbox_;
  bool reset_requested_ = false;
  bool mesh_requested_ = false;
  std::vector<std::string> snapshot_requests_;
  FrameGate gate_;
  // Frames received are counted by the gate; these are what became of them after it.
  int64_t processed_ = 0, dropped_ = 0, rejected_ = 0;
  // Frames fused into the current model (continued across --resume); whether it changed since
  // the last checkpoint.
  int64_t model_frames_ = 0;
  bool model_dirty_ = false;
  int64_t checkpoints_written_ = 0;
  int64_t checkpoint_utime_ = 0;
  std::string checkpoint_message_;
  std::chrono::steady_clock::time_point last_checkpoint_ = std::chrono::steady_clock::now();
  std::map<std::string, int64_t> reject_counts_;
  int64_t last_processed_seq_ = -1;
  std::string last_source_id_;
  int8_t state_ = vdeform::server_status_t::STATE_IDLE;
  std::string message_ = "waiting for frames";
  StageStats stats_;
  std::deque<std::chrono::steady_clock::time_point> process_times_;
  int32_t dense_ = 0;
  int32_t sparse_ = 0;
  float energy_initial_ = 0.f;
  float energy_final_ = 0.f;
  int64_t active_voxels_ = 0;
  std::optional<vdeform::mesh_t> last_live_, last_canonical_;
  bool canonical_changed_ = false;
  std::chrono::steady_clock::time_point last_canonical_sent_{};
  std::chrono::steady_clock::time_point last_status_{};
};


}  // namespace vd
