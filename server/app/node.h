#pragma once
// The LCM node: frames in, meshes and status out. A receive thread validates frames into a
// one-slot mailbox (a newer frame replaces an unprocessed one, counted as dropped); the worker
// runs the engine on the newest frame. No exception or bad message reaches past a handler.
// Checkpoints follow CheckpointScheduler; SAVE_SNAPSHOT writes snapshot.h's files.
#include <atomic>
#include <memory>
#include <string>

#include <lcm/lcm-cpp.hpp>

#include "checkpoint_scheduler.h"
#include "core/engine.h"
#include "gate.h"
#include "server_options.h"
#include "vd/common/status.h"

namespace vd {

int64_t NowUs();

class Node {
 public:
  // `options` and `lcm` must outlive the node. `output_key` (OutputKeyFromFlag): every mesh
  // and status is signed under it; empty: they go unsigned.
  Node(const ServerOptions& options, lcm::LCM* lcm, std::unique_ptr<Engine> engine, GateOptions gate = {},
       std::string output_key = {});
  ~Node();

  // LCM handlers (subscribe them to the stream's frame and control channels).
  void OnFrame(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void OnControl(const lcm::ReceiveBuffer* rbuf, const std::string& channel);

  // Serves until *stop: a worker thread runs Work, this thread receives and calls Tick; then the
  // shutdown checkpoint. A receive interrupted by a signal (Ctrl-C) is not an error; a failed
  // one stops serving and is returned.
  Status Serve(const std::atomic<bool>* stop);
  // Worker: runs the engine on the newest frame until *stop.
  void Work(const std::atomic<bool>* stop);
  // One step of the worker: a pending reset, snapshots, then the waiting frame. Returns whether a
  // frame was processed. Tests call it directly.
  bool RunOnce();
  // Publishes status, and meshes on request; called from the receive loop.
  void Tick();
  // Publishes a status message now (tests; the loop publishes twice a second via Tick).
  void PublishStatusNow();

  // Loads the newest valid checkpoint of --checkpoint DIR into the engine (--resume). Returns
  // false when one was refused or could not be restored (the server then starts a new model and
  // says so in the status); true when loaded or when there was none.
  bool Resume();
  // Writes a checkpoint when the scheduler says one is due for `trigger`.
  void MaybeCheckpoint(CheckpointTrigger trigger);

  int64_t checkpoints_written() const;
  GateCounters gate_counters() const;
  // The counters of the run on stdout, at exit.
  void PrintSummary() const;

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

// The LCM node as a process: opens LCM, serves until SIGINT or SIGTERM. Returns the exit code.
int RunNode(const ServerOptions& options);

}  // namespace vd
