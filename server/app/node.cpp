#include "node.h"

#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <malloc.h>
#include <deque>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "core/checkpoint.h"
#include "prefetch_policy.h"
#include "snapshot.h"
#include "stats.h"
#include "vd/common/auth.h"
#include "vd/common/log.h"
#include "vd/common/lcm_guard.h"
#include "vd/common/messages.h"
#include "vd/common/thread_name.h"

namespace vd {
namespace {

using Clock = std::chrono::steady_clock;

std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop = true; }

double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace

int64_t NowUs() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

class Node::Impl {
 public:
  Impl(const ServerOptions& options, lcm::LCM* lcm, std::unique_ptr<Engine> engine, GateOptions gate,
       std::string output_key)
      : options_(options),
        channels_(*ChannelsOfStream(options.stream)),
        lcm_(lcm),
        engine_(std::move(engine)),
        gate_(std::move(gate)),
        output_key_(std::move(output_key)),
        scheduler_(!options.checkpoint_dir.empty(), options.checkpoint_interval, Clock::now()) {}

  void OnFrame(const lcm::ReceiveBuffer* rbuf) {
    std::lock_guard<std::mutex> lock(mutex_);
    FrameDecision d = gate_.OnFrame(rbuf->data, rbuf->data_size);
    switch (d.verdict) {
      case FrameVerdict::kRejected:
        return Reject(d.status, d.reason);
      case FrameVerdict::kStale:
        // Re-sent or reordered: an older view of the scene than the model already holds.
        return;
      case FrameVerdict::kHeld:
        if (gate_.counters().held == 1) VD_LOG_WARNING << d.status.message();
        return;
      case FrameVerdict::kRateLimited:
        if (gate_.counters().rate_limited == 1) VD_LOG_WARNING << "dropping frames: " << d.status.message();
        return;
      case FrameVerdict::kForeign:
        if (gate_.counters().foreign == 1) VD_LOG_WARNING << "ignoring frames: " << d.status.message();
        return;
      case FrameVerdict::kAccept:
        break;
    }
    if (mailbox_) ++dropped_;
    mailbox_ = std::move(d.frame);
    // Feature detection starts now, beside the frame the worker is solving, when this frame is
    // likely the one the worker takes next (PrefetchPolicy).
    if (prefetch_.OnArrival(Clock::now())) engine_->Prefetch(*mailbox_);
    cv_.notify_one();
  }

  void OnControl(const lcm::ReceiveBuffer* rbuf) {
    std::lock_guard<std::mutex> lock(mutex_);
    ControlDecision d = gate_.OnControl(rbuf->data, rbuf->data_size, NowUs());
    if (!d.status.ok()) {
      VD_LOG_WARNING << "control command refused (from '" << d.msg.sender << "'): " << d.status.ToString();
      return;
    }
    switch (d.msg.command) {
      case vdeform::control_t::COMMAND_RESET:
        reset_requested_ = true;
        cv_.notify_one();
        break;
      case vdeform::control_t::COMMAND_SAVE_SNAPSHOT:
        snapshot_requests_.push_back(d.msg.path);
        cv_.notify_one();
        break;
      case vdeform::control_t::COMMAND_REQUEST_MESH:
        break;  // the gate keeps it; Tick serves it (TakeMeshRequest)
      default:
        break;  // the gate refuses unknown commands
    }
  }

