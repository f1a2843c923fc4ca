#pragma once
// An in-process guard in front of LCM 1.3.1's fragment reassembly (Debian 12's liblcm1), so that
// every vdeform program is protected without root or nftables (docs/OPERATIONS.md, "What LCM does
// with what it receives"). LCM allocates whatever size a message's first fragment declares (up to
// 256 MiB, held until that sender's next message) and checks a fragment's place with a 32-bit sum
// that wraps: one datagram with an offset near 2^32 makes it copy 4 GB past its buffer. The guard
// is a classic BPF socket filter on LCM's receive socket, so the kernel drops such datagrams
// before LCM's thread reads them. It does what deploy/lcm-guard.nft does, plus one rule nft lacks.
#include <cstdint>
#include <string>

#include "vd/common/messages.h"
#include "vd/common/status.h"

namespace vd {

// Largest message a guarded socket lets LCM reassemble: above every vdeform message
// (kMaxPayloadBytes plus headers), and the same 8 MiB as deploy/lcm-guard.nft.
inline constexpr uint32_t kLcmGuardMaxMessageBytes = 8u << 20;
static_assert(kLcmGuardMaxMessageBytes > kMaxPayloadBytes + (64 << 10), "the guard must pass every vdeform message");

// Attaches the filter to one UDP socket. It drops LCM fragments (magic "LC03") that declare a
// message over max_message_bytes, are placed beyond it, or are a first fragment (number 0, the
// one carrying the channel name) placed anywhere but offset 0, and datagrams too short to hold
// the header they claim. Everything else (short "LC02" messages, other traffic) passes.
Status AttachLcmFragmentFilter(int fd, uint32_t max_message_bytes = kLcmGuardMaxMessageBytes);

// Finds this process's LCM receive sockets for a udpm:// URL (UDP sockets bound to its port) and
// attaches the filter to each. LCM 1.3.1 creates the receive socket at the first subscribe, so
// call this after subscribing. Returns the number of sockets guarded: 0 for providers without a
// UDP socket (memq://, file://); for udpm:// an error when none is found. Datagrams already
// queued, or read between the subscribe and this call, are not filtered.
// $VD_NO_LCM_GUARD=1 skips it (returns 0): only to show what an unguarded LCM does (lcm_guard).
StatusOr<int> GuardLcmReceiveSockets(const std::string& url);

// For the programs: guards, and logs what it did (a warning when it could not).
void GuardLcmOrWarn(const std::string& url, const char* program);

}  // namespace vd
