#include "shared/kinematics/rx130.h"

#include <gtest/gtest.h>

namespace idi {
namespace {

constexpr double kTol = 1e-9;

Rigid3d NominalFk(const std::array<double, 6>& deg) {
  const ParamSet p = Rx130Nominal();
  const Joints q = JointsFromDeg(deg);
  return Rx130BaseFromFlange(p.data(), q.data());
}

TEST(Rx130Test, NominalParametersMatchTable41) {
  const ParamSet p = Rx130Nominal();
  ASSERT_EQ(p.size(), static_cast<std::size_t>(kRx130ParamCount));
  EXPECT_EQ(p.spec(kAlpha2).Key(), "alpha2_deg");
  EXPECT_EQ(p.spec(kBeta3).Key(), "beta3_deg");
  EXPECT_EQ(p.spec(kD4).Key(), "d4_mm");
  EXPECT_EQ(p.spec(kA6).Key(), "a6_mm");
  EXPECT_DOUBLE_EQ(p.file_value(kA3), 625.0);
  EXPECT_DOUBLE_EQ(p.file_value(kD4), 625.0);
  EXPECT_DOUBLE_EQ(p.file_value(kTheta3), -180.0);
  EXPECT_DOUBLE_EQ(p.file_value(kAlpha4), -90.0);  // not Table 3.1's +90
  EXPECT_DOUBLE_EQ(p.file_value(kAlpha5), 90.0);
  EXPECT_DOUBLE_EQ(p.file_value(kAlpha6), -90.0);
}

// All readings zero. Link 2: Rx(-90°) turns z2 into the base's +y (axes 2 and 3 horizontal). Link 3:
// a3 = 625 along x2 = base x, and Rz(-180°) flips x3, y3: x3 = -x, y3 = +z, z3 = +y. Link 4: Rx(-90°)
// then d4 = 625 along z4 = y3 = base +z: the forearm points up, o4 = (625, 0, 625). Links 5 and 6
// twist back (Rx(+90°), Rx(-90°), Rz(180°)), leaving the flange 110 mm further along +z with the
// base's orientation: (625, 0, 735), R = I.
TEST(Rx130Test, NominalPoseAtZero) {
  const Rigid3d t = NominalFk({0, 0, 0, 0, 0, 0});
  EXPECT_TRUE(t.translation.isApprox(Vec3d(625, 0, 735), kTol)) << t.translation.transpose();
  EXPECT_TRUE(t.rotation.isApprox(Mat3d::Identity(), kTol)) << t.rotation;
}

// Joint 1 turns everything about the base z axis.
TEST(Rx130Test, NominalPoseJoint1) {
  const Rigid3d t = NominalFk({90, 0, 0, 0, 0, 0});
  EXPECT_TRUE(t.translation.isApprox(Vec3d(0, 625, 735), kTol));
  EXPECT_TRUE(t.rotation.isApprox(RotZ(kPi / 2).rotation, kTol));
}

// Joint 2 at -90° raises the upper arm to vertical (rotation about +y by -90° maps x to z); joint 3 at
// +90° brings the forearm in line: the arm stands straight up, 625 + 625 + 110 = 1360 mm.
TEST(Rx130Test, NominalPoseArmStraightUp) {
  const Rigid3d t = NominalFk({0, -90, 90, 0, 0, 0});
  EXPECT_TRUE(t.translation.isApprox(Vec3d(0, 0, 1360), kTol)) << t.translation.transpose();
  EXPECT_TRUE(t.rotation.isApprox(Mat3d::Identity(), kTol));
}

// Joint 5 axis is the base's +y at zero; bending it 90° swings the 110 mm tool from +z to +x about the
// wrist centre (625, 0, 625).
TEST(Rx130Test, NominalPoseWristBent) {
  const Rigid3d t = NominalFk({0, 0, 0, 0, 90, 0});
  EXPECT_TRUE(t.translation.isApprox(Vec3d(735, 0, 625), kTol)) << t.translation.transpose();
  EXPECT_TRUE(t.rotation.isApprox(RotY(kPi / 2).rotation, kTol));
}

// Joint 4 and joint 6 spin about the (vertical) forearm and tool axes: position unchanged, and with
// q4 = -q6 the orientation too.
TEST(Rx130Test, NominalWristRollsCancel) {
  const Rigid3d t = NominalFk({0, 0, 0, 30, 0, -30});
  EXPECT_TRUE(t.translation.isApprox(Vec3d(625, 0, 735), kTol));
  EXPECT_TRUE(t.rotation.isApprox(Mat3d::Identity(), kTol));
  const Rigid3d t4 = NominalFk({0, 0, 0, 30, 0, 0});
  EXPECT_TRUE(t4.rotation.isApprox(RotZ(DegToRad(30.0)).rotation, kTol));
}

TEST(Rx130Test, LaserLineWithZeroParametersIsTheFlangeZAxis) {
  const ParamSet robot = Rx130Nominal();
  const ParamSet laser = LaserNominal();
  const Joints q = JointsFromDeg({10, -40, 70, 5, 30, -20});
  const Line3d line = LaserLineInBase(robot.data(), laser.data(), q.data());
  const Rigid3d flange = Rx130BaseFromFlange(robot.data(), q.data());
  EXPECT_TRUE(line.origin.isApprox(flange.translation, kTol));
  EXPECT_TRUE(line.direction.isApprox(flange.rotation.col(2), kTol));
}

// ^6T_7 = Rx(tx) Ry(ty) Tx(px) Ty(py), checked against the printed matrix of §3.3.3.
TEST(Rx130Test, LaserToolMatrixMatchesClosedForm) {
  const double tx = DegToRad(0.7), ty = DegToRad(-1.3), px = 2.5, py = -1.25;
  const std::array<double, 4> l = {tx, ty, px, py};
  const Rigid3d t = FlangeFromLaser(l.data());
  Mat4d expected;
  expected << std::cos(ty), 0, std::sin(ty), px * std::cos(ty),  //
      std::sin(tx) * std::sin(ty), std::cos(tx), -std::sin(tx) * std::cos(ty),
      px * std::sin(tx) * std::sin(ty) + py * std::cos(tx),  //
      -std::cos(tx) * std::sin(ty), std::sin(tx), std::cos(tx) * std::cos(ty),
      -px * std::cos(tx) * std::sin(ty) + py * std::sin(tx),  //
      0, 0, 0, 1;
  EXPECT_TRUE(t.Matrix().isApprox(expected, 1e-12)) << t.Matrix() << "\n" << expected;
}

TEST(Rx130Test, JointAxesAreConsistentWithForwardKinematics) {
  const ParamSet robot = Rx130Nominal();
  const Joints q{};
  const auto axes = Rx130JointAxes(robot, q);
  EXPECT_TRUE(axes[0].direction.isApprox(Vec3d::UnitZ(), kTol));
  EXPECT_TRUE(axes[1].direction.isApprox(Vec3d::UnitY(), kTol));  // joint 2 horizontal
  EXPECT_TRUE(axes[2].direction.isApprox(Vec3d::UnitY(), kTol));  // parallel to joint 2
  EXPECT_TRUE(axes[3].direction.isApprox(Vec3d::UnitZ(), kTol));  // forearm roll, vertical
  EXPECT_TRUE(axes[2].origin.isApprox(Vec3d(625, 0, 0), kTol));
}

TEST(Rx130Test, EncoderQuantizationRoundsToCounts) {
  const Joints q = JointsFromDeg({10.000001, -20.0000049, 30.0, 1e-6, 2.0000163, -3.0});
  const Joints qq = QuantizeToEncoders(q);
  for (std::size_t i = 0; i < kRx130Joints; ++i) {
    const double counts = RadToDeg(qq[i]) * kRx130CountsPerDeg[i];
    EXPECT_NEAR(counts, std::round(counts), 1e-6) << "joint " << i + 1;
    EXPECT_LE(std::abs(RadToDeg(qq[i] - q[i])), 0.5 / kRx130CountsPerDeg[i] + 1e-12);
  }
}

TEST(Rx130Test, JointLimitsInModelConvention) {
  const JointLimits limits = Rx130JointLimits();
  EXPECT_TRUE(limits.Contains(JointsFromDeg({0, -90, 90, 0, 0, 0})));  // straight up is the controller's zero
  EXPECT_FALSE(limits.Contains(JointsFromDeg({170, -90, 90, 0, 0, 0})));
  EXPECT_EQ(limits.FirstViolation(JointsFromDeg({0, -90, 90, 0, 125, 0})), 4);
}

}  // namespace
}  // namespace idi
