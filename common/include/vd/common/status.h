#pragma once
// Status / StatusOr: run-time failures carry what failed and where; nothing is silently dropped.
#include <cassert>
#include <optional>
#include <string>
#include <utility>

namespace vd {

enum class StatusCode {
  kOk = 0,
  kInvalidArgument,
  kNotFound,
  kOutOfRange,
  kDataLoss,
  kUnavailable,
  kDeadlineExceeded,
  kFailedPrecondition,
  kInternal,
  kUnimplemented,
  kPermissionDenied,
};

const char* StatusCodeName(StatusCode code);

class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}
  static Status Ok() { return Status(); }

  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }
  // "CODE: message", for logs and error output.
  std::string ToString() const;
  // Prefixes context to the message ("while reading X: ...").
  Status WithContext(const std::string& context) const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

inline Status InvalidArgument(std::string m) { return Status(StatusCode::kInvalidArgument, std::move(m)); }
inline Status NotFound(std::string m) { return Status(StatusCode::kNotFound, std::move(m)); }
inline Status OutOfRange(std::string m) { return Status(StatusCode::kOutOfRange, std::move(m)); }
inline Status DataLoss(std::string m) { return Status(StatusCode::kDataLoss, std::move(m)); }
inline Status Unavailable(std::string m) { return Status(StatusCode::kUnavailable, std::move(m)); }
inline Status DeadlineExceeded(std::string m) { return Status(StatusCode::kDeadlineExceeded, std::move(m)); }
inline Status FailedPrecondition(std::string m) { return Status(StatusCode::kFailedPrecondition, std::move(m)); }
inline Status Internal(std::string m) { return Status(StatusCode::kInternal, std::move(m)); }
inline Status PermissionDenied(std::string m) { return Status(StatusCode::kPermissionDenied, std::move(m)); }
inline Status Unimplemented(std::string m) { return Status(StatusCode::kUnimplemented, std::move(m)); }

template <typename T>
class [[nodiscard]] StatusOr {
 public:
  // NOLINTNEXTLINE(google-explicit-constructor): returning a Status from a StatusOr function.
  StatusOr(Status status) : status_(std::move(status)) { assert(!status_.ok()); }
  // NOLINTNEXTLINE(google-explicit-constructor)
  StatusOr(T value) : value_(std::move(value)) {}

  bool ok() const { return status_.ok(); }
  const Status& status() const { return status_; }
  T& value() & { assert(ok()); return *value_; }
  const T& value() const& { assert(ok()); return *value_; }
  T&& value() && { assert(ok()); return std::move(*value_); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }

 private:
  Status status_;
  std::optional<T> value_;
};

}  // namespace vd

#define VD_CONCAT_INNER(a, b) a##b
#define VD_CONCAT(a, b) VD_CONCAT_INNER(a, b)

// Returns the Status from the enclosing function when expr is not ok.
#define VD_RETURN_IF_ERROR(expr)              \
  do {                                        \
    ::vd::Status vd_status_tmp_ = (expr);     \
    if (!vd_status_tmp_.ok()) return vd_status_tmp_; \
  } while (0)

#define VD_ASSIGN_OR_RETURN_IMPL(tmp, lhs, expr) \
  auto tmp = (expr);                             \
  if (!tmp.ok()) return tmp.status();            \
  lhs = std::move(tmp).value()

// VD_ASSIGN_OR_RETURN(auto x, Foo()); declares x from a StatusOr or returns its error.
#define VD_ASSIGN_OR_RETURN(lhs, expr) VD_ASSIGN_OR_RETURN_IMPL(VD_CONCAT(vd_so_, __LINE__), lhs, expr)
