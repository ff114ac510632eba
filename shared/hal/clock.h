// Time for devices and control loops. Real backends use the monotonic clock; the simulation drives
// a SimClock so runs are deterministic and faster than real time. Timestamps are nanoseconds on the
// clock's own time line (sample time, not arrival time).
#pragma once

#include <cstdint>

namespace idi::hal {

class Clock {
 public:
  virtual ~Clock() = default;
  virtual int64_t NowNs() const = 0;
  // Blocks (real) or advances simulated time (sim) until `t_ns`; returns immediately if past.
  virtual void SleepUntilNs(int64_t t_ns) = 0;
  // Saturating: a huge dt is "until the end of time", not an overflow into the past.
  void SleepForNs(int64_t dt_ns) {
    const int64_t now = NowNs();
    SleepUntilNs(dt_ns > 0 && now > INT64_MAX - dt_ns ? INT64_MAX : now + dt_ns);
  }
};

// CLOCK_MONOTONIC.
class MonotonicClock final : public Clock {
 public:
  int64_t NowNs() const override;
  void SleepUntilNs(int64_t t_ns) override;
};

// Simulated time: starts at `start_ns`, moves only when advanced (or slept on). With a pace p > 0, a
// sleep of dt simulated also waits p * dt on the wall clock (p = 1: the twin in real time, for an
// operator watching it or a test that must catch it mid-move); 0, the default, never waits. New clocks
// take the process-wide default pace (the service's `sim.pace`).
class SimClock final : public Clock {
 public:
  explicit SimClock(int64_t start_ns = 0) : now_ns_(start_ns), pace_(DefaultPace()) {}
  int64_t NowNs() const override { return now_ns_; }
  void SleepUntilNs(int64_t t_ns) override;
  void AdvanceNs(int64_t dt_ns) { now_ns_ += dt_ns; }
  double pace() const { return pace_; }
  void set_pace(double wall_per_sim) { pace_ = wall_per_sim > 0 ? wall_per_sim : 0.0; }
  static void SetDefaultPace(double wall_per_sim);
  static double DefaultPace();

 private:
  int64_t now_ns_;
  double pace_;
};

inline constexpr int64_t kNsPerMs = 1'000'000;
inline constexpr int64_t kNsPerSec = 1'000'000'000;
inline double NsToSec(int64_t ns) { return static_cast<double>(ns) * 1e-9; }
// Saturates at the int64 range, and NaN is 0 (the cast of either was undefined behaviour; on x86 it gave
// INT64_MIN, so a NaN sleep became no wait).
inline int64_t SecToNs(double s) {
  const double ns = s * 1e9;
  if (!(ns == ns)) return 0;
  if (ns >= 9.2e18) return INT64_MAX;
  if (ns <= -9.2e18) return INT64_MIN;
  return static_cast<int64_t>(ns);
}

}  // namespace idi::hal
