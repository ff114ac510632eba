#include "shared/util/status.h"

#include <charconv>
#include <cstdio>
#include <cstdlib>

namespace idi {

namespace {

// The shortest decimal that reads back as `v` (std::to_chars picks the shorter of the fixed and the
// scientific form: "2000", "0.1", "1e-07"), when it has at most `max_digits` significant digits; else
// `v` to 6 significant digits.
template <typename T>
std::string Shortest(T v, int max_digits) {
  char buf[64];
  const std::to_chars_result r = std::to_chars(buf, buf + sizeof buf, v);
  int digits = 0;
  bool leading = true;
  for (const char* c = buf; c != r.ptr && *c != 'e'; ++c) {
    if (*c < '0' || *c > '9') continue;
    if (leading && *c == '0') continue;
    leading = false;
    ++digits;
  }
  if (digits <= max_digits) return std::string(buf, r.ptr);
  const std::to_chars_result g = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, 6);
  return std::string(buf, g.ptr);
}

}  // namespace

std::string FormatNumber(double v) { return Shortest(v, 12); }
std::string FormatNumber(float v) { return Shortest(v, 9); }

const char* StatusCodeName(StatusCode code) {
  switch (code) {
    case StatusCode::kOk: return "ok";
    case StatusCode::kInvalidArgument: return "invalid argument";
    case StatusCode::kNotFound: return "not found";
    case StatusCode::kParseError: return "parse error";
    case StatusCode::kIoError: return "i/o error";
    case StatusCode::kOutOfRange: return "out of range";
    case StatusCode::kFailedPrecondition: return "failed precondition";
    case StatusCode::kTimeout: return "timeout";
    case StatusCode::kDeviceError: return "device error";
    case StatusCode::kNotConverged: return "not converged";
    case StatusCode::kCancelled: return "cancelled";
    case StatusCode::kInternal: return "internal error";
  }
  return "unknown";
}

std::string Status::ToString() const {
  if (ok()) {
    return "ok";
  }
  return std::string(StatusCodeName(code_)) + ": " + message_;
}

Status Status::WithContext(const std::string& context) const {
  if (ok()) {
    return *this;
  }
  return {code_, context + ": " + message_};
}

namespace internal {
void CheckFailed(const char* file, int line, const char* condition, std::string_view message) {
  std::fprintf(stderr, "%s:%d: check failed: %s: %.*s\n", file, line, condition,
               static_cast<int>(message.size()), message.data());
  std::fflush(stderr);
  std::abort();
}
}  // namespace internal

}  // namespace idi
