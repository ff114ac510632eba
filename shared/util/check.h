// Invariant checks: a violated invariant is a bug, so it aborts loudly with file and line.
// Bad input is never checked with these; it comes back as a Status (see status.h).
#pragma once

#include <string_view>

namespace idi::internal {
[[noreturn]] void CheckFailed(const char* file, int line, const char* condition, std::string_view message);
}  // namespace idi::internal

#define IDI_CHECK(condition, message)                                         \
  do {                                                                        \
    if (!(condition)) [[unlikely]] {                                          \
      ::idi::internal::CheckFailed(__FILE__, __LINE__, #condition, message);  \
    }                                                                         \
  } while (false)

#ifdef NDEBUG
#define IDI_DCHECK(condition, message) \
  do {                                 \
  } while (false && (condition))
#else
#define IDI_DCHECK(condition, message) IDI_CHECK(condition, message)
#endif
