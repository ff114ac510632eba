#include "shared/runtime/stop_signals.h"

#include <cstddef>

namespace idi {
namespace {

std::atomic<bool> g_stop_requested{false};
std::atomic<int> g_stop_signal{0};
static_assert(std::atomic<bool>::is_always_lock_free && std::atomic<int>::is_always_lock_free,
              "set from a signal handler");

extern "C" void IdiOnStopSignal(int sig) {
  g_stop_signal.store(sig);
  g_stop_requested.store(true);
}

}  // namespace

StopSignals::StopSignals() {
  g_stop_requested.store(false);
  g_stop_signal.store(0);
  struct sigaction sa {};
  sa.sa_handler = IdiOnStopSignal;
  sigemptyset(&sa.sa_mask);
  for (std::size_t i = 0; i < kSignals.size(); ++i) {
    if (sigaction(kSignals[i], nullptr, &previous_[i]) != 0 || previous_[i].sa_handler == SIG_IGN) {
      continue;
    }
    installed_[i] = sigaction(kSignals[i], &sa, nullptr) == 0;
  }
}

StopSignals::~StopSignals() {
  for (std::size_t i = 0; i < kSignals.size(); ++i) {
    if (installed_[i]) sigaction(kSignals[i], &previous_[i], nullptr);
  }
}

std::atomic<bool>* StopSignals::flag() const { return &g_stop_requested; }

int StopSignals::signal() const { return g_stop_signal.load(); }

std::string StopSignals::Name(int sig) {
  switch (sig) {
    case SIGINT:
      return "SIGINT";
    case SIGTERM:
      return "SIGTERM";
    case SIGHUP:
      return "SIGHUP";
    default:
      return "signal " + std::to_string(sig);
  }
}

bool StopSignals::catches(int sig) const {
  for (std::size_t i = 0; i < kSignals.size(); ++i) {
    if (kSignals[i] == sig) return installed_[i];
  }
  return false;
}

}  // namespace idi
