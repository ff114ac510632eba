#include "shared/calib/acquisition.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "shared/calib/calib_test_util.h"

namespace idi::calib {
namespace {

TEST(AcquisitionTest, PlannedConfigurationsAimAtTheTargetAwayFromTheWrist) {
  const ParamSet robot = Rx130Nominal(), laser = LaserNominal();
  const Vec3d target(500, 4000, 200);
  PlanOptions o;
  const auto q = PlanAimConfigurations(robot, laser, target, 20, Rx130JointLimits(), o);
  ASSERT_TRUE(q.ok()) << q.status().ToString();
  ASSERT_EQ(q->size(), 20u);
  for (const Joints& j : *q) {
    const Line3d l = LaserLineInBase(robot.data(), laser.data(), j.data());
    EXPECT_LT(DistancePointToLine(l, target), 1e-5);
    EXPECT_GT(ProjectOntoLine(l, target), o.min_length_mm);
    EXPECT_GE(std::abs(j[4]), DegToRad(o.wrist_margin_deg) - 1e-9);
    EXPECT_TRUE(Rx130JointLimits().Contains(j));
  }
  // Different draws: the configurations differ.
  EXPECT_GT(std::abs((*q)[0][0] - (*q)[1][0]) + std::abs((*q)[0][3] - (*q)[1][3]), 1e-3);
}

TEST(AcquisitionTest, UnreachableTargetsFailClearly) {
  PlanOptions o;
  o.max_draws = 20000;
  const auto q = PlanAimConfigurations(Rx130Nominal(), LaserNominal(), Vec3d(0, 0, 100), 5, Rx130JointLimits(), o);
  EXPECT_FALSE(q.ok());
}

// A reading in set 0 or 3 is refused by the selection and the covariance helpers, as by the
// calibration (before: an abort in the problem's block check, or an index out of range).
TEST(AcquisitionTest, AReadingOutsideSetsOneAndTwoIsRefused) {
  const ArmModel arm = testing::PerturbedArm(31);
  const Vec3d point(500, 4000, 200);
  RobotCalibrationData pool = testing::ExactRobotData(arm, point, 1000.0, 50, 3);
  const ParamSet params = PackRobotCalibration(Rx130Nominal(), LaserNominal(), point, ParamSet(RailParamSpecs()));
  for (const int set : {0, 3}) {
    pool.readings[7].set = set;
    const auto s = SelectForConditioning(pool, params, {}, 20);
    ASSERT_FALSE(s.ok());
    EXPECT_NE(s.status().message().find("reading 8: set must be 1 or 2"), std::string::npos) << s.status().ToString();
    EXPECT_EQ(RobotCovarianceAt(pool, params, {}).status().code(), StatusCode::kInvalidArgument);
  }
}

TEST(AcquisitionTest, SelectionImprovesTheConditioning) {
  const ArmModel arm = testing::PerturbedArm(31);
  const Vec3d point(500, 4000, 200);
  const RobotCalibrationData pool = testing::ExactRobotData(arm, point, 1000.0, 120, 3);
  const ParamSet params = PackRobotCalibration(Rx130Nominal(), LaserNominal(), point, ParamSet(RailParamSpecs()));
  const auto s = SelectForConditioning(pool, params, {}, 40);
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  EXPECT_EQ(s->chosen.size(), 80u);
  int set2 = 0;
  for (int i : s->chosen) set2 += pool.readings[static_cast<std::size_t>(i)].set == 2;
  EXPECT_EQ(set2, 40);
  EXPECT_TRUE(std::isfinite(s->condition_number));
  EXPECT_LT(s->condition_number, s->condition_number_first);
}

// The "true" arm differs from the model used for aiming; the camera sees the true spot.
TEST(AcquisitionTest, ClosedLoopDrivesTheSpotOntoTheTarget) {
  const ArmModel truth = testing::PerturbedArm(32);
  const ParamSet robot = Rx130Nominal(), laser = LaserNominal();
  Rigid3d base_from_wall;  // wall y = 4000 facing the robot: x along base x, y up, z towards the robot
  base_from_wall.rotation << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  base_from_wall.translation = Vec3d(0, 4000, 0);
  // The loop's model of the wall is 1 degree and 15 mm off.
  Rigid3d approx = base_from_wall;
  approx.rotation = Eigen::AngleAxisd(DegToRad(1.0), Vec3d(0.3, 0.5, 0.8).normalized()).toRotationMatrix() * approx.rotation;
  approx.translation += Vec3d(10, -5, 10);
  Joints current{};
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 0.05);
  JointMover move = [&](const Joints& q) -> Result<Joints> {
    current = QuantizeToEncoders(q);
    return current;
  };
  SpotObserver observe = [&]() -> Result<Vec2d> {
    const auto s = SpotOnPlane(truth.robot, truth.laser, base_from_wall, current);
    if (!s) return NotFound("no spot");
    return Vec2d(s->x() + noise(rng), s->y() + noise(rng));
  };
  const Vec2d target(600, 150);
  const Vec3d target_base = approx * Vec3d(target.x(), target.y(), 0);
  const auto starts = PlanAimConfigurations(robot, laser, target_base, 5, Rx130JointLimits(), {});
  ASSERT_TRUE(starts.ok());
  for (const Joints& s : *starts) {
    const auto r = AimClosedLoop(robot, laser, approx, target, s, Rx130JointLimits(), move, observe, {});
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    const auto true_spot = SpotOnPlane(truth.robot, truth.laser, base_from_wall, r->reading);
    ASSERT_TRUE(true_spot.has_value());
    EXPECT_LT((*true_spot - target).norm(), 0.3);  // a few sigma of the camera noise
    EXPECT_LT(r->iterations, 10);
  }
}

// A spot camera or an arm that returns a non-finite value is a device fault (DeviceError), never a
// NaN joint command: before, a NaN spot went through the clamp and the count rounding into move().
TEST(AcquisitionTest, ANonFiniteSpotOrReadingIsADeviceFaultAndNoNaNIsCommanded) {
  const ParamSet robot = Rx130Nominal(), laser = LaserNominal();
  Rigid3d base_from_wall;
  base_from_wall.rotation << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  base_from_wall.translation = Vec3d(0, 4000, 0);
  const Vec2d target(600, 150);
  const auto starts =
      PlanAimConfigurations(robot, laser, base_from_wall * Vec3d(target.x(), target.y(), 0), 1, Rx130JointLimits(), {});
  ASSERT_TRUE(starts.ok() && !starts->empty());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const bool bad_spot : {true, false}) {
    int moves = 0;
    bool nan_commanded = false;
    JointMover move = [&](const Joints& q) -> Result<Joints> {
      ++moves;
      for (const double v : q) nan_commanded |= !std::isfinite(v);
      Joints r = QuantizeToEncoders(q);
      if (!bad_spot && moves == 2) r[3] = nan;  // the second reading is garbage
      return r;
    };
    SpotObserver observe = [&]() -> Result<Vec2d> { return bad_spot ? Vec2d(nan, 10.0) : Vec2d(0.0, 0.0); };
    const auto r =
        AimClosedLoop(robot, laser, base_from_wall, target, starts->front(), Rx130JointLimits(), move, observe, {});
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), StatusCode::kDeviceError) << r.status().ToString();
    EXPECT_FALSE(nan_commanded);
    EXPECT_EQ(moves, bad_spot ? 1 : 2);
  }
}

