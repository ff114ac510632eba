#include "shared/hal/clock.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <ctime>
#include <thread>

namespace idi::hal {

int64_t MonotonicClock::NowNs() const {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * kNsPerSec + ts.tv_nsec;
}

void MonotonicClock::SleepUntilNs(int64_t t_ns) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(t_ns / kNsPerSec);
  ts.tv_nsec = static_cast<long>(t_ns % kNsPerSec);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

namespace {
std::atomic<double> g_default_pace{0.0};
}  // namespace

void SimClock::SleepUntilNs(int64_t t_ns) {
  if (t_ns <= now_ns_) return;
  if (pace_ > 0) {
    // Capped at a day of wall time (the product of a pace and a huge interval overflowed the cast).
    const double wall_ns = std::min(pace_ * static_cast<double>(t_ns - now_ns_), 86400e9);
    std::this_thread::sleep_for(std::chrono::nanoseconds(static_cast<int64_t>(wall_ns)));
  }
  now_ns_ = t_ns;
}

void SimClock::SetDefaultPace(double wall_per_sim) { g_default_pace = wall_per_sim > 0 ? wall_per_sim : 0.0; }
double SimClock::DefaultPace() { return g_default_pace.load(); }

}  // namespace idi::hal