  Status Serve(const std::atomic<bool>* stop) {
    // The worker also stops when receiving fails, which *stop (the caller's) does not say.
    std::atomic<bool> done{false};
    // This thread receives (and decodes); the OpenCL runtime's threads, started before, keep the
    // program's name.
    NameThisThread("vd-receive");
    async_output_ = true;
    std::thread output([&] {
      NameThisThread("vd-output");
      OutputLoop();
    });
    std::thread worker([&] {
      NameThisThread("vd-worker");
      Work(&done);
    });
    Status status = Status::Ok();
    while (!*stop) {
      errno = 0;
      // select() returns EINTR when a signal arrives while it waits: a SIGINT or SIGTERM that sets
      // *stop, or any other handled signal; neither is a failure of LCM.
      if (lcm_->handleTimeout(50) < 0 && errno != EINTR) {
        status = Unavailable(std::string("LCM receive failed: ") + (errno ? std::strerror(errno) : "lcm_handle"));
        break;
      }
      Tick();
    }
    done = true;
    worker.join();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      output_stop_ = true;
    }
    output_cv_.notify_all();
    output.join();
    async_output_ = false;
    MaybeCheckpoint(CheckpointTrigger::kShutdown);
    return status;
  }

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

  bool RunOnce() {
    MaybeCheckpoint(CheckpointTrigger::kInterval);
    std::optional<RgbdFrame> frame;
    bool reset = false;
    std::vector<std::string> snapshots;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      frame.swap(mailbox_);
      if (frame) prefetch_.WorkerStarted(Clock::now());
      reset = reset_requested_;
      reset_requested_ = false;
      snapshots.swap(snapshot_requests_);
    }
    if (reset) {
      engine_->Reset();
      std::lock_guard<std::mutex> lock(mutex_);
      last_live_.reset();
      last_canonical_.reset();
      canonical_pending_.reset();
      model_frames_ = 0;
      state_ = vdeform::server_status_t::STATE_IDLE;
      message_ = "reset";
      VD_LOG_INFO << "model reset";
    }
    for (const auto& name : snapshots) Snapshot(name);
    if (frame) {
      Process(*frame);
      std::lock_guard<std::mutex> lock(mutex_);
      prefetch_.WorkerFinished(Clock::now());
    }
    return frame.has_value();
  }

  void Tick() {
    bool send_meshes = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      send_meshes = gate_.TakeMeshRequest();
    }
    if (send_meshes) PublishMeshes(true);
    if (Clock::now() - last_status_ > std::chrono::milliseconds(500)) PublishStatus();
  }

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
    last_processed_seq_ = published_seq_ = r.state->last_seq;
    last_source_id_ = r.state->source_id;
    const size_t triangles = meshes.live_mesh.num_triangles();
    KeepMeshes(EncodeLive(&meshes, r.state->last_seq), &meshes, r.state->last_seq);
    state_ = vdeform::server_status_t::STATE_TRACKING;
    message_ = "resumed";
    checkpoint_message_ = "resumed from " + r.loaded_path + (problems.empty() ? "" : " after refusing: " + problems);
    VD_LOG_INFO << "resumed " << model_frames_ << " fused frames from " << r.loaded_path << " ("
                << triangles << " triangles)";
    return problems.empty();
  }

  // `saved`: the model as SaveModel took it just now (a snapshot's), written instead of a second
  // download of the volume.
  void MaybeCheckpoint(CheckpointTrigger trigger, const EngineState* saved = nullptr) {
    const auto now = Clock::now();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!scheduler_.Due(trigger, engine_->has_model(), now)) return;
    }
    std::optional<StatusOr<EngineState>> taken;
    if (!saved) {
      taken = SaveModel();
      if (taken->ok()) saved = &taken->value();
    }
    size_t bytes = 0;
    const Status s = saved ? WriteCheckpoint(options_.checkpoint_dir, *saved, &bytes) : taken->status();
    const double ms = MsSince(now);
    std::lock_guard<std::mutex> lock(mutex_);
    scheduler_.Attempted(now, s.ok());
    if (!s.ok()) {
      checkpoint_message_ = "checkpoint failed: " + s.message();
      VD_LOG_ERROR << checkpoint_message_;
      return;
    }
    checkpoint_utime_ = NowUs();
    ++checkpoints_written_;
    checkpoint_message_ = "checkpoint of " + std::to_string(model_frames_) + " frames, " + std::to_string(bytes >> 10) +
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
                "reordered %lld, lost %lld, foreign %lld, held %lld, rate-limited %lld frames; %lld sequence jumps; "
                "%lld control commands refused (%lld for rate); %lld mesh requests served, %lld merged\n",
                (long long)g.received, (long long)processed_, (long long)dropped_, (long long)rejected_,
                (long long)g.duplicates, (long long)g.reordered, (long long)g.lost, (long long)g.foreign,
                (long long)g.held, (long long)g.rate_limited, (long long)g.jumps, (long long)g.control_refused,
                (long long)g.control_rate_limited, (long long)g.mesh_requests_served,
                (long long)g.mesh_requests_merged);
    if (stats_.count()) std::printf("stages (mean ms): %s\n", stats_.Summary().c_str());
    if (!latencies_ms_.empty())
      std::printf("latency capture -> mesh (last %zu frames): p50 %.0f ms, p95 %.0f ms\n", latencies_ms_.size(),
                  Percentile(latencies_ms_, 0.5), Percentile(latencies_ms_, 0.95));
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
      st.frames_held = g.held;
      st.sequence_jumps = g.jumps;
      st.frames_rate_limited = g.rate_limited;
      st.control_rate_limited = g.control_rate_limited;
      st.mesh_requests_merged = g.mesh_requests_merged;
      st.model_frames = model_frames_;
      st.checkpoint_utime = checkpoint_utime_;
      st.checkpoint_message = checkpoint_message_;
      st.last_processed_seq = published_seq_;
      st.last_source_id = last_source_id_;
      st.last_epoch = last_epoch_;
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
      if (!latencies_ms_.empty()) {
        st.latency_ms_last = float(latencies_ms_.back());
        st.latency_ms_p50 = float(Percentile(latencies_ms_, 0.5));
        st.latency_ms_p95 = float(Percentile(latencies_ms_, 0.95));
      }
      st.active_voxels = active_voxels_;
      st.dense_correspondences = dense_;
      st.sparse_correspondences = sparse_;
      st.energy_initial = energy_initial_;
      st.energy_final = energy_final_;
      st.resident_memory_bytes = ResidentBytes();
      last_status_ = Clock::now();
    }
    PublishOutput(channels_.status, &st, &SignStatus);
  }

 private:
  // Counts a refused frame under `reason` (derived from the error when empty); logs each reason once.
  void Reject(const Status& s, const std::string& given_reason = "") {
    ++rejected_;
    const std::string reason = given_reason.empty() ? RejectReason(s) : given_reason;
    if (reject_counts_[reason]++ == 0) VD_LOG_WARNING << "rejected a frame (" << reason << "): " << s.ToString();
  }

  // The live mesh is encoded for every frame (outside mutex_: Draco takes ~20 ms on a 50k-vertex
  // mesh); the canonical one only when it is published or saved (EncodeCanonical), at most once a
  // second, instead of every frame.
  std::optional<vdeform::mesh_t> EncodeLive(FrameResult* result, int64_t seq) const {
    // Every live mesh carries its vertices' canonical positions (same vertices, same order), so
    // viewers colour by canonical position on every frame, not only when a canonical mesh came.
    TriangleMesh& live_mesh = result->live_mesh;
    if (result->canonical_mesh.positions.size() == live_mesh.positions.size())
      live_mesh.canonical = result->canonical_mesh.positions;
    auto live = MeshToMessage(live_mesh, NowUs(), seq, vdeform::mesh_t::KIND_LIVE, vdeform::mesh_t::ENCODING_DRACO,
                              PublishedMeshDraco(options_, live_mesh.num_triangles()));
    if (live.ok()) return std::move(live).value();
    VD_LOG_WARNING << "cannot encode live mesh: " << live.status().ToString();
    return std::nullopt;
  }

  // A frame's meshes become the ones published and saved (mutex_ held).
  void KeepMeshes(std::optional<vdeform::mesh_t> live, FrameResult* result, int64_t seq) {
    if (live) last_live_ = std::move(live);
    canonical_pending_ = std::move(result->canonical_mesh);
    canonical_pending_seq_ = seq;
    canonical_changed_ = true;
  }

  // Encodes the newest canonical mesh if it is not yet (mutex_ held).
  void EncodeCanonical() {
    if (!canonical_pending_) return;
    auto canonical = MeshToMessage(*canonical_pending_, NowUs(), canonical_pending_seq_,
                                   vdeform::mesh_t::KIND_CANONICAL, vdeform::mesh_t::ENCODING_DRACO,
                                   PublishedMeshDraco(options_, canonical_pending_->num_triangles()));
    if (canonical.ok()) last_canonical_ = std::move(canonical).value();
    else VD_LOG_WARNING << "cannot encode canonical mesh: " << canonical.status().ToString();
    canonical_pending_.reset();
  }

  void Process(const RgbdFrame& frame) {
    const auto t0 = Clock::now();
    auto result = engine_->Process(frame);
    const double ms = MsSince(t0);
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
      scheduler_.ModelChanged();
    }
    last_processed_seq_ = frame.seq;
    last_source_id_ = frame.source_id;
    last_epoch_ = frame.epoch;
    stats_.Add(result->times, ms);
    process_times_.push_back(Clock::now());
    while (process_times_.size() > 30) process_times_.pop_front();
    state_ = result->tracking_ok ? vdeform::server_status_t::STATE_TRACKING : vdeform::server_status_t::STATE_TRACKING_LOST;
    message_ = result->tracking_ok ? engine_->DeviceDescription() : result->tracking_message;
    // The sparse volume's pool use first: viewers that show the start of the message (the window's
    // overlay) then show whether the pool is full.
    if (result->bricks_pool > 0) message_ = BrickPoolNote(*result) + "; " + message_;
    dense_ = result->dense_correspondences;
    sparse_ = result->sparse_matches;
    if (result->energies_evaluated) {
      energy_initial_ = float(result->energy_initial);
      energy_final_ = float(result->energy_final);
    }
    active_voxels_ = result->active_voxels;
    OutputJob job{std::move(result).value(), frame.seq, frame.utime};
    if (async_output_) {
      // The output thread encodes and publishes while this thread goes on with the next frame;
      // at most one result waits for it, so none is skipped and memory stays bounded.
      output_cv_.wait(lock, [&] { return !output_slot_.has_value(); });
      output_slot_ = std::move(job);
      output_cv_.notify_all();
      return;
    }
    lock.unlock();
    Output(std::move(job));
  }

  // A processed frame's output: its meshes encoded, kept and published, then its status (which
  // names the frame only once its mesh is out, so a lockstep capture never outruns the meshes).
  struct OutputJob {
    FrameResult result;
    int64_t seq = 0;
    int64_t capture_utime = 0;
  };
  void Output(OutputJob job) {
    std::optional<vdeform::mesh_t> live = EncodeLive(&job.result, job.seq);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      KeepMeshes(std::move(live), &job.result, job.seq);
      published_seq_ = job.seq;
    }
    PublishMeshes(false);
    if (!job.result.tracked_mesh.triangles.empty()) OutputTracked(job.result.tracked_mesh, job.seq);
    RecordLatency(job.capture_utime);
    PublishStatus();
  }

  // --track-mesh: the frame's tracked mesh is published as KIND_TRACKED (before the status that
  // names the frame), kept for REQUEST_MESH and, with --save-dir, written numbered by the frame's
  // sequence number (the node has no source index).
  void OutputTracked(const TriangleMesh& tracked, int64_t seq) {
    auto msg = MeshToMessage(tracked, NowUs(), seq, vdeform::mesh_t::KIND_TRACKED, vdeform::mesh_t::ENCODING_DRACO,
                             PublishedMeshDraco(options_, tracked.num_triangles()));
    if (msg.ok()) {
      std::lock_guard<std::mutex> lock(mutex_);
      last_tracked_ = std::move(msg).value();
      PublishOutput(channels_.mesh, &*last_tracked_, &SignMesh);
    } else if (tracked_encode_failures_++ == 0) {
      VD_LOG_ERROR << "cannot encode the tracked mesh: " << msg.status().ToString();
    }
    if (options_.save_dir.empty()) return;
    const Status s = WritePly(FramePath(options_.save_dir, seq, "tracked.ply"), tracked);
    if (!s.ok() && tracked_write_failures_++ == 0) VD_LOG_ERROR << "cannot write the tracked mesh: " << s.ToString();
  }

  // Serve's output thread: runs Output for each job until stopped with nothing left.
  void OutputLoop() {
    for (;;) {
      std::unique_lock<std::mutex> lock(mutex_);
      output_cv_.wait(lock, [&] { return output_slot_.has_value() || output_stop_; });
      if (!output_slot_) return;
      OutputJob job = std::move(*output_slot_);
      output_slot_.reset();
      output_cv_.notify_all();
      lock.unlock();
      Output(std::move(job));
    }
  }

  // Capture to mesh publication; frames without a capture time (utime 0) are not counted.
  void RecordLatency(int64_t capture_utime) {
    if (capture_utime <= 0) return;
    std::lock_guard<std::mutex> lock(mutex_);
    latencies_ms_.push_back(double(NowUs() - capture_utime) / 1000.0);
    if (latencies_ms_.size() > kLatencyWindow) latencies_ms_.erase(latencies_ms_.begin());
  }

  // The live mesh always; the canonical one when it changed, at most once a second, or on request.
  void PublishMeshes(bool force_canonical) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (last_live_) PublishOutput(channels_.mesh, &*last_live_, &SignMesh);
    // A viewer that joined late (REQUEST_MESH) also gets the newest tracked mesh; per frame it
    // goes out once, from OutputTracked.
    if (force_canonical && last_tracked_) PublishOutput(channels_.mesh, &*last_tracked_, &SignMesh);
    const auto now = Clock::now();
    const bool canonical_due =
        force_canonical || (canonical_changed_ && now - last_canonical_sent_ > std::chrono::seconds(1));
    if (canonical_due) EncodeCanonical();
    if (last_canonical_ && canonical_due) {
      PublishOutput(channels_.mesh, &*last_canonical_, &SignMesh);
      last_canonical_sent_ = now;
      canonical_changed_ = false;
    }
  }

  // Stamps this run's epoch and the next out_seq on an outgoing mesh or status, signs it under the
  // output key when there is one, and publishes it. One message at a time, so out_seq grows in
  // the order messages leave (the worker and the receive thread both publish).
  template <typename Msg>
  void PublishOutput(const std::string& channel, Msg* msg, Status (*sign)(const std::string&, Msg*)) {
    std::lock_guard<std::mutex> lock(output_mutex_);
    msg->epoch = epoch_;
    msg->out_seq = ++out_seq_;
    msg->auth_size = 0;
    msg->auth.clear();
    if (!output_key_.empty()) {
      // Left unsigned on failure: receivers with the key refuse it, and the log says why.
      const Status s = sign(output_key_, msg);
      if (!s.ok() && sign_failures_++ == 0) VD_LOG_ERROR << "cannot sign the output: " << s.ToString();
    }
    lcm_->publish(channel, msg);
  }

  // The engine's model with the sequence number and source of the last frame in it.
  StatusOr<EngineState> SaveModel() {
    EngineState state;
    VD_RETURN_IF_ERROR(engine_->SaveState(&state));
    std::lock_guard<std::mutex> lock(mutex_);
    state.last_seq = last_processed_seq_;
    state.source_id = last_source_id_;
    return state;
  }

  // SAVE_SNAPSHOT: the meshes and the model below --snapshot-dir, then a checkpoint of the same
  // model (also when the name is refused: the command still asks for the model to be kept).
  void Snapshot(const std::string& name) {
    auto path = SnapshotPath(options_.snapshot_dir, name);
    if (!path.ok()) {
      VD_LOG_WARNING << "SAVE_SNAPSHOT refused: " << path.status().message();
      return MaybeCheckpoint(CheckpointTrigger::kSnapshot);
    }
    std::optional<vdeform::mesh_t> live, canonical;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      live = last_live_;
      EncodeCanonical();
      canonical = last_canonical_;
    }
    Status s = Status::Ok();
    std::optional<TriangleMesh> live_mesh, canonical_mesh;
    auto decode = [&](const std::optional<vdeform::mesh_t>& m, std::optional<TriangleMesh>* out) {
      if (!s.ok() || !m) return;
      auto mesh = MessageToMesh(*m);
      if (mesh.ok()) *out = std::move(mesh).value();
      else s = mesh.status();
    };
    decode(live, &live_mesh);
    decode(canonical, &canonical_mesh);
    std::optional<StatusOr<EngineState>> model;
    if (engine_->has_model()) model = SaveModel();
    const EngineState* saved = model && model->ok() ? &model->value() : nullptr;
    if (s.ok())
      s = WriteSnapshot(*path, live_mesh ? &*live_mesh : nullptr, canonical_mesh ? &*canonical_mesh : nullptr, saved);
    if (s.ok() && model && !model->ok()) s = model->status();
    if (s.ok()) VD_LOG_INFO << "snapshot written to " << path->string();
    else VD_LOG_WARNING << "snapshot failed: " << s.ToString();
    MaybeCheckpoint(CheckpointTrigger::kSnapshot, saved);
  }

  // Borrowed from the caller, which validated them once at start-up.
  const ServerOptions& options_;
  const StreamChannels channels_;
  // Borrowed from the caller; publishing is thread-safe in LCM.
  lcm::LCM* lcm_;
  // Run by the worker; the receive thread only calls Prefetch, which is made to run beside Process.
  std::unique_ptr<Engine> engine_;
  // Guards everything below: the receive thread (handlers, Tick) and the worker share it.
  mutable std::mutex mutex_;
  // Wakes the worker for a frame, a reset or a snapshot.
  std::condition_variable cv_;
  // One slot: the newest accepted frame not yet processed.
  std::optional<RgbdFrame> mailbox_;
  // Whether an arriving frame's features are detected at once or when the worker takes it.
  PrefetchPolicy prefetch_;
  // Control commands wait for the worker, which owns the engine.
  bool reset_requested_ = false;
  std::vector<std::string> snapshot_requests_;
  // Decides about every message before it reaches the engine; counts what it received.
  FrameGate gate_;
  // Signs every mesh and status (empty: unsigned); set once at start.
  const std::string output_key_;
  // This server run, in every mesh and status: a restart is a new epoch to the receivers.
  const int64_t epoch_ = RandomEpoch();
  // Orders stamping and publishing of the output; taken after mutex_ when both are held.
  std::mutex output_mutex_;
  // The out_seq of the last message published (guarded by output_mutex_).
  int64_t out_seq_ = 0;
  // Messages that went out unsigned because signing failed (logged once).
  int64_t sign_failures_ = 0;
  // Tracked meshes that could not be written to --save-dir (logged once).
  int64_t tracked_write_failures_ = 0;
  // The newest tracked mesh as published (--track-mesh), re-sent on REQUEST_MESH.
  std::optional<vdeform::mesh_t> last_tracked_;
  int64_t tracked_encode_failures_ = 0;
  // Decides when the worker writes a checkpoint.
  CheckpointScheduler scheduler_;
  // Frames received are counted by the gate; these are what became of them after it.
  int64_t processed_ = 0, dropped_ = 0, rejected_ = 0;
  // Frames fused into the current model (continued across --resume).
  int64_t model_frames_ = 0;
  // Checkpoint outcome for the status: how many, when the last one was written, what happened.
  int64_t checkpoints_written_ = 0;
  int64_t checkpoint_utime_ = 0;
  std::string checkpoint_message_;
  // Refused frames by reason, reported in the status.
  std::map<std::string, int64_t> reject_counts_;
  // The newest frame in the model; a resumed model continues the sequence.
  int64_t last_processed_seq_ = -1;
  // The last frame whose mesh has been published: what the status names as processed.
  int64_t published_seq_ = -1;
  // Serve hands each result to its output thread (RunOnce alone publishes inline): the slot, its
  // wake-up, and the stop once the worker has ended. async_output_ is set before the threads start.
  std::optional<OutputJob> output_slot_;
  std::condition_variable output_cv_;
  bool output_stop_ = false;
  bool async_output_ = false;
  std::string last_source_id_;
  // The run of the source of the newest frame (0 after a resume: the checkpoint does not keep it).
  int64_t last_epoch_ = 0;
  // What the status says the server is doing, and why (device, tracking failure, bad frame).
  int8_t state_ = vdeform::server_status_t::STATE_IDLE;
  std::string message_ = "waiting for frames";
  // Stage times of every processed frame, for the status and the summary at exit.
  StageStats stats_;
  // Completion times of the last 30 frames, for the frame rate.
  std::deque<Clock::time_point> process_times_;
  // Capture-to-publication latency of the last kLatencyWindow frames, ms (the status's p50/p95:
  // what a live user waits, including the time a frame queued behind the one being solved).
  static constexpr size_t kLatencyWindow = 100;
  std::vector<double> latencies_ms_;
  // The last frame's solve, for a monitor: depth correspondences and SIFT matches (none of either
  // means the solve ran on regularity alone), the energy before and after (a rise means it
  // diverged), the grid points near the surface (what the solve and memory scale with).
  int32_t dense_ = 0;
  int32_t sparse_ = 0;
  float energy_initial_ = 0.f;
  float energy_final_ = 0.f;
  int64_t active_voxels_ = 0;
  // Encoded once per frame, republished on REQUEST_MESH to viewers that join late.
  std::optional<vdeform::mesh_t> last_live_, last_canonical_;
  // The newest canonical mesh while last_canonical_ does not hold it yet, and its frame.
  std::optional<TriangleMesh> canonical_pending_;
  int64_t canonical_pending_seq_ = 0;
  // The canonical mesh is large: sent at most once a second, and only when it changed.
  bool canonical_changed_ = false;
  Clock::time_point last_canonical_sent_{};
  // Status goes out after each frame and at least twice a second.
  Clock::time_point last_status_{};
};

