#include "vd/viewer/receiver.h"

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <system_error>

#include <opencv2/imgcodecs.hpp>
#include <vdeform/control_t.hpp>

#include "vd/common/codecs.h"
#include "vd/common/log.h"
#include "vd/common/messages.h"

namespace vd {

Status ReceiverOptions::Validate() const {
  if (write_png && save_dir.empty())
    return InvalidArgument("ReceiverOptions.write_png = true needs a save_dir (--png needs --save-dir DIR)");
  if (sender.empty()) return InvalidArgument("ReceiverOptions.sender = '' violates: a non-empty name");
  if (mesh_queue_capacity < 0 || mesh_queue_capacity > 10000)
    return InvalidArgument("ReceiverOptions.mesh_queue_capacity = " + std::to_string(mesh_queue_capacity) +
                           " violates 0 <= mesh_queue_capacity <= 10000");
  return render.Validate();
}

Status RunOptions::Validate() const {
  if (count < 0) return InvalidArgument("RunOptions.count = " + std::to_string(count) + " violates count >= 0");
  if (!std::isfinite(timeout_s) || timeout_s < 0.0 || timeout_s > 1e6)
    return InvalidArgument("RunOptions.timeout_s = " + std::to_string(timeout_s) + " violates 0 <= timeout_s <= 1e6");
  if (poll_ms < 0 || poll_ms > 10000)
    return InvalidArgument("RunOptions.poll_ms = " + std::to_string(poll_ms) + " violates 0 <= poll_ms <= 10000");
  return Status::Ok();
}

StatusOr<std::unique_ptr<MeshReceiver>> MeshReceiver::Create(lcm::LCM* lcm, const ReceiverOptions& options) {
  VD_RETURN_IF_ERROR(options.Validate());
  if (lcm == nullptr || !lcm->good()) return Unavailable("MeshReceiver needs an initialised LCM instance");
  if (!options.save_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(options.save_dir, ec);
    if (ec || !std::filesystem::is_directory(options.save_dir, ec))
      return Unavailable("cannot create the save directory '" + options.save_dir + "': " + ec.message());
  }
  std::unique_ptr<MeshReceiver> receiver(new MeshReceiver(lcm, options));
  const StreamChannels& channels = options.channels;
  receiver->mesh_subscription_ = lcm->subscribe(channels.mesh, &MeshReceiver::OnMesh, receiver.get());
  receiver->status_subscription_ = lcm->subscribe(channels.status, &MeshReceiver::OnStatus, receiver.get());
  if (!receiver->mesh_subscription_ || !receiver->status_subscription_)
    return Unavailable("cannot subscribe to " + channels.mesh + " and " + channels.status);
  if (options.mesh_queue_capacity > 0 && receiver->mesh_subscription_->setQueueCapacity(options.mesh_queue_capacity) != 0)
    return Unavailable("cannot set the mesh queue capacity to " + std::to_string(options.mesh_queue_capacity));
  // A provider that cannot publish (a file:// log opened for replay) still delivers meshes.
  if (options.request_mesh) {
    Status sent = receiver->RequestMesh();
    if (!sent.ok()) receiver->LogOnce("request", sent);
  }
  return receiver;
}

MeshReceiver::MeshReceiver(lcm::LCM* lcm, const ReceiverOptions& options)
    : lcm_(lcm), options_(options), last_message_time_(Clock::now()) {
  if (!options_.output_key.empty()) verifier_.emplace(options_.output_key);
  stats_.verifying = verifier_.has_value();
}

MeshReceiver::~MeshReceiver() {
  if (mesh_subscription_) lcm_->unsubscribe(mesh_subscription_);
  if (status_subscription_) lcm_->unsubscribe(status_subscription_);
}

Status MeshReceiver::RequestMesh() {
  vdeform::control_t msg;
  msg.utime = std::chrono::duration_cast<std::chrono::microseconds>(
                  std::chrono::system_clock::now().time_since_epoch())
                  .count();
  msg.command = vdeform::control_t::COMMAND_REQUEST_MESH;
  msg.sender = options_.sender;
  msg.auth_size = 0;
  if (lcm_->publish(options_.channels.control, &msg) != 0)
    return Unavailable("cannot publish REQUEST_MESH on " + options_.channels.control);
  ++stats_.requests_sent;
  return Status::Ok();
}

Status MeshReceiver::Poll(int timeout_ms) {
  errno = 0;
  if (lcm_->handleTimeout(std::max(0, timeout_ms)) >= 0) return Status::Ok();
  // A signal (SIGINT/SIGTERM asking us to stop) interrupts LCM's select(): not a failure.
  if (errno == EINTR) return Status::Ok();
  const std::string cause = errno != 0 ? std::string(": ") + std::strerror(errno) : "";
  return Unavailable("LCM stopped delivering messages (the provider failed, or a file:// log ended)" + cause);
}

Status MeshReceiver::Run(const RunOptions& options, const std::atomic<bool>* stop, const std::function<void()>& tick) {
  VD_RETURN_IF_ERROR(options.Validate());
  const auto timeout = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(options.timeout_s));
  // The time-out counts from whichever is later: the start of Run or the last message.
  const auto run_start = Clock::now();
  while (stop == nullptr || !stop->load()) {
    if (options.count > 0 && stats_.live_meshes >= options.count) return Status::Ok();
    int wait_ms = options.poll_ms;
    if (options.timeout_s > 0) {
      const auto deadline = std::max(run_start, last_message_time_) + timeout;
      const auto now = Clock::now();
      if (now >= deadline) {
        char text[64];
        std::snprintf(text, sizeof text, "%g", options.timeout_s);
        return DeadlineExceeded(std::string("no mesh or status message arrived for ") + text + " s on " + options_.channels.mesh +
                                " / " + options_.channels.status + "; is vdeform-server running on the same LCM URL?");
      }
      const auto left_ms = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - now).count() + 1;
      wait_ms = static_cast<int>(std::min<int64_t>(wait_ms, left_ms));
    }
    VD_RETURN_IF_ERROR(Poll(wait_ms));
    if (tick) tick();
  }
  return Status::Ok();
}

