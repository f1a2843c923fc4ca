// vdeform-server's flags and their translation into engine and gate parameters.
#include "server_options.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "vd/common/codecs.h"

namespace vd {

void ServerOptions::Register(FlagParser* f) {
  f->Section("Offline mode (--input)");
  f->Add("input", &input, "Process SOURCE (openni2[:URI], oni:FILE, folder:DIR, synthetic:NAME) without LCM", "SOURCE");
  f->Add("intrinsics", &intrinsics, "Intrinsics overriding the source's, pixels", "FX,FY,CX,CY");
  f->Add("depth-scale", &depth_scale, "Raw depth units per metre overriding the source's (0 = source's)");
  f->Add("count", &count, "Process at most N frames (-1 = all)", "N");
  f->Add("start", &start, "First frame index of the source", "N");
  f->Add("stride", &stride, "Use every n-th frame of the source", "N");
  f->Add("frames", &synthetic_frames,
         "synthetic: inputs: frames in one pass of the motion (0 = the scene's own, 60; more = a long take of the "
         "same motion)",
         "N");
  f->Add("save-dir", &save_dir,
         "Write frame-%06d.mesh.ply (live, camera coordinates), frame-%06d.canonical.ply and frame-%06d.pose.txt "
         "(camera-to-world) per frame, numbered by the frame's index in the source (--start 3 --stride 2: 3, 5, 7, "
         "...)",
         "DIR");
  f->Add("stats-json", &stats_json, "Write per-stage timing statistics, fps and peak memory", "FILE");
  f->AddSwitch("track-mesh", &track_mesh,
               "Track a fixed-topology mesh: the first frame's mesh deformed by the current field, in that frame's camera "
               "coordinates, with the same vertices and faces in every frame. With --save-dir it is written as "
               "frame-%06d.tracked.ply; a node (no --input) also publishes it on the mesh channel as mesh_t "
               "KIND_TRACKED for every processed frame");
  f->Add("track-mesh-from", &track_mesh_from,
         "Track this PLY (canonical coordinates: the first frame's camera, metres) instead of the first frame's mesh "
         "(implies --track-mesh)",
         "FILE");
  engine.Bind(f);
  f->Section("Device");
  f->Add("device", &device, "OpenCL device: index (see --list-devices) or name substring; default first GPU, else CPU");
  f->AddSwitch("list-devices", &list_devices, "List the OpenCL devices and exit");
  f->Section("LCM node");
  f->Add("lcm-url", &lcm_url, "LCM URL (default: $LCM_DEFAULT_URL, else host-only multicast with a 4 MB receive buffer)",
         "URL");
  f->Add("stream", &stream,
         "Stream name, for several capture+server pairs on one LCM URL: frames on VDEFORM_<NAME>_FRAMES, meshes, "
         "status and control on VDEFORM_<NAME>_MESH, _STATUS, _CONTROL (empty = VDEFORM_FRAMES, ...)",
         "NAME");
  f->Add("snapshot-dir", &snapshot_dir, "Directory SAVE_SNAPSHOT commands write into (paths cannot leave it)", "DIR");
  f->Add("checkpoint", &checkpoint_dir,
         "Directory for checkpoints of the model (volume, deformation field, feature history), written "
         "atomically every --checkpoint-interval seconds, on SAVE_SNAPSHOT and at shutdown; empty = none",
         "DIR");
  f->Add("checkpoint-interval", &checkpoint_interval,
         "Seconds between periodic checkpoints while the model changes (0 = only on SAVE_SNAPSHOT and shutdown)");
  f->AddSwitch("resume", &resume,
               "Continue from the newest valid checkpoint in --checkpoint (a torn or corrupt one is reported, "
               "kept aside and never loaded)");
  f->Add("accept-sources", &accept_sources,
         "Comma-separated source ids whose frames are accepted (empty = any); others are counted and ignored", "IDS");
  f->Add("control-key-file", &control_key_file,
         "File holding the HMAC-SHA256 key (>= 16 bytes, mode 600) that RESET and SAVE_SNAPSHOT commands must "
         "be signed with (vdeform-control --key-file); empty = control is not authenticated",
         "FILE");
  f->Add("frame-key-file", &frame_key_file,
         "File of HMAC-SHA256 keys frames must be signed with (vdeform-capture --frame-key-file): one line KEY for "
         "every source, or SOURCE_ID KEY lines; KEY is 64 hex digits (openssl rand -hex 32), mode 600. Unsigned, "
         "wrongly signed and replayed frames are counted and refused; empty = frames are not authenticated",
         "FILE");
  f->Add("output-key-file", &output_key_file,
         "Sign every mesh and status message with HMAC-SHA256 under the key in FILE: one line KEY, 64 hex digits "
         "(openssl rand -hex 32), mode 600; give the same file to vdeform-viewer/vdeform-web --key-file and "
         "vdeform-capture --output-key-file, which then take only this server's output. Empty = unsigned",
         "FILE");
  f->Add("draco-speed", &draco_speed,
         "Draco encoding speed of the published meshes, 0-10: 10 = sequential connectivity, the fastest to encode "
         "(the output thread shares the cores with the solve); 0-9 = edgebreaker, about 2.4x smaller messages for "
         "slow links at 2-3x the encoding time",
         "N");
  gate.Bind(f);
  f->Section("Output");
  f->AddSwitch("quiet", &quiet, "Only warnings and errors");
}

Status ServerOptions::Validate() const {
  VD_RETURN_IF_ERROR(engine.Validate());
  VD_RETURN_IF_ERROR(ValidateStreamName(stream).WithContext("--stream"));
  // Source options are checked by SourceOptions::Validate when the offline mode opens its source.
  if (!(checkpoint_interval >= 0.0))
    return ParamOutOfBounds("ServerOptions", "checkpoint_interval", checkpoint_interval, ">= 0 s (--checkpoint-interval)");
  VD_RETURN_IF_ERROR(gate.Validate());
  if (draco_speed < 0 || draco_speed > 10)
    return ParamOutOfBounds("ServerOptions", "draco_speed", static_cast<double>(draco_speed),
                            "0 <= draco_speed <= 10 (--draco-speed)");
  if (resume && checkpoint_dir.empty()) return InvalidArgument("--resume needs --checkpoint DIR");
  return Status::Ok();
}

DracoOptions PublishedMeshDraco(const ServerOptions& options, size_t triangles) {
  DracoOptions draco;
  draco.speed = static_cast<int>(options.draco_speed);
  if (triangles > kSequentialMaxTriangles) draco.speed = std::min(draco.speed, 7);
  return draco;
}

Status ApplyTrackMesh(const ServerOptions& options, Engine* engine) {
  if (!options.tracks_mesh()) return Status::Ok();
  TriangleMesh given;
  if (!options.track_mesh_from.empty()) {
    auto read = ReadPly(options.track_mesh_from);
    if (!read.ok()) return read.status().WithContext("--track-mesh-from");
    given = std::move(read).value();
  }
  return engine->TrackMesh(given).WithContext("--track-mesh-from");
}

std::string FramePath(const std::string& dir, int64_t index, const char* suffix) {
  char name[64];
  std::snprintf(name, sizeof(name), "frame-%06lld.%s", static_cast<long long>(index), suffix);
  return (std::filesystem::path(dir) / name).string();
}

StatusOr<GateOptions> ServerOptions::ToGateOptions() const {
  GateOptions g;
  g.params = gate;
  size_t begin = 0;
  while (begin <= accept_sources.size() && !accept_sources.empty()) {
    const size_t end = std::min(accept_sources.find(',', begin), accept_sources.size());
    const std::string id = accept_sources.substr(begin, end - begin);
    if (id.empty()) return InvalidArgument("--accept-sources has an empty source id: '" + accept_sources + "'");
    g.accept_sources.push_back(id);
    begin = end + 1;
  }
  if (!control_key_file.empty()) {
    auto key = ReadControlKey(control_key_file);
    if (!key.ok()) return key.status();
    g.control_key = std::move(key).value();
  }
  if (!frame_key_file.empty()) {
    auto keys = ReadFrameKeys(frame_key_file);
    if (!keys.ok()) return keys.status();
    g.frame_keys = std::move(keys).value();
  }
  return g;
}

}  // namespace vd
