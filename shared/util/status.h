// Status and Result<T>: expected failures come back as values; no exceptions cross shared/.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <variant>

#include "shared/util/check.h"

namespace idi {

enum class StatusCode {
  kOk = 0,
  kInvalidArgument,     // bad input or configuration (exit code 2 in the binaries)
  kNotFound,            // a file, device or key that is not there
  kParseError,          // malformed file contents
  kIoError,             // read/write failed
  kOutOfRange,          // a value outside its allowed range (joint limits, PTU limits, ...)
  kFailedPrecondition,  // the system is not in a state where this can be done
  kTimeout,             // a device did not answer in time
  kDeviceError,         // a device answered with an error or garbage
  kNotConverged,        // an optimisation or iteration did not reach its tolerance
  kCancelled,           // stopped by a signal or an operator
  kInternal,
};

const char* StatusCodeName(StatusCode code);

// A number as messages should show it: the shortest decimal that reads back as the same value (the
// shorter of the fixed and the scientific form, as std::to_chars picks it: "0.1", "2000", "1e-07",
// "1.0000001", "1e+308", "inf", "nan"), which shows a value as it was given; a value that needs more than
// 12 significant digits (9 for a float), such as a computed residual, to 6 ("0.123457"). std::to_string
// printed six fixed decimals: a refused 1e-7 read "got 0.000000", and 1e308 took 316 characters.
std::string FormatNumber(double v);
std::string FormatNumber(float v);

class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status Ok() { return {}; }

  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }
  // "kInvalidArgument: <message>".
  std::string ToString() const;

  // Prefixes the message with context ("robot.yaml: " + message), keeping the code.
  Status WithContext(const std::string& context) const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

inline Status InvalidArgument(std::string m) { return {StatusCode::kInvalidArgument, std::move(m)}; }
inline Status NotFound(std::string m) { return {StatusCode::kNotFound, std::move(m)}; }
inline Status ParseError(std::string m) { return {StatusCode::kParseError, std::move(m)}; }
inline Status IoError(std::string m) { return {StatusCode::kIoError, std::move(m)}; }
inline Status OutOfRange(std::string m) { return {StatusCode::kOutOfRange, std::move(m)}; }
inline Status FailedPrecondition(std::string m) { return {StatusCode::kFailedPrecondition, std::move(m)}; }
inline Status Timeout(std::string m) { return {StatusCode::kTimeout, std::move(m)}; }
inline Status DeviceError(std::string m) { return {StatusCode::kDeviceError, std::move(m)}; }
inline Status NotConverged(std::string m) { return {StatusCode::kNotConverged, std::move(m)}; }
inline Status Cancelled(std::string m) { return {StatusCode::kCancelled, std::move(m)}; }
inline Status Internal(std::string m) { return {StatusCode::kInternal, std::move(m)}; }

// Either a value or a non-OK Status.
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : data_(std::move(value)) {}  // NOLINT(google-explicit-constructor)
  Result(Status status) : data_(std::move(status)) {  // NOLINT(google-explicit-constructor)
    IDI_CHECK(!std::get<Status>(data_).ok(), "Result constructed from an OK status without a value");
  }

  bool ok() const { return std::holds_alternative<T>(data_); }
  const Status& status() const {
    static const Status kOkStatus;
    return ok() ? kOkStatus : std::get<Status>(data_);
  }
  const T& value() const& {
    IDI_CHECK(ok(), "Result::value() on an error: " + std::get<Status>(data_).ToString());
    return std::get<T>(data_);
  }
  T& value() & {
    IDI_CHECK(ok(), "Result::value() on an error: " + std::get<Status>(data_).ToString());
    return std::get<T>(data_);
  }
  T&& value() && {
    IDI_CHECK(ok(), "Result::value() on an error: " + std::get<Status>(data_).ToString());
    return std::get<T>(std::move(data_));
  }
  const T* operator->() const { return &value(); }
  T* operator->() { return &value(); }
  const T& operator*() const& { return value(); }
  T& operator*() & { return value(); }

 private:
  std::variant<T, Status> data_;
};

}  // namespace idi

// Returns early from a function returning Status or Result<T> when `expr` is not OK.
#define IDI_RETURN_IF_ERROR(expr)            \
  do {                                       \
    ::idi::Status idi_status_tmp_ = (expr);  \
    if (!idi_status_tmp_.ok()) {             \
      return idi_status_tmp_;                \
    }                                        \
  } while (false)

#define IDI_CONCAT_INNER_(a, b) a##b
#define IDI_CONCAT_(a, b) IDI_CONCAT_INNER_(a, b)
// IDI_ASSIGN_OR_RETURN(auto x, MakeX()): assigns the value or returns the error.
#define IDI_ASSIGN_OR_RETURN(lhs, expr) IDI_ASSIGN_OR_RETURN_IMPL_(IDI_CONCAT_(idi_result_, __LINE__), lhs, expr)
#define IDI_ASSIGN_OR_RETURN_IMPL_(tmp, lhs, expr) \
  auto tmp = (expr);                               \
  if (!tmp.ok()) {                                 \
    return tmp.status();                           \
  }                                                \
  lhs = std::move(tmp).value()