void MeshReceiver::OnMesh(const lcm::ReceiveBuffer* buffer, const std::string&) {
  try {
    HandleMesh(buffer);
  } catch (const std::exception& e) {
    ++stats_.internal_errors;
    LogOnce("mesh handler", Internal(e.what()));
  }
}

void MeshReceiver::OnStatus(const lcm::ReceiveBuffer* buffer, const std::string&) {
  try {
    HandleStatus(buffer);
  } catch (const std::exception& e) {
    ++stats_.internal_errors;
    LogOnce("status handler", Internal(e.what()));
  }
}

void MeshReceiver::HandleMesh(const lcm::ReceiveBuffer* buffer) {
  if (!verifier_) last_message_time_ = Clock::now();
  ++stats_.mesh_messages;
  stats_.mesh_bytes += buffer->data_size;
  // Decoded here rather than by LCM's typed handler so malformed bytes are counted, not thrown.
  StatusOr<vdeform::mesh_t> msg = DecodeLcm<vdeform::mesh_t>(buffer->data, buffer->data_size);
  if (!msg.ok()) {
    ++stats_.meshes_failed;
    LogOnce("malformed mesh_t", msg.status());
    return;
  }
  if (verifier_) {
    // Checked before the Draco decode: a forger's mesh costs a hash, not a decode.
    const OutputCheck taken = verifier_->Check(*msg);
    stats_.meshes_refused = verifier_->mesh_refused();
    if (!taken.ok()) return LogOnce(std::string("mesh refused, ") + OutputVerdictName(taken.verdict), taken.status);
    last_message_time_ = Clock::now();
  }
  StatusOr<TriangleMesh> mesh = MessageToMesh(*msg);
  if (!mesh.ok()) {
    ++stats_.meshes_failed;
    LogOnce("undecodable mesh", mesh.status());
    return;
  }
  ++stats_.meshes_decoded;
  if (msg->kind == vdeform::mesh_t::KIND_TRACKED) {
    // Published once per frame, never as an answer to REQUEST_MESH: no repeats to skip.
    ++stats_.tracked_meshes;
    stats_.last_tracked_vertices = static_cast<int64_t>(mesh->num_vertices());
    if (!options_.save_dir.empty()) {
      Status written = WriteMeshPly(*mesh, FramePath(msg->seq, ".tracked.ply"));
      if (!written.ok()) LogOnce("write", written);
    }
    return;
  }
  const bool live = msg->kind == vdeform::mesh_t::KIND_LIVE;
  if (live ? (live_ && live_seq_ == msg->seq) : (canonical_ && canonical_seq_ == msg->seq)) {
    ++stats_.repeated_meshes;
    return;
  }
  if (live) {
    if (png_pending_) FlushPendingPng();
    live_ = std::move(mesh).value();
    live_seq_ = msg->seq;
    ++stats_.live_meshes;
    stats_.last_live_seq = msg->seq;
    stats_.last_live_vertices = static_cast<int64_t>(live_->num_vertices());
    stats_.last_live_triangles = static_cast<int64_t>(live_->num_triangles());
    ++version_;
    if (!options_.save_dir.empty()) {
      Status written = WriteMeshPly(*live_, FramePath(live_seq_, ".mesh.ply"));
      if (!written.ok()) LogOnce("write", written);
    }
    if (options_.write_png) {
      png_pending_ = true;
      // The canonical mesh of this frame may already be here (it arrived first): no need to wait.
      if (canonical_ && canonical_seq_ == live_seq_) FlushPendingPng();
    }
    return;
  }
  canonical_ = std::move(mesh).value();
  canonical_seq_ = msg->seq;
  ++stats_.canonical_meshes;
  ++version_;
  if (!options_.save_dir.empty()) {
    Status written = WriteMeshPly(*canonical_, FramePath(canonical_seq_, ".canonical.ply"));
    if (!written.ok()) LogOnce("write", written);
  }
  if (png_pending_ && live_seq_ == canonical_seq_) FlushPendingPng();
}