Node::Node(const ServerOptions& options, lcm::LCM* lcm, std::unique_ptr<Engine> engine, GateOptions gate,
           std::string output_key)
    : impl_(std::make_unique<Impl>(options, lcm, std::move(engine), std::move(gate), std::move(output_key))) {}
Node::~Node() = default;

void Node::OnFrame(const lcm::ReceiveBuffer* rbuf, const std::string&) { impl_->OnFrame(rbuf); }
void Node::OnControl(const lcm::ReceiveBuffer* rbuf, const std::string&) { impl_->OnControl(rbuf); }
Status Node::Serve(const std::atomic<bool>* stop) { return impl_->Serve(stop); }
void Node::Work(const std::atomic<bool>* stop) { impl_->Work(stop); }
bool Node::RunOnce() { return impl_->RunOnce(); }
void Node::Tick() { impl_->Tick(); }
void Node::PublishStatusNow() { impl_->PublishStatus(); }
bool Node::Resume() { return impl_->Resume(); }
void Node::MaybeCheckpoint(CheckpointTrigger trigger) { impl_->MaybeCheckpoint(trigger); }
int64_t Node::checkpoints_written() const { return impl_->checkpoints_written(); }
GateCounters Node::gate_counters() const { return impl_->gate_counters(); }
void Node::PrintSummary() const { impl_->PrintSummary(); }

