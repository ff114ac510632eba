#include "workcell/devices/ptu/ptu_sim.h"

#include <gtest/gtest.h>

#include <cmath>

#include "workcell/devices/ptu/ptu_codec.h"

namespace idi::workcell {
namespace {

using std::chrono::milliseconds;

TEST(SimPanTiltTest, QuantisesToThePositionResolution) {
  hal::SimClock clock;
  SimPanTilt ptu({}, &clock);
  const double res = PtuArcSecondsToRad(185.1428);
  ASSERT_TRUE(ptu.MoveTo(0.12345, -0.05432, milliseconds(10'000)).ok());
  EXPECT_EQ(ptu.pan_position(), std::lround(0.12345 / res));
  const auto state = ptu.Read();
  ASSERT_TRUE(state.ok());
  EXPECT_NE(state->pan_rad, 0.12345);  // quantised, not the commanded value
  EXPECT_NEAR(state->pan_rad, 0.12345, res / 2);
  EXPECT_NEAR(state->tilt_rad, -0.05432, res / 2);
  EXPECT_NEAR(std::remainder(state->pan_rad, res), 0.0, 1e-12);
}

TEST(SimPanTiltTest, MovesTakeSimulatedTimeAtTheUnitsSpeed) {
  hal::SimClock clock;
  SimPtuOptions options;
  options.speed_pos_per_s = 1000;
  SimPanTilt ptu(options, &clock);
  const double res = PtuArcSecondsToRad(options.pan_arcsec);
  ASSERT_TRUE(ptu.MoveTo(2000 * res, 500 * res, milliseconds(10'000)).ok());
  EXPECT_EQ(clock.NowNs(), hal::SecToNs(2.0));  // the longer axis: 2000 positions at 1000 pos/s
}

TEST(SimPanTiltTest, EnforcesLimitsAndTimeouts) {
  hal::SimClock clock;
  SimPanTilt ptu({}, &clock);
  const auto limits = ptu.Limits();
  ASSERT_TRUE(limits.ok());
  EXPECT_TRUE(limits->Contains(0, 0));
  EXPECT_EQ(ptu.MoveTo(limits->pan_max_rad + 0.01, 0, milliseconds(1000)).code(), StatusCode::kOutOfRange);
  EXPECT_EQ(ptu.MoveTo(0, limits->tilt_min_rad - 0.01, milliseconds(1000)).code(), StatusCode::kOutOfRange);
  EXPECT_EQ(ptu.pan_position(), 0);
  const Status slow = ptu.MoveTo(limits->pan_max_rad, 0, milliseconds(100));
  EXPECT_EQ(slow.code(), StatusCode::kTimeout);
  EXPECT_GT(ptu.pan_position(), 0);
  EXPECT_LT(ptu.pan_position(), 3090);
  EXPECT_EQ(ptu.halts(), 1);
}

TEST(SimPanTiltTest, InjectedFaultFailsTheMoveAndHalts) {
  hal::SimClock clock;
  SimPanTilt ptu({}, &clock);
  ptu.InjectFault(DeviceError("sim-ptu: injected"));
  const Status s = ptu.MoveTo(0.5, 0, milliseconds(10'000));
  EXPECT_EQ(s.code(), StatusCode::kDeviceError);
  EXPECT_EQ(ptu.halts(), 1);
  EXPECT_TRUE(ptu.MoveTo(0.5, 0, milliseconds(10'000)).ok());
}

}  // namespace
}  // namespace idi::workcell