void MeshReceiver::HandleStatus(const lcm::ReceiveBuffer* buffer) {
  if (!verifier_) last_message_time_ = Clock::now();
  StatusOr<vdeform::server_status_t> msg = DecodeLcm<vdeform::server_status_t>(buffer->data, buffer->data_size);
  if (!msg.ok()) {
    ++stats_.status_failed;
    LogOnce("malformed server_status_t", msg.status());
    return;
  }
  if (verifier_) {
    const OutputCheck taken = verifier_->Check(*msg);
    stats_.status_refused = verifier_->status_refused();
    if (!taken.ok()) return LogOnce(std::string("status refused, ") + OutputVerdictName(taken.verdict), taken.status);
    last_message_time_ = Clock::now();
  }
  const bool first = !last_status_.has_value();
  last_status_ = std::move(msg).value();
  ++stats_.status_messages;
  // A viewer started before the server asked into the void; ask again now that it is there.
  if (first && options_.request_mesh && !live_ && stats_.requests_sent <= 1) {
    Status sent = RequestMesh();
    if (!sent.ok()) LogOnce("request", sent);
  }
}

std::string MeshReceiver::FramePath(int64_t seq, const char* suffix) const {
  char name[64];
  std::snprintf(name, sizeof name, "frame-%06lld%s", static_cast<long long>(seq), suffix);
  return (std::filesystem::path(options_.save_dir) / name).string();
}

Status MeshReceiver::WriteMeshPly(const TriangleMesh& mesh, const std::string& path) {
  Status written = WritePly(path, mesh);
  if (!written.ok()) {
    ++stats_.write_failures;
    return written.WithContext("writing " + path);
  }
  ++stats_.files_written;
  written_paths_.push_back(path);
  return Status::Ok();
}

Status MeshReceiver::WritePng(const std::string& path) {
  if (!live_) return FailedPrecondition("no live mesh to render for " + path);
  const TriangleMesh* canonical = canonical_ ? &*canonical_ : nullptr;
  const VertexColors colors = SelectVertexColors(*live_, live_seq_, canonical, canonical_seq_, options_.color_mode);
  StatusOr<RenderResult> rendered = RenderMesh(*live_, colors.rgb, options_.render);
  if (!rendered.ok()) {
    ++stats_.write_failures;
    return rendered.status().WithContext("rendering " + path);
  }
  bool ok = false;
  std::string error = "cv::imwrite returned false";
  try {
    // OpenCV's default (level 1, RLE strategy) measured 14 ms for 640x480; an explicit level 1
    // switches to the filtered strategy and took 31 ms.
    ok = cv::imwrite(path, rendered->image);
  } catch (const cv::Exception& e) {
    error = e.what();
  }
  if (!ok) {
    ++stats_.write_failures;
    return Unavailable("cannot write " + path + ": " + error);
  }
  ++stats_.files_written;
  written_paths_.push_back(path);
  return Status::Ok();
}

void MeshReceiver::FlushPendingPng() {
  png_pending_ = false;
  Status written = WritePng(FramePath(live_seq_, ".png"));
  if (!written.ok()) LogOnce("write", written);
}

Status MeshReceiver::Finish() {
  Status first_error;
  if (png_pending_) {
    png_pending_ = false;
    first_error = WritePng(FramePath(live_seq_, ".png"));
  }
  if (options_.write_png && live_) {
    Status final_png = WritePng((std::filesystem::path(options_.save_dir) / "final.png").string());
    if (first_error.ok()) first_error = final_png;
  }
  return first_error;
}

void MeshReceiver::LogOnce(const std::string& kind, const Status& status) {
  const std::string key = kind + "/" + StatusCodeName(status.code());
  if (!logged_kinds_.insert(key).second) return;
  VD_LOG_WARNING << kind << " (counted; further ones of this kind are not logged): " << status.ToString();
}

}  // namespace vd
