#pragma once
// Names the calling thread (at most 15 characters on Linux), so `top -H`, `ps -L` and
// /proc/<pid>/task/*/comm tell the server's threads apart (tests/bench/live_30hz.sh prints the
// CPU each one used).
#include <pthread.h>

#include <string>

namespace vd {

inline void NameThisThread(const std::string& name) {
  pthread_setname_np(pthread_self(), name.substr(0, 15).c_str());
}

}  // namespace vd
