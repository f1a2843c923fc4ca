#include "vd/common/lcm_guard.h"

#include <arpa/inet.h>
#include <dirent.h>
#include <linux/filter.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <regex>
#include <vector>

#include "vd/common/log.h"

namespace vd {
namespace {

// LCM's long (fragment) header after the 8-byte UDP header, which is where a socket filter on a
// UDP socket starts reading: magic, sequence, message size, fragment offset (32 bits each, big
// endian), fragment number and count (16 bits each), then the channel name in fragment 0.
constexpr uint32_t kLcmMagicLong = 0x4c433033;  // "LC03"
constexpr uint32_t kAtMagic = 8;
constexpr uint32_t kAtMessageSize = 16;
constexpr uint32_t kAtFragmentOffset = 20;
// Fragment number (high half) and count (low half) as one word: the header's last 4 bytes.
constexpr uint32_t kAtFragmentNumberAndCount = 24;

std::vector<sock_filter> FragmentFilter(uint32_t max_message_bytes) {
  // Jump offsets count instructions after the jump; kAccept and kDrop are the last two.
  constexpr uint8_t kAccept = 11, kDrop = 12;
  auto to = [](uint8_t target, uint8_t from) { return static_cast<uint8_t>(target - from - 1); };
  return {
      /* 0*/ BPF_STMT(BPF_LD | BPF_W | BPF_ABS, kAtMagic),
      /* 1*/ BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, kLcmMagicLong, 0, to(kAccept, 1)),
      /* 2*/ BPF_STMT(BPF_LD | BPF_W | BPF_ABS, kAtMessageSize),
      /* 3*/ BPF_JUMP(BPF_JMP | BPF_JGT | BPF_K, max_message_bytes, to(kDrop, 3), 0),
      // A load past the datagram's end ends the program with 0 (drop): this one requires the
      // whole fragment header.
      /* 4*/ BPF_STMT(BPF_LD | BPF_W | BPF_ABS, kAtFragmentNumberAndCount),
      /* 5*/ BPF_STMT(BPF_MISC | BPF_TAX, 0),
      /* 6*/ BPF_STMT(BPF_LD | BPF_W | BPF_ABS, kAtFragmentOffset),
      // Unsigned: an offset near 2^32 (the one that wraps LCM's check) is beyond the bound.
      /* 7*/ BPF_JUMP(BPF_JMP | BPF_JGT | BPF_K, max_message_bytes, to(kDrop, 7), 0),
      /* 8*/ BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, 0, to(kAccept, 8), 0),
      // Fragment 0 placed off 0: LCM subtracts the channel name's strlen from its size, which can
      // wrap when the name runs past the datagram; with offset 0 the wrapped sum is refused.
      // (number << 16 | count) below 2^16 is fragment number 0.
      /* 9*/ BPF_STMT(BPF_MISC | BPF_TXA, 0),
      /*10*/ BPF_JUMP(BPF_JMP | BPF_JGE | BPF_K, 0x10000, to(kAccept, 10), to(kDrop, 10)),
      /*11*/ BPF_STMT(BPF_RET | BPF_K, 0xffffffffu),
      /*12*/ BPF_STMT(BPF_RET | BPF_K, 0),
  };
}

// The port of a udpm:// URL; nullopt-like 0 for other providers.
StatusOr<int> UdpmPort(const std::string& url) {
  static const std::regex kUdpm(R"(^udpm://[^:/?]*:(\d{1,5})([?].*)?$)");
  std::smatch m;
  if (url.rfind("udpm://", 0) != 0) return 0;
  // LCM's own default when the URL names no port.
  if (!std::regex_match(url, m, kUdpm)) return url.find(':', 7) == std::string::npos ? 7667 : -1;
  const int port = std::atoi(m[1].str().c_str());
  return port > 0 && port < 65536 ? port : -1;
}

}  // namespace

Status AttachLcmFragmentFilter(int fd, uint32_t max_message_bytes) {
  std::vector<sock_filter> code = FragmentFilter(max_message_bytes);
  sock_fprog prog{static_cast<unsigned short>(code.size()), code.data()};
  if (setsockopt(fd, SOL_SOCKET, SO_ATTACH_FILTER, &prog, sizeof prog) != 0)
    return Internal("cannot attach the LCM fragment filter to socket " + std::to_string(fd) + ": " +
                    std::strerror(errno));
  return Status::Ok();
}

StatusOr<int> GuardLcmReceiveSockets(const std::string& url) {
  const char* off = std::getenv("VD_NO_LCM_GUARD");
  if (off != nullptr && std::strcmp(off, "1") == 0) return 0;
  VD_ASSIGN_OR_RETURN(const int port, UdpmPort(url));
  if (port == 0) return 0;
  if (port < 0) return InvalidArgument("cannot read the port of LCM URL '" + url + "'");
  DIR* dir = opendir("/proc/self/fd");
  if (dir == nullptr) return Internal(std::string("cannot list /proc/self/fd: ") + std::strerror(errno));
  std::vector<int> sockets;
  while (const dirent* e = readdir(dir)) {
    char* end = nullptr;
    const long fd = std::strtol(e->d_name, &end, 10);
    if (end == e->d_name || *end != '\0') continue;
    int type = 0;
    socklen_t len = sizeof type;
    if (getsockopt(static_cast<int>(fd), SOL_SOCKET, SO_TYPE, &type, &len) != 0 || type != SOCK_DGRAM) continue;
    sockaddr_in addr{};
    len = sizeof addr;
    if (getsockname(static_cast<int>(fd), reinterpret_cast<sockaddr*>(&addr), &len) != 0) continue;
    if (addr.sin_family == AF_INET && ntohs(addr.sin_port) == port) sockets.push_back(static_cast<int>(fd));
  }
  closedir(dir);
  if (sockets.empty())
    return NotFound("no UDP socket bound to port " + std::to_string(port) + " of '" + url +
                    "' (subscribe before guarding: LCM opens its receive socket then)");
  for (int fd : sockets) VD_RETURN_IF_ERROR(AttachLcmFragmentFilter(fd));
  return static_cast<int>(sockets.size());
}

void GuardLcmOrWarn(const std::string& url, const char* program) {
  const StatusOr<int> guarded = GuardLcmReceiveSockets(url);
  if (!guarded.ok()) {
    VD_LOG_WARNING << program << ": LCM fragments are not guarded (" << guarded.status().message()
                   << "); load deploy/lcm-guard.nft on this host";
  } else if (*guarded > 0) {
    VD_LOG_DEBUG << program << ": LCM fragments of messages over " << (kLcmGuardMaxMessageBytes >> 20)
                 << " MiB are dropped in the kernel";
  }
}

}  // namespace vd
