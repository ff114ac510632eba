#include "shared/sim/workcell/workcell_twin.h"

#include <gtest/gtest.h>

#include "shared/geometry/lines.h"

namespace idi::sim {
namespace {

TEST(WorkcellTwinTest, TruthDiffersFromNominalAndIsSeeded) {
  WorkcellTwin a({}), b({});
  WorkcellTwinOptions other;
  other.seed = 2;
  WorkcellTwin c(other);
  const ParamSet nominal = Rx130Nominal();
  double max_dev_deg = 0;
  for (std::size_t i = 0; i < nominal.size(); ++i) {
    EXPECT_EQ(a.true_robot(0).value(i), b.true_robot(0).value(i));
    if (nominal.spec(i).unit == Unit::kDegree) {
      max_dev_deg = std::max(max_dev_deg, std::abs(a.true_robot(0).file_value(i) - nominal.file_value(i)));
    }
  }
  EXPECT_GT(max_dev_deg, 0.005);
  EXPECT_LT(max_dev_deg, 1.0);
  EXPECT_NE(a.true_robot(0).value(kA3), c.true_robot(0).value(kA3));
  EXPECT_NE(a.true_robot(0).value(kA3), a.true_robot(1).value(kA3));
  EXPECT_NEAR(a.true_psi()[0], 5650.0, 30.0);
}

TEST(WorkcellTwinTest, JointsAreRealisedAtEncoderCountsAndLimitsHold) {
  WorkcellTwin twin({});
  const Joints q = JointsFromDeg({10.123456789, -40.5, 80.25, 3.3, 45.000001, -20});
  ASSERT_TRUE(twin.arm(0).MoveJoints(q, {}).ok());
  const auto r = twin.arm(0).ReadJoints();
  ASSERT_TRUE(r.ok());
  for (std::size_t i = 0; i < 6; ++i) {
    const double counts = RadToDeg(r->q_rad[i]) * kRx130CountsPerDeg[i];
    EXPECT_NEAR(counts, std::round(counts), 1e-6);
    EXPECT_LE(std::abs(r->q_rad[i] - q[i]), 0.5 * DegToRad(1.0 / kRx130CountsPerDeg[i]) + 1e-15);
  }
  EXPECT_EQ(twin.arm(0).MoveJoints(JointsFromDeg({200, 0, 0, 0, 0, 0}), {}).code(), StatusCode::kOutOfRange);
  EXPECT_EQ(twin.rail(0).MoveTo(-5.0, {}).code(), StatusCode::kOutOfRange);
}

TEST(WorkcellTwinTest, RailLandsWithinItsRepeatabilityAndReadsTheCommand) {
  WorkcellTwin twin({});
  double sum2 = 0;
  for (int i = 0; i < 200; ++i) {
    ASSERT_TRUE(twin.rail(0).MoveTo(1000.0, {}).ok());
    EXPECT_EQ(twin.rail(0).Read()->position_mm, 1000.0);
    sum2 += std::pow(twin.true_rail_position(0) - 1000.0, 2);
  }
  EXPECT_NEAR(std::sqrt(sum2 / 200), 0.1, 0.03);
}

// The rail refuses a speed fraction outside (0, 1], as the arm and the real controller do (a NaN was a
// NaN sleep, others were clamped), and the options refuse values that are not finite.
TEST(WorkcellTwinTest, BadSpeedsAndOptionsAreRefused) {
  WorkcellTwin twin({});
  for (const double f : {std::nan(""), 0.0, 1.5}) {
    hal::MoveOptions o;
    o.speed_fraction = f;
    EXPECT_EQ(twin.rail(0).MoveTo(1000.0, o).code(), StatusCode::kInvalidArgument) << f;
  }
  WorkcellTwinOptions o;
  EXPECT_TRUE(o.Check().ok());
  o.wall_distance_max_mm = INFINITY;
  EXPECT_FALSE(o.Check().ok());
  o = {};
  o.spot_sigma_mm = INFINITY;
  EXPECT_FALSE(o.Check().ok());
  o = {};
  o.psi_sigma[2] = -1;
  EXPECT_FALSE(o.Check().ok());
}

TEST(WorkcellTwinTest, SpotIsWhereTheTrueBeamMeetsTheWall) {
  WorkcellTwinOptions o;
  o.spot_sigma_mm = 0.0;
  WorkcellTwin twin(o);
  EXPECT_EQ(twin.ObserveSpot(0, 0).status().code(), StatusCode::kNotFound);  // laser off
  ASSERT_TRUE(twin.laser(0).SetOn(true).ok());
  // Aim roughly at the left wall (+y): joint 1 at 90 degrees, upper arm and forearm level and in line,
  // the tool tilted 10 degrees.
  ASSERT_TRUE(twin.arm(0).MoveJoints(JointsFromDeg({90, 0, 90, 0, 10, 0}), {}).ok());
  const auto spot = twin.ObserveSpot(0, 0);
  ASSERT_TRUE(spot.ok()) << spot.status().ToString();
  // The spot lies on the true laser line.
  const Rigid3d world_from_base = twin.WorldFromBase(0);
  const Joints q = twin.true_joints(0);
  const Line3d l = LaserLineInBase(twin.true_robot(0).data(), twin.true_laser(0).data(), q.data());
  const Line3d world_line{world_from_base * l.origin, world_from_base.RotateVector(l.direction)};
  const Vec3d p = twin.walls()[0].world_from_wall * Vec3d(spot->x(), spot->y(), 0.0);
  EXPECT_LT(DistancePointToLine(world_line, p), 1e-6);
  // The setup's wall differs from the truth by the configured errors (tens of mm, a degree).
  const Wall setup = twin.Setup().walls[0];
  EXPECT_GT((setup.world_from_wall.translation - twin.walls()[0].world_from_wall.translation).norm(), 1.0);
  EXPECT_LT(RadToDeg(RotationAngle(Mat3d(setup.world_from_wall.rotation.transpose() * twin.walls()[0].world_from_wall.rotation))), 5.0);
}

}  // namespace
}  // namespace idi::sim
