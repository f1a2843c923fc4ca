#pragma once
// Minimal leveled logging to stderr, thread-safe, with a process-wide level.
#include <sstream>
#include <string>

namespace vd {

enum class LogLevel { kDebug = 0, kInfo = 1, kWarning = 2, kError = 3, kQuiet = 4 };

void SetLogLevel(LogLevel level);
LogLevel GetLogLevel();
void LogMessage(LogLevel level, const char* file, int line, const std::string& text);

namespace internal {
class LogLine {
 public:
  LogLine(LogLevel level, const char* file, int line) : level_(level), file_(file), line_(line) {}
  ~LogLine() { LogMessage(level_, file_, line_, stream_.str()); }
  std::ostringstream& stream() { return stream_; }

 private:
  LogLevel level_;
  const char* file_;
  int line_;
  std::ostringstream stream_;
};
// Swallows the stream so VD_LOG is one expression (safe inside if/else without braces).
struct Voidify {
  void operator&(std::ostream&) {}
};
}  // namespace internal

}  // namespace vd

#define VD_LOG(level)                                                  \
  (::vd::LogLevel::level < ::vd::GetLogLevel())                        \
      ? (void)0                                                        \
      : ::vd::internal::Voidify() &                                    \
            ::vd::internal::LogLine(::vd::LogLevel::level, __FILE__, __LINE__).stream()
#define VD_LOG_DEBUG VD_LOG(kDebug)
#define VD_LOG_INFO VD_LOG(kInfo)
#define VD_LOG_WARNING VD_LOG(kWarning)
#define VD_LOG_ERROR VD_LOG(kError)
