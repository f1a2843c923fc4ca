#include "vd/common/log.h"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <cstring>
#include <mutex>

namespace vd {
namespace {

LogLevel InitialLevel() {
  const char* env = std::getenv("VD_LOG_LEVEL");
  if (!env) return LogLevel::kInfo;
  if (!std::strcmp(env, "debug")) return LogLevel::kDebug;
  if (!std::strcmp(env, "warning")) return LogLevel::kWarning;
  if (!std::strcmp(env, "error")) return LogLevel::kError;
  if (!std::strcmp(env, "quiet")) return LogLevel::kQuiet;
  return LogLevel::kInfo;
}

std::atomic<int>& Level() {
  static std::atomic<int> level{static_cast<int>(InitialLevel())};
  return level;
}

std::mutex& Mutex() {
  static std::mutex m;
  return m;
}

}  // namespace

void SetLogLevel(LogLevel level) { Level() = static_cast<int>(level); }
LogLevel GetLogLevel() { return static_cast<LogLevel>(Level().load()); }

void LogMessage(LogLevel level, const char* file, int line, const std::string& text) {
  static const char kTags[] = {'D', 'I', 'W', 'E', 'Q'};
  const char* base = std::strrchr(file, '/');
  base = base ? base + 1 : file;
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  const double secs = std::chrono::duration<double>(now).count();
  std::lock_guard<std::mutex> lock(Mutex());
  // "\r\033[K" would fight with progress lines; a plain newline-terminated record is enough.
  std::fprintf(stderr, "%c %.3f %s:%d] %s\n", kTags[static_cast<int>(level)],
               std::fmod(secs, 100000.0), base, line, text.c_str());
}

}  // namespace vd
