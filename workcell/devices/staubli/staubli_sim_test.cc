#include "workcell/devices/staubli/staubli_sim.h"

#include <gtest/gtest.h>

#include "shared/util/units.h"
#include "workcell/devices/staubli/staubli_joints.h"

namespace idi::workcell {
namespace {

TEST(SimStaubliTest, ReadingsAreQuantisedToTheEncodersAndMovesTakeTime) {
  hal::SimClock clock;
  SimStaubli arm({}, &clock);
  const Joints q = {0.1234567, -0.5, 0.7, 0.2, -0.3, 1.0};
  hal::MoveOptions options;
  options.speed_fraction = 0.5;
  ASSERT_TRUE(arm.MoveJoints(q, options).ok());
  // Largest change: joint 6, 1 rad = 57.3 deg at 90 deg/s.
  EXPECT_NEAR(hal::NsToSec(clock.NowNs()), RadToDeg(1.0) / 90.0, 1e-6);
  const auto state = arm.ReadJoints();
  ASSERT_TRUE(state.ok());
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_NEAR(state->q_rad[i], q[i], DegToRad(0.5 / kRx130CountsPerDeg[i]) + 1e-15) << i;
  }
  EXPECT_NE(state->q_rad[0], q[0]);
}

TEST(SimStaubliTest, LimitsRailAndFaults) {
  hal::SimClock clock;
  SimStaubli arm({}, &clock);
  Joints too_far{};
  too_far[1] = DegToRad(60.0);  // model J2 max is 137.5 - 90 = 47.5 deg
  EXPECT_EQ(arm.MoveJoints(too_far, {}).code(), StatusCode::kOutOfRange);
  ASSERT_TRUE(arm.MoveTo(1000.004, {}).ok());
  EXPECT_NEAR(arm.Read()->position_mm, 1000.0, 1e-9);
  EXPECT_EQ(arm.MoveTo(7000, {}).code(), StatusCode::kOutOfRange);
  arm.InjectFault(DeviceError("sim-arm: injected"));
  EXPECT_EQ(arm.MoveTo(2000, {}).code(), StatusCode::kDeviceError);
  EXPECT_NEAR(arm.Read()->position_mm, 1500.0, 1e-9);
  EXPECT_EQ(arm.stops(), 1);
}

}  // namespace
}  // namespace idi::workcell
