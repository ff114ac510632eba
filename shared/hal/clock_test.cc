#include "shared/hal/clock.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdint>

namespace idi::hal {
namespace {

// Unpaced simulated time jumps on a sleep; a pace makes the sleep also wait at least pace x dt on the
// wall clock (a lower bound, which sleep_for guarantees), and new clocks take the process default.
TEST(SimClockTest, SleepAdvancesAndPaceWaitsOnTheWallClock) {
  SimClock fast(5);
  EXPECT_EQ(fast.pace(), 0.0);
  fast.SleepForNs(2 * kNsPerSec);
  EXPECT_EQ(fast.NowNs(), 5 + 2 * kNsPerSec);
  fast.SleepUntilNs(1);  // in the past: no change
  EXPECT_EQ(fast.NowNs(), 5 + 2 * kNsPerSec);

  SimClock::SetDefaultPace(0.02);
  SimClock paced;
  SimClock::SetDefaultPace(0);
  EXPECT_DOUBLE_EQ(paced.pace(), 0.02);
  EXPECT_EQ(SimClock().pace(), 0.0) << "the default was reset";
  const auto t0 = std::chrono::steady_clock::now();
  paced.SleepForNs(3 * kNsPerSec);  // 60 ms of wall time at least
  const auto waited = std::chrono::steady_clock::now() - t0;
  EXPECT_EQ(paced.NowNs(), 3 * kNsPerSec);
  EXPECT_GE(waited, std::chrono::milliseconds(60));
  paced.set_pace(-1);
  EXPECT_EQ(paced.pace(), 0.0) << "a negative pace means unpaced";
}

// Seconds that do not fit in int64 ns saturate and NaN is 0 (the casts were undefined; on x86 a NaN
// sleep became INT64_MIN, no wait); a sleep for INT64_MAX ns ends at the end of time, not in the past.
TEST(SimClockTest, ConversionsAndSleepsSaturate) {
  EXPECT_EQ(SecToNs(1.5), 1'500'000'000);
  EXPECT_EQ(SecToNs(-0.25), -250'000'000);
  EXPECT_EQ(SecToNs(std::nan("")), 0);
  EXPECT_EQ(SecToNs(INFINITY), INT64_MAX);
  EXPECT_EQ(SecToNs(1e12), INT64_MAX);
  EXPECT_EQ(SecToNs(-1e12), INT64_MIN);
  SimClock clock(5 * kNsPerSec);
  clock.set_pace(0.0);
  clock.SleepForNs(INT64_MAX);
  EXPECT_EQ(clock.NowNs(), INT64_MAX);
}

}  // namespace
}  // namespace idi::hal
