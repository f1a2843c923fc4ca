// LCM wire safety: lcm-gen's decode() trusts declared array sizes; ValidateLcmWire must refuse
// hostile input before decode() allocates for it.
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <new>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "vd/common/messages.h"

// Records the largest single allocation and refuses absurd ones with bad_alloc, so the test can
// see what a decoder tried to allocate without the machine actually committing gigabytes.
namespace {
std::atomic<size_t> g_largest_allocation{0};
constexpr size_t kRefuseAbove = size_t{1} << 30;
}  // namespace

// GCC flags free() on memory from operator new even when both are replaced together, as here.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(size_t n) {
  size_t seen = g_largest_allocation.load();
  while (n > seen && !g_largest_allocation.compare_exchange_weak(seen, n)) {
  }
  if (n > kRefuseAbove) throw std::bad_alloc();
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, size_t) noexcept { std::free(p); }

namespace vd {
namespace {

template <typename Msg>
std::vector<uint8_t> Wire(const Msg& msg) {
  std::vector<uint8_t> out(msg.getEncodedSize());
  EXPECT_EQ(msg.encode(out.data(), 0, static_cast<int>(out.size())), static_cast<int>(out.size()));
  return out;
}

vdeform::rgbd_frame_t Frame() {
  vdeform::rgbd_frame_t m{};
  m.utime = 1;
  m.seq = 2;
  m.source_id = "camera-1";
  m.fx = m.fy = 500.f;
  m.cx = 16.f;
  m.cy = 12.f;
  m.width = 32;
  m.height = 24;
  m.depth_scale = 1000.f;
  m.depth_encoding = vdeform::rgbd_frame_t::DEPTH_RAW16;
  m.depth_data.assign(32 * 24 * 2, 3);
  m.depth_size = static_cast<int32_t>(m.depth_data.size());
  m.color_encoding = vdeform::rgbd_frame_t::COLOR_RAW_BGR8;
  m.color_data.assign(32 * 24 * 3, 200);
  m.color_size = static_cast<int32_t>(m.color_data.size());
  return m;
}

vdeform::mesh_t Mesh() {
  vdeform::mesh_t m{};
  m.utime = 5;
  m.kind = vdeform::mesh_t::KIND_LIVE;
  m.encoding = vdeform::mesh_t::ENCODING_RAW;
  m.data.assign(77, 1);
  m.data_size = 77;
  m.bbox_max[2] = 1.f;
  return m;
}

vdeform::server_status_t ServerStatus() {
  vdeform::server_status_t m{};
  m.message = "tracking";
  m.num_reject_reasons = 2;
  m.reject_reason = {"bad size", "bad depth"};
  m.reject_count = {3, 4};
  m.last_source_id = "camera-1";
  m.num_stages = 3;
  m.stage_name = {"icp", "fuse", "mesh"};
  m.stage_ms_last = {1.f, 2.f, 3.f};
  m.stage_ms_mean = {1.5f, 2.5f, 3.5f};
  return m;
}

vdeform::control_t Control() {
  vdeform::control_t m{};
  m.command = vdeform::control_t::COMMAND_SAVE_SNAPSHOT;
  m.path = "snap/1";
  m.sender = "viewer";
  m.auth.assign(32, 9);
  m.auth_size = 32;
  return m;
}

// Full bytes pass and every strict prefix fails: the walker covers the layout to the last byte.
template <typename Msg>
void ExpectExactLayout(const Msg& msg) {
  SCOPED_TRACE(Msg::getTypeName());
  const std::vector<uint8_t> wire = Wire(msg);
  EXPECT_TRUE(ValidateLcmWire<Msg>(wire.data(), wire.size()).ok());
  ASSERT_TRUE(DecodeLcm<Msg>(wire.data(), wire.size()).ok());
  for (size_t n = 0; n < wire.size(); ++n) {
    ASSERT_FALSE(ValidateLcmWire<Msg>(wire.data(), n).ok()) << "prefix of " << n << " bytes accepted";
    ASSERT_FALSE(DecodeLcm<Msg>(wire.data(), n).ok());
  }
}

TEST(LcmWireTest, WalkerMatchesGeneratedLayoutForEveryType) {
  ExpectExactLayout(Frame());
  ExpectExactLayout(Mesh());
  ExpectExactLayout(ServerStatus());
  ExpectExactLayout(Control());
}

void PutBe32(std::vector<uint8_t>* wire, size_t at, int32_t v) {
  const uint32_t u = static_cast<uint32_t>(v);
  for (int k = 0; k < 4; ++k) (*wire)[at + k] = static_cast<uint8_t>(u >> (24 - 8 * k));
}

// Offset of rgbd_frame_t.depth_size in Frame()'s wire bytes.
size_t DepthSizeOffset() { return 8 + 24 + 4 + std::strlen("camera-1") + 1 + 16 + 8 + 4 + 1; }

TEST(LcmWireTest, GeneratedDecodeAllocatesTheDeclaredSize) {
  // Documents the lcm-gen behaviour that ValidateLcmWire exists for.
  std::vector<uint8_t> wire = Wire(Frame());
  PutBe32(&wire, DepthSizeOffset(), INT32_MAX);
  wire.resize(DepthSizeOffset() + 4 + 10);
  vdeform::rgbd_frame_t msg;
  g_largest_allocation = 0;
  bool threw = false;
  try {
    (void)msg.decode(wire.data(), 0, static_cast<int>(wire.size()));
  } catch (const std::bad_alloc&) {
    threw = true;
  }
  EXPECT_TRUE(threw);
  EXPECT_GE(g_largest_allocation.load(), static_cast<size_t>(INT32_MAX));
}

TEST(LcmWireTest, HugeDeclaredSizeInTruncatedInputIsRefusedWithoutAllocating) {
  std::vector<uint8_t> wire = Wire(Frame());
  PutBe32(&wire, DepthSizeOffset(), INT32_MAX);
  wire.resize(DepthSizeOffset() + 4 + 10);
  g_largest_allocation = 0;
  auto decoded = DecodeLcm<vdeform::rgbd_frame_t>(wire.data(), wire.size());
  ASSERT_FALSE(decoded.ok());
  EXPECT_EQ(decoded.status().code(), StatusCode::kDataLoss);
  EXPECT_NE(decoded.status().message().find("depth_data"), std::string::npos) << decoded.status().message();
  EXPECT_LT(g_largest_allocation.load(), size_t{64} * 1024);
}

TEST(LcmWireTest, NegativeCountsAndEmptyStringsAreRefused) {
  std::vector<uint8_t> wire = Wire(Frame());
  PutBe32(&wire, DepthSizeOffset(), -1);
  auto decoded = DecodeLcm<vdeform::rgbd_frame_t>(wire.data(), wire.size());
  ASSERT_FALSE(decoded.ok());
  EXPECT_NE(decoded.status().message().find("negative"), std::string::npos) << decoded.status().message();

  // source_id length 0 would make lcm-gen assign (size_t)-1 characters.
  wire = Wire(Frame());
  PutBe32(&wire, 8 + 24, 0);
  decoded = DecodeLcm<vdeform::rgbd_frame_t>(wire.data(), wire.size());
  ASSERT_FALSE(decoded.ok());
  EXPECT_NE(decoded.status().message().find("source_id"), std::string::npos) << decoded.status().message();
  PutBe32(&wire, 8 + 24, INT32_MIN);
  EXPECT_FALSE(DecodeLcm<vdeform::rgbd_frame_t>(wire.data(), wire.size()).ok());

  // rgbd_frame_t.auth_size (the last field): negative, or more bytes than the message holds.
  wire = Wire(Frame());
  const size_t frame_auth_at = wire.size() - 4;
  PutBe32(&wire, frame_auth_at, -1);
  decoded = DecodeLcm<vdeform::rgbd_frame_t>(wire.data(), wire.size());
  ASSERT_FALSE(decoded.ok());
  EXPECT_NE(decoded.status().message().find("auth_size = -1 is negative"), std::string::npos)
      << decoded.status().message();
  PutBe32(&wire, frame_auth_at, INT32_MAX);
  g_largest_allocation = 0;
  decoded = DecodeLcm<vdeform::rgbd_frame_t>(wire.data(), wire.size());
  ASSERT_FALSE(decoded.ok());
  EXPECT_NE(decoded.status().message().find("rgbd_frame_t.auth needs"), std::string::npos)
      << decoded.status().message();
  EXPECT_LT(g_largest_allocation.load(), size_t{64} * 1024);

  // server_status_t: 2^31-1 reject reasons in a short message.
  std::vector<uint8_t> status = Wire(ServerStatus());
  const size_t count_at = 8 + 8 + 1 + 4 + std::strlen("tracking") + 1 + 32;
  PutBe32(&status, count_at, INT32_MAX);
  g_largest_allocation = 0;
  EXPECT_FALSE(DecodeLcm<vdeform::server_status_t>(status.data(), status.size()).ok());
  EXPECT_LT(g_largest_allocation.load(), size_t{64} * 1024);

  // control_t: negative auth_size.
  std::vector<uint8_t> control = Wire(Control());
  const size_t auth_at = 8 + 8 + 1 + 4 + std::strlen("snap/1") + 1 + 4 + std::strlen("viewer") + 1;
  PutBe32(&control, auth_at, -7);
  EXPECT_FALSE(DecodeLcm<vdeform::control_t>(control.data(), control.size()).ok());

  // mesh_t: data_size larger than the bytes.
  std::vector<uint8_t> mesh = Wire(Mesh());
  PutBe32(&mesh, 8 + 8 + 8 + 1 + 4 + 4 + 1, 1 << 30);
  EXPECT_FALSE(DecodeLcm<vdeform::mesh_t>(mesh.data(), mesh.size()).ok());
}

TEST(LcmWireTest, WrongTypeAndNullAreRefused) {
  const std::vector<uint8_t> wire = Wire(Mesh());
  auto as_frame = DecodeLcm<vdeform::rgbd_frame_t>(wire.data(), wire.size());
  ASSERT_FALSE(as_frame.ok());
  EXPECT_NE(as_frame.status().message().find("fingerprint"), std::string::npos);
  EXPECT_FALSE(DecodeLcm<vdeform::mesh_t>(nullptr, 100).ok());
}

// Random bytes behind a correct fingerprint, and single-bit flips of valid messages: decode
// either fails or yields a message the converters then accept or refuse, never a crash, and
// allocations stay within the input's size.
template <typename Msg>
void FuzzType(const Msg& valid, uint32_t seed, int iterations) {
  SCOPED_TRACE(Msg::getTypeName());
  std::mt19937 rng(seed);
  const std::vector<uint8_t> wire = Wire(valid);
  for (int it = 0; it < iterations; ++it) {
    std::vector<uint8_t> bytes;
    if (it % 2) {
      bytes = wire;
      const size_t bit = rng() % (bytes.size() * 8);
      bytes[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
    } else {
      bytes.assign(wire.begin(), wire.begin() + 8);
      bytes.resize(8 + rng() % 200);
      for (size_t k = 8; k < bytes.size(); ++k) bytes[k] = static_cast<uint8_t>(rng());
    }
    g_largest_allocation = 0;
    auto decoded = DecodeLcm<Msg>(bytes.data(), bytes.size());
    ASSERT_LT(g_largest_allocation.load(), bytes.size() + 64 * 1024);
    if constexpr (std::is_same_v<Msg, vdeform::rgbd_frame_t>) {
      if (decoded.ok()) {
        auto frame = MessageToFrame(*decoded);
        if (frame.ok()) {
          EXPECT_TRUE(frame->Validate().ok());
        }
      }
    }
  }
}

TEST(LcmWireTest, RandomAndBitFlippedBytesNeverCrash) {
  FuzzType(Frame(), 1, 1000);
  FuzzType(Mesh(), 2, 500);
  FuzzType(ServerStatus(), 3, 500);
  FuzzType(Control(), 4, 500);
}

}  // namespace
}  // namespace vd
