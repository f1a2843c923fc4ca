// Depth, colour and mesh codec cost at 640x480 / ~100k triangles: encode and decode time and
// encoded bytes (counter "bytes"); signing and verifying a frame message (HMAC-SHA256) against
// decoding it. Uses 7-Scenes frame 0 when ../shared/data is present, else a
// synthetic noisy depth ramp and colour gradient (the label says which).
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/imgcodecs.hpp>

#include "vd/common/auth.h"
#include "vd/common/codecs.h"
#include "vd/common/messages.h"

namespace vd {
namespace {

struct Images {
  cv::Mat depth;
  cv::Mat color;
  std::string label;
};

const Images& TestImages() {
  static const Images images = [] {
    Images im;
    const std::string dir = std::string(VD_SHARED_DATA_DIR) + "/7scenes_redkitchen/";
    im.depth = cv::imread(dir + "frame-000000.depth.png", cv::IMREAD_UNCHANGED);
    im.color = cv::imread(dir + "frame-000000.color.jpg", cv::IMREAD_COLOR);
    if (im.depth.type() == CV_16UC1 && im.depth.size() == cv::Size(640, 480) && im.color.size() == im.depth.size()) {
      im.label = "7scenes frame-000000";
      return im;
    }
    im.label = "SYNTHETIC noisy ramp (no shared data)";
    im.depth.create(480, 640, CV_16UC1);
    im.color.create(480, 640, CV_8UC3);
    std::mt19937 rng(1);
    std::normal_distribution<double> noise(0.0, 4.0);
    for (int y = 0; y < 480; ++y)
      for (int x = 0; x < 640; ++x) {
        const bool hole = (x < 20) || ((x / 40 + y / 30) % 7 == 0);
        im.depth.at<uint16_t>(y, x) = hole ? 0 : static_cast<uint16_t>(900 + 2 * x + y + noise(rng));
        im.color.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<uint8_t>(x / 3), static_cast<uint8_t>(y / 2),
                                                 static_cast<uint8_t>(128 + 60 * std::sin(x * 0.05) + noise(rng)));
      }
    return im;
  }();
  return images;
}

// PNG through cv::imencode with an explicit zlib level (our API uses OpenCV's default).
std::vector<uint8_t> EncodePngLevel(const cv::Mat& depth, int level) {
  std::vector<uint8_t> out;
  cv::imencode(".png", depth, out, {cv::IMWRITE_PNG_COMPRESSION, level});
  return out;
}

// png_level < 0: EncodeDepth (OpenCV default parameters).
void BM_DepthEncode(benchmark::State& state, DepthEncoding encoding, int png_level) {
  const Images& im = TestImages();
  size_t bytes = 0;
  for (auto _ : state) {
    if (png_level >= 0) {
      auto out = EncodePngLevel(im.depth, png_level);
      bytes = out.size();
      benchmark::DoNotOptimize(out.data());
    } else {
      auto out = EncodeDepth(im.depth, encoding);
      if (!out.ok()) state.SkipWithError(out.status().ToString().c_str());
      bytes = out->size();
      benchmark::DoNotOptimize(out->data());
    }
  }
  state.counters["bytes"] = static_cast<double>(bytes);
  state.counters["ratio_vs_raw"] = static_cast<double>(bytes) / (640.0 * 480.0 * 2.0);
  state.SetLabel(im.label);
}

void BM_DepthDecode(benchmark::State& state, DepthEncoding encoding, int png_level) {
  const Images& im = TestImages();
  const std::vector<uint8_t> bytes = png_level >= 0 ? EncodePngLevel(im.depth, png_level) : *EncodeDepth(im.depth, encoding);
  for (auto _ : state) {
    auto depth = DecodeDepth(bytes.data(), bytes.size(), encoding, im.depth.cols, im.depth.rows);
    if (!depth.ok()) state.SkipWithError(depth.status().ToString().c_str());
    benchmark::DoNotOptimize(depth->data);
  }
  state.counters["bytes"] = static_cast<double>(bytes.size());
  state.SetLabel(im.label);
}

void BM_JpegEncode(benchmark::State& state) {
  const Images& im = TestImages();
  const int quality = static_cast<int>(state.range(0));
  size_t bytes = 0;
  for (auto _ : state) {
    auto out = EncodeColor(im.color, ColorEncoding::kJpeg, quality);
    if (!out.ok()) state.SkipWithError(out.status().ToString().c_str());
    bytes = out->size();
    benchmark::DoNotOptimize(out->data());
  }
  state.counters["bytes"] = static_cast<double>(bytes);
  state.SetLabel(im.label);
}

void BM_JpegDecode(benchmark::State& state) {
  const Images& im = TestImages();
  const std::vector<uint8_t> bytes = *EncodeColor(im.color, ColorEncoding::kJpeg, static_cast<int>(state.range(0)));
  for (auto _ : state) {
    auto color = DecodeColor(bytes.data(), bytes.size(), ColorEncoding::kJpeg, im.color.cols, im.color.rows);
    if (!color.ok()) state.SkipWithError(color.status().ToString().c_str());
    benchmark::DoNotOptimize(color->data);
  }
  state.counters["bytes"] = static_cast<double>(bytes.size());
  state.SetLabel(im.label);
}

// The peers: OpenCV's imencode/imdecode on the same image, which DecodeColor/EncodeColor used
// before calling libjpeg directly (same bytes and pixels; OpenCV 4.6 swaps BGR and RGB per pixel).
void BM_JpegEncodeOpenCv(benchmark::State& state) {
  const Images& im = TestImages();
  for (auto _ : state) {
    std::vector<uint8_t> out;
    cv::imencode(".jpg", im.color, out, {cv::IMWRITE_JPEG_QUALITY, static_cast<int>(state.range(0))});
    benchmark::DoNotOptimize(out.data());
  }
  state.SetLabel(im.label);
}

void BM_JpegDecodeOpenCv(benchmark::State& state) {
  const Images& im = TestImages();
  const std::vector<uint8_t> bytes = *EncodeColor(im.color, ColorEncoding::kJpeg, static_cast<int>(state.range(0)));
  for (auto _ : state) {
    const cv::Mat color = cv::imdecode(bytes, cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
    benchmark::DoNotOptimize(color.data);
  }
  state.SetLabel(im.label);
}

// UV sphere of radius 0.5 m: 158 rings x 316 segments = 99,224 triangles, 49,614 vertices, with
// a smooth colour field like a textured reconstruction.
const TriangleMesh& BenchMesh() {
  static const TriangleMesh mesh = [] {
    const int rings = 158, segments = 316;
    const float pi = 3.14159265f;
    TriangleMesh m;
    auto add = [&](float t, float p) {
      const float x = 0.5f * std::sin(t) * std::cos(p), y = 0.5f * std::sin(t) * std::sin(p), z = 0.5f * std::cos(t) + 1.f;
      m.positions.insert(m.positions.end(), {x, y, z});
      m.colors.insert(m.colors.end(), {static_cast<uint8_t>(128 + 120 * x), static_cast<uint8_t>(128 + 120 * y),
                                       static_cast<uint8_t>(60 + 100 * (z - 0.5f))});
    };
    add(0.f, 0.f);
    for (int r = 1; r < rings; ++r)
      for (int s = 0; s < segments; ++s) add(pi * r / rings, 2 * pi * s / segments);
    add(pi, 0.f);
    const int south = static_cast<int>(m.num_vertices()) - 1;
    auto ring = [&](int r, int s) { return 1 + (r - 1) * segments + (s % segments); };
    for (int s = 0; s < segments; ++s) {
      m.triangles.insert(m.triangles.end(), {0, ring(1, s), ring(1, s + 1)});
      m.triangles.insert(m.triangles.end(), {south, ring(rings - 1, s + 1), ring(rings - 1, s)});
    }
    for (int r = 1; r + 1 < rings; ++r)
      for (int s = 0; s < segments; ++s) {
        m.triangles.insert(m.triangles.end(), {ring(r, s), ring(r + 1, s), ring(r + 1, s + 1)});
        m.triangles.insert(m.triangles.end(), {ring(r, s), ring(r + 1, s + 1), ring(r, s + 1)});
      }
    return m;
  }();
  return mesh;
}

DracoOptions Draco(int speed) {
  DracoOptions options;
  options.position_bits = 14;
  options.speed = speed;
  return options;
}

// Encodes `mesh` at the speed of the benchmark's argument (14 bits).
void EncodeDraco(benchmark::State& state, const TriangleMesh& mesh) {
  size_t bytes = 0;
  for (auto _ : state) {
    auto out = EncodeMeshDraco(mesh, Draco(static_cast<int>(state.range(0))));
    if (!out.ok()) state.SkipWithError(out.status().ToString().c_str());
    bytes = out->size();
    benchmark::DoNotOptimize(out->data());
  }
  state.counters["bytes"] = static_cast<double>(bytes);
  state.counters["triangles"] = static_cast<double>(mesh.num_triangles());
}

void BM_DracoEncode(benchmark::State& state) { EncodeDraco(state, BenchMesh()); }

// A live mesh as the server sends it since issue 16: with each vertex's canonical position (here the
// sphere before a smooth bend of up to 5 cm), the extra Draco attribute.
const TriangleMesh& BenchMeshWithCanonical() {
  static const TriangleMesh mesh = [] {
    TriangleMesh m = BenchMesh();
    m.canonical = m.positions;
    for (size_t i = 0; i < m.canonical.size(); i += 3) m.canonical[i] += 0.05f * std::sin(4.f * m.positions[i + 1]);
    return m;
  }();
  return mesh;
}

void BM_DracoEncodeCanonical(benchmark::State& state) { EncodeDraco(state, BenchMeshWithCanonical()); }

void BM_DracoDecode(benchmark::State& state) {
  const std::vector<uint8_t> bytes = *EncodeMeshDraco(BenchMesh(), Draco(static_cast<int>(state.range(0))));
  for (auto _ : state) {
    auto mesh = DecodeMeshDraco(bytes.data(), bytes.size());
    if (!mesh.ok()) state.SkipWithError(mesh.status().ToString().c_str());
    benchmark::DoNotOptimize(mesh->positions.data());
  }
  state.counters["bytes"] = static_cast<double>(bytes.size());
}

void BM_PlyEncode(benchmark::State& state) {
  size_t bytes = 0;
  for (auto _ : state) {
    auto out = EncodePly(BenchMesh());
    bytes = out->size();
    benchmark::DoNotOptimize(out->data());
  }
  state.counters["bytes"] = static_cast<double>(bytes);
}

void BM_PlyDecode(benchmark::State& state) {
  const std::vector<uint8_t> bytes = *EncodePly(BenchMesh());
  for (auto _ : state) {
    auto mesh = DecodePly(bytes.data(), bytes.size());
    if (!mesh.ok()) state.SkipWithError(mesh.status().ToString().c_str());
    benchmark::DoNotOptimize(mesh->positions.data());
  }
  state.counters["bytes"] = static_cast<double>(bytes.size());
}

// A frame message as vdeform-capture publishes it (the default RVL + JPEG 90, or raw depth and
// colour: 1.5 MB), for the cost of signing and verifying it against decoding it.
vdeform::rgbd_frame_t BenchFrameMessage(bool raw) {
  const Images& im = TestImages();
  RgbdFrame frame;
  frame.utime = 1764633600000000;
  frame.seq = 1;
  frame.source_id = "capture-bench";
  frame.intrinsics = Intrinsics{525.f, 525.f, 319.5f, 239.5f, im.depth.cols, im.depth.rows};
  frame.depth_scale = 1000.f;
  frame.depth = im.depth;
  frame.color = im.color;
  FrameEncodeOptions options;
  if (raw) {
    options.depth = DepthEncoding::kRaw16;
    options.color = ColorEncoding::kRawBgr8;
  }
  vdeform::rgbd_frame_t msg = *FrameToMessage(frame, options);
  msg.epoch = RandomEpoch();
  return msg;
}

const std::string kBenchFrameKey(kFrameKeyBytes, '\x42');

// Signing `msg` under kBenchFrameKey, as its sender does before publishing it.
template <typename Msg>
void BenchSign(benchmark::State& state, Msg msg, Status (*sign)(const std::string&, Msg*)) {
  for (auto _ : state) {
    const Status s = sign(kBenchFrameKey, &msg);
    if (!s.ok()) state.SkipWithError(s.ToString().c_str());
    benchmark::DoNotOptimize(msg.auth.data());
  }
  state.counters["bytes"] = static_cast<double>(msg.getEncodedSize());
}

// Verifying the signed `msg`, as its receiver does before using it.
template <typename Msg>
void BenchVerify(benchmark::State& state, Msg msg, Status (*sign)(const std::string&, Msg*),
                 Status (*verify)(const std::string&, const Msg&)) {
  if (!sign(kBenchFrameKey, &msg).ok()) state.SkipWithError("cannot sign");
  for (auto _ : state) {
    const Status s = verify(kBenchFrameKey, msg);
    if (!s.ok()) state.SkipWithError(s.ToString().c_str());
    benchmark::DoNotOptimize(s);
  }
  state.counters["bytes"] = static_cast<double>(msg.getEncodedSize());
}

void BM_FrameSign(benchmark::State& state) {
  BenchSign(state, BenchFrameMessage(state.range(0) != 0), &SignFrame);
  state.SetLabel(TestImages().label);
}

void BM_FrameVerify(benchmark::State& state) {
  BenchVerify(state, BenchFrameMessage(state.range(0) != 0), &SignFrame, &VerifyFrame);
  state.SetLabel(TestImages().label);
}

// The server's output since issue 15: the live mesh of BenchMeshWithCanonical (99,224 triangles,
// with the canonical attribute, Draco at the server's default options) and a status as the node
// fills it (its 8 stages, two reject reasons), signed by the server and verified by each viewer
// and lockstep capture.
vdeform::mesh_t BenchMeshMessage() {
  vdeform::mesh_t msg = *MeshToMessage(BenchMeshWithCanonical(), 1764633600000000, 41, vdeform::mesh_t::KIND_LIVE);
  msg.epoch = RandomEpoch();
  msg.out_seq = 1234;
  return msg;
}

vdeform::server_status_t BenchStatusMessage() {
  vdeform::server_status_t st{};
  st.utime = 1764633600000000;
  st.state = vdeform::server_status_t::STATE_TRACKING;
  st.message = "pthread-skylake-avx512 (Portable Computing Language)";
  st.frames_received = st.frames_processed = 1000;
  st.reject_reason = {"bad_signature", "unsigned"};
  st.reject_count = {3, 7};
  st.num_reject_reasons = 2;
  st.last_processed_seq = 999;
  st.last_source_id = "capture-host-12345";
  st.last_epoch = RandomEpoch();
  st.stage_name = {"preprocess", "raster", "icp", "nonrigid", "integrate", "marching_cubes", "download", "features"};
  st.stage_ms_last = st.stage_ms_mean = std::vector<float>(st.stage_name.size(), 12.5f);
  st.num_stages = int32_t(st.stage_name.size());
  st.checkpoint_message = "checkpoint of 1000 frames, 20480 KiB, 150 ms";
  st.epoch = RandomEpoch();
  st.out_seq = 1235;
  return st;
}

void BM_MeshSign(benchmark::State& state) { BenchSign(state, BenchMeshMessage(), &SignMesh); }
void BM_MeshVerify(benchmark::State& state) { BenchVerify(state, BenchMeshMessage(), &SignMesh, &VerifyMesh); }
void BM_StatusSign(benchmark::State& state) { BenchSign(state, BenchStatusMessage(), &SignStatus); }
void BM_StatusVerify(benchmark::State& state) {
  BenchVerify(state, BenchStatusMessage(), &SignStatus, &VerifyStatus);
}

// What the server's gate does with every valid frame after verifying it: both decoders.
void BM_FrameDecode(benchmark::State& state) {
  const vdeform::rgbd_frame_t msg = BenchFrameMessage(state.range(0) != 0);
  for (auto _ : state) {
    auto frame = MessageToFrame(msg);
    if (!frame.ok()) state.SkipWithError(frame.status().ToString().c_str());
    benchmark::DoNotOptimize(frame->depth.data);
  }
  state.counters["bytes"] = static_cast<double>(msg.depth_size + msg.color_size);
  state.SetLabel(TestImages().label);
}

BENCHMARK(BM_FrameSign)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FrameVerify)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FrameDecode)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_MeshSign)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_MeshVerify)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_StatusSign)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_StatusVerify)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_DepthEncode, raw16, DepthEncoding::kRaw16, -1)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DepthEncode, png16_default, DepthEncoding::kPng16, -1)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DepthEncode, png16_level1, DepthEncoding::kPng16, 1)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DepthEncode, png16_level6, DepthEncoding::kPng16, 6)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DepthEncode, rvl, DepthEncoding::kRvl, -1)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DepthDecode, raw16, DepthEncoding::kRaw16, -1)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DepthDecode, png16_default, DepthEncoding::kPng16, -1)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DepthDecode, png16_level1, DepthEncoding::kPng16, 1)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DepthDecode, png16_level6, DepthEncoding::kPng16, 6)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DepthDecode, rvl, DepthEncoding::kRvl, -1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_JpegEncode)->Arg(75)->Arg(90)->Arg(95)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_JpegDecode)->Arg(75)->Arg(90)->Arg(95)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_JpegEncodeOpenCv)->Arg(90)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_JpegDecodeOpenCv)->Arg(90)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DracoEncode)->Arg(3)->Arg(7)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DracoEncodeCanonical)->Arg(3)->Arg(7)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DracoDecode)->Arg(3)->Arg(7)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PlyEncode)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PlyDecode)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace vd

BENCHMARK_MAIN();