int RunNode(const ServerOptions& options) {
  // Bounded memory under hostile traffic (issue 15): LCM allocates a buffer of whatever size a
  // message declares, and the gate then decodes and rejects it. glibc raises its mmap
  // threshold to the size of each freed mmapped block, so after one 6.6 MB message the next ones
  // come from the heap and fragment it: the hostile test saw RSS step up by 10 MB during a flood.
  // A fixed threshold keeps every block of 4 MiB and more mmapped, returned to the system on free.
  // The per-frame buffers (a 640x480 float image is 1.2 MB) stay below it.
  mallopt(M_MMAP_THRESHOLD, 4 << 20);
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  // Key files are arguments: a bad one is a usage error (exit 2) before anything starts.
  auto gate = options.ToGateOptions();
  if (!gate.ok()) {
    std::fprintf(stderr, "vdeform-server: %s\n", gate.status().message().c_str());
    return 2;
  }
  auto output_key = OutputKeyFromFlag(options.output_key_file);
  if (!output_key.ok()) {
    std::fprintf(stderr, "vdeform-server: %s\n", output_key.status().message().c_str());
    return 2;
  }
  const std::string url = ResolveLcmUrl(options.lcm_url);
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    std::fprintf(stderr,
                 "vdeform-server: cannot open LCM at '%s' %s\n",
                 url.c_str(), kLcmRouteHint);
    return 1;
  }
  auto engine = Engine::Create(options.engine, options.device);
  if (!engine.ok()) {
    std::fprintf(stderr, "vdeform-server: %s\n", engine.status().ToString().c_str());
    return 1;
  }
  if (Status s = ApplyTrackMesh(options, engine->get()); !s.ok()) {
    std::fprintf(stderr, "vdeform-server: %s\n", s.ToString().c_str());
    return 2;
  }
  if (options.tracks_mesh() && options.save_dir.empty())
    VD_LOG_INFO << "--track-mesh without --save-dir: the tracked meshes are published (mesh_t KIND_TRACKED), not written";
  if (options.tracks_mesh() && !options.save_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(options.save_dir, ec);
    if (ec) {
      std::fprintf(stderr, "vdeform-server: cannot create --save-dir '%s': %s\n", options.save_dir.c_str(),
                   ec.message().c_str());
      return 2;
    }
  }
  VD_LOG_INFO << "vdeform-server on " << (*engine)->DeviceDescription() << ", LCM " << url
              << (options.stream.empty() ? "" : ", stream " + options.stream);
  if (!gate->control_key.empty()) VD_LOG_INFO << "control commands RESET and SAVE_SNAPSHOT need an HMAC";
  if (!gate->frame_keys.empty())
    VD_LOG_INFO << "frames must be signed (" << gate->frame_keys.size()
                << (gate->frame_keys.per_source() ? " source keys)" : " key for every source)");
  if (!gate->accept_sources.empty()) VD_LOG_INFO << "accepting frames only from: " << options.accept_sources;
  if (!output_key->empty()) VD_LOG_INFO << "meshes and status are signed under the output key";
  Node node(options, &lcm, std::move(engine).value(), std::move(gate).value(), std::move(output_key).value());
  // A refused checkpoint is reported (log and status) and the server starts a new model.
  if (options.resume) node.Resume();
  const StreamChannels channels = *ChannelsOfStream(options.stream);
  lcm.subscribe(channels.frames, &Node::OnFrame, &node);
  lcm.subscribe(channels.control, &Node::OnControl, &node);
  GuardLcmOrWarn(url, "vdeform-server");
  const Status served = node.Serve(&g_stop);
  node.PrintSummary();
  if (!served.ok()) {
    VD_LOG_ERROR << served.message() << "; stopped";
    return 1;
  }
  return 0;
}

}  // namespace vd
