// SIGINT, SIGTERM and SIGHUP as a request to stop safely: a handler sets a flag that the command's loop
// polls (the loop then brings its devices to a stop, writes what it has and returns), instead of the
// default action, which ends the process wherever it is.
#pragma once

#include <array>
#include <atomic>
#include <csignal>
#include <string>

namespace idi {

// While an object lives, SIGINT, SIGTERM and SIGHUP set the stop flag, except a signal that was ignored
// when it was made: `nohup` ignores SIGHUP and a shell ignores SIGINT for a job it starts in the
// background, and whoever started us that way asked not to be stopped by them. The dispositions before
// are restored when it is destroyed (a command may run inside a longer-lived process, a test's). One at
// a time: the flag is the process's.
class StopSignals {
 public:
  StopSignals();  // clears the flag
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

  // The flag the handler sets, for a loop's `stop` pointer.
  std::atomic<bool>* flag() const;
  bool requested() const { return flag()->load(); }
  // The last signal caught (0: none yet).
  int signal() const;
  // Whether `sig` (one of the three) is caught: false for one that was ignored.
  bool catches(int sig) const;
  // "SIGINT", "SIGTERM" or "SIGHUP" (else "signal N"), for messages.
  static std::string Name(int sig);

 private:
  static constexpr std::array<int, 3> kSignals = {SIGINT, SIGTERM, SIGHUP};
  std::array<struct sigaction, 3> previous_{};
  std::array<bool, 3> installed_{};
};

}  // namespace idi
