#include "workcell/devices/barrett/barrett_sim.h"

#include <gtest/gtest.h>

#include <cmath>

namespace idi::workcell {
namespace {

TEST(SimGripperTest, NeedsInitialisationThenOpensClosesAndSpreads) {
  hal::SimClock clock;
  SimGripper hand({}, &clock);
  EXPECT_EQ(hand.Close().code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE(hand.Initialize().ok());
  EXPECT_EQ(clock.NowNs(), hal::SecToNs(3.0));
  ASSERT_TRUE(hand.Close().ok());
  const double closed = 140.0 * M_PI / 180.0;
  EXPECT_NEAR(hal::NsToSec(clock.NowNs()), 3.0 + closed / 2.0, 1e-6);
  ASSERT_TRUE(hand.SetSpread(1.0).ok());
  const auto state = hand.Read();
  ASSERT_TRUE(state.ok());
  EXPECT_TRUE(state->initialized);
  EXPECT_NEAR(state->finger_rad[2], closed, 1e-4);
  // Quantised to encoder counts: close to, but not exactly, the command.
  EXPECT_NE(state->spread_rad, 1.0);
  EXPECT_NEAR(state->spread_rad, 1.0, 0.5 * M_PI / 3150);
  EXPECT_EQ(hand.SetSpread(4.0).code(), StatusCode::kOutOfRange);
}

TEST(SimGripperTest, ClosingFingersStallOnTheObject) {
  hal::SimClock clock;
  SimGripper hand({}, &clock);
  ASSERT_TRUE(hand.Initialize().ok());
  hand.SetObject({0.8, 0.9, std::nullopt});
  ASSERT_TRUE(hand.Close().ok());
  const auto state = hand.Read();
  ASSERT_TRUE(state.ok());
  EXPECT_NEAR(state->finger_rad[0], 0.8, 1e-3);
  EXPECT_NEAR(state->finger_rad[1], 0.9, 1e-3);
  EXPECT_NEAR(state->finger_rad[2], 140.0 * M_PI / 180.0, 1e-3);
}

TEST(SimGripperTest, InjectedFaultStopsHalfWay) {
  hal::SimClock clock;
  SimGripper hand({}, &clock);
  ASSERT_TRUE(hand.Initialize().ok());
  hand.InjectFault(DeviceError("sim-barrett: injected"));
  EXPECT_EQ(hand.Close().code(), StatusCode::kDeviceError);
  EXPECT_EQ(hand.stops(), 1);
  const auto state = hand.Read();
  ASSERT_TRUE(state.ok());
  EXPECT_GT(state->finger_rad[0], 0.1);
  EXPECT_LT(state->finger_rad[0], 2.0);
}

}  // namespace
}  // namespace idi::workcell
