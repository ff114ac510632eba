#include "shared/kinematics/aiming.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <string>
#include <vector>

namespace idi {
namespace {

TEST(AimingTest, AimDirectionEqs37And38) {
  const AimAngles a = AimDirection(Vec3d(0, 0, 0), Vec3d(1, 1, 0));
  EXPECT_NEAR(a.yaw_rad, kPi / 4, 1e-15);
  EXPECT_NEAR(a.pitch_rad, kPi / 2, 1e-15);
  const AimAngles up = AimDirection(Vec3d(5, 5, 5), Vec3d(5, 5, 10));
  EXPECT_NEAR(up.pitch_rad, 0.0, 1e-15);
  const Vec3d d = Vec3d(3, -4, 12).normalized();
  EXPECT_TRUE(DirectionFromAim(AimDirection(Vec3d::Zero(), d)).isApprox(d, 1e-14));
}

// A calibration-like setting: a wall 3 m in front of the robot, random starting configurations whose
// laser roughly faces it, random points on it. After aiming, the laser line passes within 1e-6 mm.
TEST(AimingTest, AimsLaserThroughTargetsOnAWall) {
  ParamSet robot = Rx130Nominal();
  // A robot that is not nominal, so the test does not rely on special structure.
  robot.set_file_value(kA2, 0.05);
  robot.set_file_value(kD4, 626.25);
  robot.set_file_value(kBeta3, -0.04);
  ParamSet laser = LaserNominal();
  laser.set_file_value(kLaserThetaY, 0.16);
  laser.set_file_value(kLaserPy, 1.63);
  const JointLimits limits = Rx130JointLimits();
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int solved = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const Vec3d target(3000.0, 800.0 * u(rng), 700.0 + 500.0 * u(rng));
    // Start with the tool roughly horizontal, pointing along +x (wrist bent 90°).
    const Joints start = JointsFromDeg({15 * u(rng), -60 + 20 * u(rng), 100 + 20 * u(rng), 20 * u(rng),
                                        90 + 20 * u(rng), 30 * u(rng)});
    const auto r = AimLaserAt(robot, laser, start, target, limits);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    const Line3d line = LaserLineInBase(robot.data(), laser.data(), r->q.data());
    EXPECT_LT(DistancePointToLine(line, target), 1e-6);
    EXPECT_GT(ProjectOntoLine(line, target), 0.0);  // the target is in front of the laser
    EXPECT_TRUE(limits.Contains(r->q));
    ++solved;
  }
  EXPECT_EQ(solved, 40);
}

// Starting with the arm straight up (beam vertical), the target to the side is reached by first
// turning the tool towards it (eqs. 3.6-3.8).
TEST(AimingTest, TurnsTowardsATargetFarFromTheBeam) {
  const ParamSet robot = Rx130Nominal();
  const ParamSet laser = LaserNominal();
  const Joints start = JointsFromDeg({0, -90, 90, 0, 0, 0});
  const Vec3d target(3000, 200, 900);
  const auto r = AimLaserAt(robot, laser, start, target, Rx130JointLimits());
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const Line3d line = LaserLineInBase(robot.data(), laser.data(), r->q.data());
  EXPECT_LT(DistancePointToLine(line, target), 1e-6);
  EXPECT_GT(ProjectOntoLine(line, target), 0.0);
}

TEST(AimingTest, RefusesBadTargets) {
  const ParamSet robot = Rx130Nominal();
  const ParamSet laser = LaserNominal();
  const Joints start = JointsFromDeg({0, -60, 100, 0, 90, 0});
  IkOptions opt;
  opt.max_iterations = 30;
  // The laser origin itself cannot be aimed at.
  const Line3d line = LaserLineInBase(robot.data(), laser.data(), start.data());
  EXPECT_FALSE(AimLaserAt(robot, laser, start, line.origin, Rx130JointLimits(), opt).ok());
  const auto nan = AimLaserAt(robot, laser, start, Vec3d(NAN, 0, 0), Rx130JointLimits(), opt);
  EXPECT_EQ(nan.status().code(), StatusCode::kInvalidArgument);
}

// A target on the backward half of the beam's line is offset from the beam only by rounding noise; that
// noise was taken for a converged aim (at iteration 0) with the beam pointing away from the target. Now
// the start is turned round, or the call fails; it never reports the backward line as aimed.
TEST(AimingTest, ATargetStraightBehindTheLaserIsNeverReportedAsAimed) {
  const ParamSet robot = Rx130Nominal();
  const ParamSet laser = LaserNominal();
  const JointLimits limits = Rx130JointLimits();
  int behind_exactly = 0;
  for (const auto& deg : std::vector<std::array<double, 6>>{{0, 0, 0, 0, 0, 0},
                                                            {0, -90, 90, 0, 0, 0},
                                                            {10, -60, 100, 0, 90, 0},
                                                            {-20, -45, 120, 30, 60, 15},
                                                            {35, -80, 95, -10, 45, 90}}) {
    const Joints start = JointsFromDeg({deg[0], deg[1], deg[2], deg[3], deg[4], deg[5]});
    const Line3d line = LaserLineInBase(robot.data(), laser.data(), start.data());
    const Vec3d target = line.origin - 500.0 * line.direction;
    if (DistancePointToLine(line, target) < 1e-7) ++behind_exactly;
    const auto r = AimLaserAt(robot, laser, start, target, limits);
    if (!r.ok()) continue;
    const Line3d aimed = LaserLineInBase(robot.data(), laser.data(), r->q.data());
    EXPECT_GT(ProjectOntoLine(aimed, target), 0.0) << "start " << deg[0] << " " << deg[1] << " " << deg[2];
    EXPECT_LT(DistancePointToLine(aimed, target), 1e-6);
  }
  EXPECT_EQ(behind_exactly, 5);  // every start had the target within rounding of its backward beam
}

TEST(AimingTest, RefusesOptionsAndStartsThatTurnTheLimitsOff) {
  const ParamSet robot = Rx130Nominal();
  const ParamSet laser = LaserNominal();
  const Joints start = JointsFromDeg({0, -60, 100, 0, 90, 0});
  const Vec3d target(3000, 200, 900);
  IkOptions nan_margin;
  nan_margin.limit_margin_rad = NAN;  // std::clamp(q, NaN, NaN) left every joint unclamped
  EXPECT_EQ(AimLaserAt(robot, laser, start, target, Rx130JointLimits(), nan_margin).status().code(),
            StatusCode::kInvalidArgument);
  IkOptions wide_margin;
  wide_margin.limit_margin_rad = 5.0;  // wider than half of J2's range: lo > hi in std::clamp
  const auto wide = AimLaserAt(robot, laser, start, target, Rx130JointLimits(), wide_margin);
  EXPECT_EQ(wide.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(wide.status().message().find("leave no room"), std::string::npos) << wide.status().message();
  Joints nan_start = start;
  nan_start[2] = NAN;
  const auto ns = AimLaserAt(robot, laser, nan_start, target, Rx130JointLimits());
  EXPECT_EQ(ns.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(ns.status().message().find("start joint 3"), std::string::npos) << ns.status().message();
  Rigid3d pose = Rx130BaseFromFlange(robot.data(), start.data());
  pose.translation.x() = NAN;
  EXPECT_EQ(SolveFlangePose(robot, start, pose, Rx130JointLimits()).status().code(), StatusCode::kInvalidArgument);
}

TEST(AimingTest, FlangePoseIkRecoversForwardKinematics) {
  const ParamSet robot = Rx130Nominal();
  const JointLimits limits = Rx130JointLimits();
  const Joints truth = JointsFromDeg({20, -70, 110, 15, 60, -30});
  const Rigid3d goal = Rx130BaseFromFlange(robot.data(), truth.data());
  const Joints start = JointsFromDeg({15, -65, 100, 10, 55, -20});
  const auto r = SolveFlangePose(robot, start, goal, limits);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const Rigid3d got = Rx130BaseFromFlange(robot.data(), r->q.data());
  EXPECT_LT((got.translation - goal.translation).norm(), 1e-6);
  EXPECT_LT((got.rotation - goal.rotation).norm(), 1e-9);
}

}  // namespace
}  // namespace idi
