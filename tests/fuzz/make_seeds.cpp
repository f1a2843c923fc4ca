// vd_fuzz_seeds OUT_DIR: writes valid encodings, one folder per seed set (the SEEDS names that
// vd_fuzz_target takes), for the fuzzers to start from. Small images and meshes keep inputs short
// and executions fast; several codec settings reach the decoders' different paths.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "fuzz_util.h"
#include "vd/common/auth.h"
#include "vd/common/codecs.h"
#include "vd/common/messages.h"

namespace vd::fuzz {
namespace {

namespace fs = std::filesystem;

class SeedWriter {
 public:
  explicit SeedWriter(fs::path root) : root_(std::move(root)) {}

  void Write(const std::string& set, const std::string& name, const std::vector<uint8_t>& bytes) {
    const fs::path dir = root_ / set;
    fs::create_directories(dir);
    std::ofstream out(dir / name, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    if (!out) Fail("cannot write " + (dir / name).string());
    ++count_;
  }
  template <typename Msg>
  void WriteLcm(const std::string& set, const std::string& name, const Msg& msg) {
    std::vector<uint8_t> bytes(static_cast<size_t>(msg.getEncodedSize()));
    if (msg.encode(bytes.data(), 0, static_cast<int>(bytes.size())) != static_cast<int>(bytes.size()))
      Fail("cannot LCM-encode " + name);
    Write(set, name, bytes);
  }
  int count() const { return count_; }

  [[noreturn]] static void Fail(const std::string& what) {
    std::fprintf(stderr, "vd_fuzz_seeds: %s\n", what.c_str());
    std::exit(1);
  }
  template <typename T>
  static T Check(StatusOr<T> value, const std::string& what) {
    if (!value.ok()) Fail(what + ": " + value.status().ToString());
    return std::move(value).value();
  }

 private:
  fs::path root_;
  int count_ = 0;
};

// A sloped surface with holes, as a sensor sees it; zero_every = 0 gives no holes.
cv::Mat Depth(int width, int height, int zero_every, uint32_t seed) {
  cv::Mat depth(height, width, CV_16UC1);
  std::mt19937 rng(seed);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      depth.at<uint16_t>(y, x) =
          (zero_every > 0 && rng() % zero_every == 0) ? 0 : static_cast<uint16_t>(800 + 7 * x + 3 * y + rng() % 4);
  return depth;
}

cv::Mat Color(int width, int height, uint32_t seed) {
  cv::Mat color(height, width, CV_8UC3);
  std::mt19937 rng(seed);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      color.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<uint8_t>(16 * x), static_cast<uint8_t>(16 * y),
                                            static_cast<uint8_t>(rng()));
  return color;
}

TriangleMesh Tetrahedron() {
  TriangleMesh m;
  m.positions = {0.f, 0.f, 0.f, 0.1f, 0.f, 0.f, 0.f, 0.1f, 0.f, 0.f, 0.f, 0.1f};
  m.colors = {255, 0, 0, 0, 255, 0, 0, 0, 255, 200, 200, 200};
  m.triangles = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  return m;
}

// A closed sphere of rings x segments quads: edgebreaker coding keeps it as it is.
TriangleMesh Sphere(int rings, int segments, bool normals) {
  TriangleMesh m;
  for (int r = 0; r <= rings; ++r)
    for (int s = 0; s < segments; ++s) {
      const float t = 3.14159265f * r / rings, p = 6.2831853f * s / segments;
      const float n[3] = {std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t)};
      m.positions.insert(m.positions.end(), {0.2f * n[0], 0.2f * n[1], 1.f + 0.2f * n[2]});
      m.colors.insert(m.colors.end(), {static_cast<uint8_t>(30 * r), static_cast<uint8_t>(20 * s), 128});
      if (normals) m.normals.insert(m.normals.end(), {n[0], n[1], n[2]});
    }
  for (int r = 0; r < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      const int a = r * segments + s, b = r * segments + (s + 1) % segments;
      m.triangles.insert(m.triangles.end(), {a, a + segments, b + segments, a, b + segments, b});
    }
  return m;
}

std::vector<uint8_t> Bytes(const std::string& text) { return std::vector<uint8_t>(text.begin(), text.end()); }

void DepthSeeds(SeedWriter* w) {
  struct Case {
    int width, height, zero_every;
  };
  const Case cases[] = {{1, 1, 0}, {8, 6, 4}, {16, 12, 8}, {16, 12, 1}, {13, 7, 0}};
  const struct {
    const char* set;
    DepthEncoding encoding;
  } codecs[] = {{"depth_raw16", DepthEncoding::kRaw16}, {"depth_png16", DepthEncoding::kPng16},
                {"depth_rvl", DepthEncoding::kRvl}};
  for (const auto& codec : codecs) {
    int k = 0;
    for (const Case& c : cases) {
      const cv::Mat depth = Depth(c.width, c.height, c.zero_every, 10 + k);
      const auto bytes = SeedWriter::Check(EncodeDepth(depth, codec.encoding), codec.set);
      w->Write(codec.set, "seed-" + std::to_string(k++), WithSizePrefix(c.width, c.height, bytes));
    }
  }
}

void ColorSeeds(SeedWriter* w) {
  const int sizes[][2] = {{1, 1}, {8, 8}, {16, 12}, {13, 7}};
  int k = 0;
  for (const auto& s : sizes) {
    const cv::Mat color = Color(s[0], s[1], 20 + k);
    w->Write("color_raw", "seed-" + std::to_string(k),
             WithSizePrefix(s[0], s[1], SeedWriter::Check(EncodeColor(color, ColorEncoding::kRawBgr8), "raw")));
    for (int quality : {50, 95})
      w->Write("color_jpeg", "seed-" + std::to_string(k) + "-q" + std::to_string(quality),
               WithSizePrefix(s[0], s[1], SeedWriter::Check(EncodeColor(color, ColorEncoding::kJpeg, quality), "jpeg")));
    ++k;
  }
  // Greyscale and progressive JPEGs reach other libjpeg paths than our encoder's output does.
  std::vector<uint8_t> grey, progressive;
  cv::Mat grey_image;
  cv::cvtColor(Color(16, 12, 30), grey_image, cv::COLOR_BGR2GRAY);
  if (!cv::imencode(".jpg", grey_image, grey)) SeedWriter::Fail("cannot encode a greyscale JPEG");
  w->Write("color_jpeg", "seed-grey", WithSizePrefix(16, 12, grey));
  if (!cv::imencode(".jpg", Color(16, 12, 31), progressive, {cv::IMWRITE_JPEG_PROGRESSIVE, 1}))
    SeedWriter::Fail("cannot encode a progressive JPEG");
  w->Write("color_jpeg", "seed-progressive", WithSizePrefix(16, 12, progressive));
}

void MeshSeeds(SeedWriter* w) {
  const TriangleMesh meshes[] = {Tetrahedron(), Sphere(3, 4, false), Sphere(4, 6, true)};
  int k = 0;
  for (const TriangleMesh& mesh : meshes) {
    for (int speed : {0, 7, 10}) {
      DracoOptions options;
      options.speed = speed;
      options.include_normals = !mesh.normals.empty();
      options.position_bits = speed == 0 ? 8 : 14;
      w->Write("draco", "seed-" + std::to_string(k) + "-speed" + std::to_string(speed),
               SeedWriter::Check(EncodeMeshDraco(mesh, options), "draco"));
    }
    w->Write("ply", "seed-" + std::to_string(k) + ".ply", SeedWriter::Check(EncodePly(mesh), "ply"));
    ++k;
  }
  TriangleMesh bare = Tetrahedron();
  bare.colors.clear();
  w->Write("ply", "seed-nocolor.ply", SeedWriter::Check(EncodePly(bare), "ply"));
  // ASCII, doubles, faces before vertices, alpha and comments: what other tools write.
  w->Write("ply", "seed-ascii.ply",
           Bytes("ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 4\nproperty double x\n"
                 "property double y\nproperty double z\nproperty float nx\nproperty float ny\nproperty float nz\n"
                 "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n"
                 "element face 2\nproperty list uchar uint vertex_indices\nend_header\n"
                 "0 0 0 0 0 1 255 0 0 255\n1 0 0 0 0 1 0 255 0 255\n0 1 0 0 0 1 0 0 255 255\n"
                 "1 1 0 0 0 1 9 9 9 255\n3 0 1 2\n3 1 3 2\n"));
  w->Write("ply", "seed-faces-first.ply",
           Bytes("ply\r\nformat ascii 1.0\r\nelement face 1\r\nproperty list int int vertex_index\r\n"
                 "element vertex 3\r\nproperty float x\r\nproperty float y\r\nproperty float z\r\nend_header\r\n"
                 "3 0 1 2\r\n0 0 0\r\n1e-3 0 0\r\n0 -2.5E+1 0\r\n"));
}

void FrameSeeds(SeedWriter* w) {
  RgbdFrame frame;
  frame.utime = 1700000000000000;
  frame.seq = 42;
  frame.source_id = "synthetic:tube";
  frame.intrinsics = Intrinsics{20.f, 20.f, 7.5f, 5.5f, 16, 12};
  frame.depth_scale = 1000.f;
  frame.depth = Depth(16, 12, 6, 40);
  const cv::Mat color = Color(16, 12, 41);
  const DepthEncoding depths[] = {DepthEncoding::kRaw16, DepthEncoding::kPng16, DepthEncoding::kRvl};
  const ColorEncoding colors[] = {ColorEncoding::kNone, ColorEncoding::kRawBgr8, ColorEncoding::kJpeg};
  for (DepthEncoding d : depths)
    for (ColorEncoding c : colors) {
      FrameEncodeOptions options;
      options.depth = d;
      options.color = c;
      frame.color = c == ColorEncoding::kNone ? cv::Mat() : color;
      const auto msg = SeedWriter::Check(FrameToMessage(frame, options), "frame");
      w->WriteLcm("lcm_frame", std::string("seed-") + DepthEncodingName(d) + "-" + ColorEncodingName(c), msg);
    }
}

void MeshMessageSeeds(SeedWriter* w) {
  const TriangleMesh sphere = Sphere(3, 4, false);
  w->WriteLcm("lcm_mesh", "seed-draco",
              SeedWriter::Check(MeshToMessage(sphere, 1700000000000000, 7, vdeform::mesh_t::KIND_LIVE), "mesh"));
  w->WriteLcm("lcm_mesh", "seed-raw",
              SeedWriter::Check(MeshToMessage(Tetrahedron(), 1700000000000000, 8, vdeform::mesh_t::KIND_CANONICAL,
                                              vdeform::mesh_t::ENCODING_RAW),
                                "mesh"));
  w->WriteLcm("lcm_mesh", "seed-empty",
              SeedWriter::Check(MeshToMessage(TriangleMesh(), 1700000000000000, 0, vdeform::mesh_t::KIND_LIVE), "mesh"));
  // Signed under the fuzz targets' output key, so the verifier's accepting path is reached.
  vdeform::mesh_t signed_mesh =
      SeedWriter::Check(MeshToMessage(sphere, 1700000000000000, 9, vdeform::mesh_t::KIND_LIVE), "mesh");
  signed_mesh.epoch = 77;
  signed_mesh.out_seq = 12;
  if (!SignMesh(kOutputKey, &signed_mesh).ok()) SeedWriter::Fail("cannot sign the mesh seed");
  w->WriteLcm("lcm_mesh", "seed-draco-signed", signed_mesh);
}

void ControlSeeds(SeedWriter* w) {
  const struct {
    int8_t command;
    const char* path;
    int auth_bytes;
  } cases[] = {{vdeform::control_t::COMMAND_RESET, "", 0},
               {vdeform::control_t::COMMAND_SAVE_SNAPSHOT, "run-1/after-reset", 32},
               {vdeform::control_t::COMMAND_REQUEST_MESH, "", 0}};
  int k = 0;
  for (const auto& c : cases) {
    vdeform::control_t msg{};
    msg.utime = 1700000000000000 + k;
    msg.command = c.command;
    msg.path = c.path;
    msg.sender = "vdeform-viewer@host";
    msg.auth.assign(static_cast<size_t>(c.auth_bytes), static_cast<uint8_t>(0xA5));
    msg.auth_size = c.auth_bytes;
    w->WriteLcm("lcm_control", "seed-" + std::to_string(k++), msg);
  }
}

void StatusSeeds(SeedWriter* w) {
  vdeform::server_status_t msg{};
  msg.utime = 1700000000000000;
  msg.state = vdeform::server_status_t::STATE_TRACKING;
  msg.message = "tracking on pthread-cpu";
  msg.frames_received = 100;
  msg.frames_processed = 90;
  msg.reject_reason = {"malformed_message", "depth"};
  msg.reject_count = {3, 1};
  msg.num_reject_reasons = 2;
  msg.last_processed_seq = 99;
  msg.last_source_id = "synthetic:tube";
  msg.stage_name = {"preprocess", "track", "fuse"};
  msg.stage_ms_last = {1.f, 20.f, 3.f};
  msg.stage_ms_mean = {1.1f, 19.f, 3.2f};
  msg.num_stages = 3;
  msg.fps = 9.5f;
  w->WriteLcm("lcm_status", "seed-tracking", msg);
  msg.epoch = 77;
  msg.out_seq = 13;
  if (!SignStatus(kOutputKey, &msg).ok()) SeedWriter::Fail("cannot sign the status seed");
  w->WriteLcm("lcm_status", "seed-tracking-signed", msg);
  vdeform::server_status_t idle{};
  idle.state = vdeform::server_status_t::STATE_IDLE;
  idle.last_processed_seq = -1;
  w->WriteLcm("lcm_status", "seed-idle", idle);
}

// fuzz_server_gate: sequences of [kind][u16 length][message] records (kind even = frame, odd =
// control), with the source ids and the HMAC keys that target configures: in-order frames, a
// duplicate, a gap, a restart, a foreign source, a signed RESET and an unsigned one; signed frames
// (capture-a under 32 'a' bytes, capture-b under 32 'b'), a restart with a new epoch, a replay of
// the earlier epoch and a frame signed under the other source's key; a forged jump and a real one.
void GateSeeds(SeedWriter* w) {
  const std::string key = "fuzz-control-key-0123456789";
  const int64_t now = 1764633600000000;
  auto record = [](std::vector<uint8_t>* out, uint8_t kind, const std::vector<uint8_t>& msg) {
    out->push_back(kind);
    out->push_back(static_cast<uint8_t>(msg.size() & 0xff));
    out->push_back(static_cast<uint8_t>(msg.size() >> 8));
    out->insert(out->end(), msg.begin(), msg.end());
  };
  auto encode = [](const auto& msg) {
    std::vector<uint8_t> bytes(static_cast<size_t>(msg.getEncodedSize()));
    msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    return bytes;
  };
  auto frame_message = [&](const std::string& source, int64_t seq, int64_t utime, int64_t epoch) {
    RgbdFrame f;
    f.utime = utime;
    f.seq = seq;
    f.source_id = source;
    f.intrinsics = Intrinsics{20.f, 20.f, 7.5f, 5.5f, 16, 12};
    f.depth_scale = 1000.f;
    f.depth = Depth(16, 12, 6, 50 + uint32_t(seq));
    FrameEncodeOptions options;
    options.color = ColorEncoding::kNone;
    vdeform::rgbd_frame_t m = SeedWriter::Check(FrameToMessage(f, options), "gate frame");
    m.epoch = epoch;
    return m;
  };
  auto frame = [&](const std::string& source, int64_t seq, int64_t utime) {
    return encode(frame_message(source, seq, utime, 1));
  };
  auto signed_frame = [&](const std::string& source, int64_t seq, int64_t utime, int64_t epoch, char key) {
    vdeform::rgbd_frame_t m = frame_message(source, seq, utime, epoch);
    const Status s = SignFrame(std::string(32, key), &m);
    if (!s.ok()) SeedWriter::Fail("signed gate frame: " + s.ToString());
    return encode(m);
  };
  auto control = [&](int8_t command, int64_t utime, bool sign) {
    vdeform::control_t m{};
    m.utime = utime;
    m.command = command;
    m.path = command == vdeform::control_t::COMMAND_SAVE_SNAPSHOT ? "snap" : "";
    m.sender = "seed";
    m.auth_size = 0;
    if (sign) SignControl(key, &m);
    return encode(m);
  };
  std::vector<uint8_t> seq;
  record(&seq, 0, frame("capture-a", 0, now));
  record(&seq, 0, frame("capture-a", 1, now + 1));
  record(&seq, 2, frame("capture-a", 1, now + 1));
  record(&seq, 0, frame("capture-a", 5, now + 5));
  record(&seq, 0, frame("capture-b", 0, now + 6));
  record(&seq, 0, frame("intruder", 0, now + 7));
  record(&seq, 0, frame("capture-a", 0, now + 9));
  w->Write("server_gate", "seed-frames", seq);
  std::vector<uint8_t> ctl;
  record(&ctl, 1, control(vdeform::control_t::COMMAND_RESET, now, true));
  record(&ctl, 1, control(vdeform::control_t::COMMAND_RESET, now, true));
  record(&ctl, 3, control(vdeform::control_t::COMMAND_SAVE_SNAPSHOT, now + 10, false));
  record(&ctl, 1, control(vdeform::control_t::COMMAND_SAVE_SNAPSHOT, now + 20, true));
  record(&ctl, 1, control(vdeform::control_t::COMMAND_REQUEST_MESH, now + 30, false));
  record(&ctl, 0, frame("capture-a", 0, now));
  w->Write("server_gate", "seed-control", ctl);
  std::vector<uint8_t> sig;
  record(&sig, 0, signed_frame("capture-a", 0, now, 7, 'a'));
  record(&sig, 0, signed_frame("capture-a", 1, now + 1, 7, 'a'));
  record(&sig, 0, signed_frame("capture-b", 0, now + 2, 8, 'b'));
  record(&sig, 0, signed_frame("capture-b", 1, now + 3, 8, 'a'));
  record(&sig, 0, signed_frame("capture-a", 0, now + 10, 9, 'a'));
  record(&sig, 0, signed_frame("capture-a", 1, now + 1, 7, 'a'));
  record(&sig, 0, frame("capture-a", 1, now + 11));
  w->Write("server_gate", "seed-signed", sig);
  // A forged number near 2^62 amid a stream, then a jump confirmed by the frames after it.
  std::vector<uint8_t> jump;
  for (int64_t s = 0; s < 3; ++s) record(&jump, 0, frame("capture-a", s, now + s));
  record(&jump, 0, frame("capture-a", int64_t(1) << 62, now + 3));
  record(&jump, 0, frame("capture-a", 3, now + 4));
  for (int64_t s = 1000; s < 1003; ++s) record(&jump, 0, frame("capture-a", s, now + s));
  record(&jump, 0, frame("capture-a", 2, now + 2));
  w->Write("server_gate", "seed-jump", jump);
}

}  // namespace
}  // namespace vd::fuzz

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: vd_fuzz_seeds OUT_DIR\n");
    return 2;
  }
  vd::fuzz::Quiet();
  vd::fuzz::SeedWriter writer(argv[1]);
  vd::fuzz::DepthSeeds(&writer);
  vd::fuzz::ColorSeeds(&writer);
  vd::fuzz::MeshSeeds(&writer);
  vd::fuzz::FrameSeeds(&writer);
  vd::fuzz::MeshMessageSeeds(&writer);
  vd::fuzz::ControlSeeds(&writer);
  vd::fuzz::StatusSeeds(&writer);
  vd::fuzz::GateSeeds(&writer);
  std::printf("vd_fuzz_seeds: %d seeds in %s\n", writer.count(), argv[1]);
  return 0;
}