// Aims at one target from many starts with a perfect camera; returns the true spot's miss (mm) per aim.
std::vector<Vec2d> TrueMisses(bool quantize, const AimLoopOptions& o) {
  const ArmModel truth = testing::PerturbedArm(33);
  const ParamSet robot = Rx130Nominal(), laser = LaserNominal();
  Rigid3d base_from_wall;
  base_from_wall.rotation << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  base_from_wall.translation = Vec3d(0, 4000, 0);
  Joints current{};
  JointMover move = [&](const Joints& q) -> Result<Joints> {
    current = quantize ? QuantizeToEncoders(q) : q;
    return current;
  };
  SpotObserver observe = [&]() -> Result<Vec2d> {
    const auto s = SpotOnPlane(truth.robot, truth.laser, base_from_wall, current);
    if (!s) return NotFound("no spot");
    return *s;
  };
  const Vec2d target(400, 250);
  const auto starts = PlanAimConfigurations(robot, laser, base_from_wall * Vec3d(target.x(), target.y(), 0), 40,
                                            Rx130JointLimits(), {});
  EXPECT_TRUE(starts.ok());
  std::vector<Vec2d> misses;
  if (!starts.ok()) return misses;
  for (const Joints& s : *starts) {
    const auto r = AimClosedLoop(robot, laser, base_from_wall, target, s, Rx130JointLimits(), move, observe, o);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    if (!r.ok()) continue;
    const auto spot = SpotOnPlane(truth.robot, truth.laser, base_from_wall, r->reading);
    EXPECT_TRUE(spot.has_value());
    if (spot) misses.push_back(*spot - target);
  }
  return misses;
}

// The loop's Jacobian is the nominal model's, so one correction of an error e leaves a remainder of
// up to about 1% of e, in the direction the loop came from. The second correction starts from that
// remainder alone. With a perfect camera and continuous joints, at a 0.1 mm tolerance, the spot then
// lands within 2e-5 mm; after one correction it is up to about 5e-4 mm off.
TEST(AcquisitionTest, SecondFinalCorrectionRemovesTheNominalJacobiansRemainder) {
  AimLoopOptions o;
  o.tolerance_mm = 0.1;
  o.round_to_encoder_counts = false;
  ASSERT_EQ(o.final_corrections, 2);
  const std::vector<Vec2d> misses = TrueMisses(false, o);
  ASSERT_EQ(misses.size(), 40u);
  for (const Vec2d& m : misses) EXPECT_LT(m.norm(), 2e-5);
}

// With encoder counts, a correction smaller than a count is lost to plain rounding, and the spot stays
// where the approach left it: on one side of the target, aim after aim. Choosing the counts by their
// effect on the spot leaves misses of a fraction of a count's spot step (about 3e-4 mm for joints 1-3
// at 4 m), centred on the target.
TEST(AcquisitionTest, EncoderAwareRoundingLeavesCentredSubCountMisses) {
  AimLoopOptions o;
  o.tolerance_mm = 0.01;
  const std::vector<Vec2d> misses = TrueMisses(true, o);
  ASSERT_EQ(misses.size(), 40u);
  Vec2d mean = Vec2d::Zero();
  double ss = 0;
  for (const Vec2d& m : misses) {
    mean += m / static_cast<double>(misses.size());
    ss += m.squaredNorm() / static_cast<double>(misses.size());
  }
  EXPECT_LT(std::sqrt(ss), 3e-4);
  EXPECT_LT(mean.norm(), 1e-4);
}

}  // namespace
}  // namespace idi::calib
