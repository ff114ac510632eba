#include "shared/hal/clock.h"

#include <gtest/gtest.h>

#include <chrono>

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

}  // namespace
}  // namespace idi::hal
