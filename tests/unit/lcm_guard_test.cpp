// The in-process LCM guard: which datagrams its socket filter lets through to LCM, and that it
// finds LCM's receive socket. The datagrams go over loopback unicast to a plain UDP socket; the
// filter reads them exactly as it reads LCM's multicast ones.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

#include "vd/common/lcm_guard.h"

namespace vd {
namespace {

void PutU32(std::vector<uint8_t>* b, size_t at, uint32_t v) {
  const uint32_t be = htonl(v);
  std::memcpy(b->data() + at, &be, 4);
}

// An LCM fragment datagram: the 20-byte long header, then "CHANNEL\0" in fragment 0, then bytes;
// its last byte is `id`, so the receiver can tell which datagrams arrived.
std::vector<uint8_t> Fragment(uint32_t msg_size, uint32_t offset, uint16_t number, uint8_t id, size_t bytes = 200) {
  std::vector<uint8_t> b(std::max<size_t>(bytes, 40), 0x55);
  PutU32(&b, 0, 0x4c433033);
  PutU32(&b, 4, 7);
  PutU32(&b, 8, msg_size);
  PutU32(&b, 12, offset);
  const uint16_t no = htons(number), count = htons(40);
  std::memcpy(b.data() + 16, &no, 2);
  std::memcpy(b.data() + 18, &count, 2);
  std::memcpy(b.data() + 20, "VDEFORM_FRAMES", 15);
  b.resize(bytes);
  b.back() = id;
  return b;
}

class LcmFilterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    rx_ = socket(AF_INET, SOCK_DGRAM, 0);
    tx_ = socket(AF_INET, SOCK_DGRAM, 0);
    ASSERT_GE(rx_, 0);
    ASSERT_GE(tx_, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(bind(rx_, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    socklen_t len = sizeof to_;
    ASSERT_EQ(getsockname(rx_, reinterpret_cast<sockaddr*>(&to_), &len), 0);
    timeval tv{0, 200000};
    ASSERT_EQ(setsockopt(rx_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv), 0);
  }
  void TearDown() override {
    close(rx_);
    close(tx_);
  }
  void Send(const std::vector<uint8_t>& d) {
    ASSERT_EQ(sendto(tx_, d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&to_), sizeof to_),
              static_cast<ssize_t>(d.size()));
  }
  // The last bytes of every datagram that arrived (their ids), and the sizes of all.
  std::set<int> Received(std::vector<size_t>* sizes = nullptr) {
    std::set<int> ids;
    uint8_t buf[70000];
    for (ssize_t n; (n = recv(rx_, buf, sizeof buf, 0)) > 0;) {
      ids.insert(buf[n - 1]);
      if (sizes != nullptr) sizes->push_back(static_cast<size_t>(n));
    }
    return ids;
  }
  int rx_ = -1, tx_ = -1;
  sockaddr_in to_{};
};

TEST_F(LcmFilterTest, PassesLcmMessagesAndDropsTheFragmentsLcmWouldMishandle) {
  ASSERT_TRUE(AttachLcmFragmentFilter(rx_).ok());
  // What vdeform and LCM send: short messages, fragments of messages up to the bound, other traffic.
  std::vector<uint8_t> short_msg(60, 0x11);
  PutU32(&short_msg, 0, 0x4c433032);
  short_msg.back() = 1;
  Send(short_msg);
  std::vector<uint8_t> junk(100, 0x22);
  junk.back() = 2;
  Send(junk);
  Send(Fragment(1 << 20, 0, 0, 3));                                 // first fragment of 1 MiB
  Send(Fragment(1 << 20, 60000, 1, 4));                             // a later one
  Send(Fragment(kLcmGuardMaxMessageBytes, kLcmGuardMaxMessageBytes - 1400, 5000, 5));  // the bound itself
  // What the guard must stop.
  Send(Fragment(kLcmGuardMaxMessageBytes + 1, 0, 0, 10));           // declares a message over 8 MiB
  Send(Fragment(200u << 20, 1400, 1, 11));                          // 200 MiB, a later fragment
  Send(Fragment(1 << 20, 0xfffff000u, 2, 12));                      // offset wrapping LCM's 32-bit check
  Send(Fragment(1 << 20, kLcmGuardMaxMessageBytes + 1, 2, 13));     // placed beyond the bound
  Send(Fragment(1 << 20, 100, 0, 14));                              // fragment 0 placed off 0
  Send(Fragment(1 << 20, 1400, 1, 15, 19));                         // shorter than its header
  EXPECT_EQ(Received(), (std::set<int>{1, 2, 3, 4, 5}));
}

TEST_F(LcmFilterTest, WithoutTheFilterEveryDatagramArrives) {
  // The same hostile fragments reach an unguarded socket: the test above is not passing because
  // loopback dropped them.
  Send(Fragment(kLcmGuardMaxMessageBytes + 1, 0, 0, 10));
  Send(Fragment(1 << 20, 0xfffff000u, 2, 12));
  Send(Fragment(1 << 20, 100, 0, 14));
  EXPECT_EQ(Received(), (std::set<int>{10, 12, 14}));
}

TEST_F(LcmFilterTest, TheBoundIsAParameter) {
  ASSERT_TRUE(AttachLcmFragmentFilter(rx_, 1 << 20).ok());
  Send(Fragment(1 << 20, 0, 0, 1));
  Send(Fragment((1 << 20) + 1, 0, 0, 2));
  EXPECT_EQ(Received(), (std::set<int>{1}));
}

TEST(LcmGuardTest, ProvidersWithoutSocketsNeedNoGuardAndBadUrlsAreRefused) {
  EXPECT_EQ(*GuardLcmReceiveSockets("memq://"), 0);
  EXPECT_EQ(*GuardLcmReceiveSockets("file:///tmp/x.log?mode=r"), 0);
  const auto bad = GuardLcmReceiveSockets("udpm://239.255.76.67:99999?ttl=0");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("port"), std::string::npos) << bad.status().message();
}

TEST(LcmGuardTest, FindsLcmsReceiveSocketOnceSubscribed) {
  const int port = 20000 + getpid() % 20000;
  const std::string url = "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0";
  lcm::LCM lcm(url);
  if (!lcm.good()) GTEST_SKIP() << "LCM cannot open " << url << " (no multicast route on this host)";
  // Before the first subscribe LCM has no receive socket: the guard says so instead of passing.
  const auto early = GuardLcmReceiveSockets(url);
  ASSERT_FALSE(early.ok());
  EXPECT_EQ(early.status().code(), StatusCode::kNotFound);
  struct Sink {
    void On(const lcm::ReceiveBuffer*, const std::string&) {}
  } sink;
  lcm.subscribe("VDEFORM_GUARD_TEST", &Sink::On, &sink);
  const auto guarded = GuardLcmReceiveSockets(url);
  ASSERT_TRUE(guarded.ok()) << guarded.status().message();
  EXPECT_EQ(*guarded, 1);
  setenv("VD_NO_LCM_GUARD", "1", 1);
  EXPECT_EQ(*GuardLcmReceiveSockets(url), 0);
  unsetenv("VD_NO_LCM_GUARD");
}

}  // namespace
}  // namespace vd
