#include "shared/kinematics/rtu.h"

#include <gtest/gtest.h>

namespace idi {
namespace {

TEST(RtuTest, RailFromBaseMatchesEq33) {
  const double l = DegToRad(0.8), m = DegToRad(-0.3), d = 1000.0;
  const Rigid3d t = RailFromBase(l, m, d);
  Mat4d expected;
  expected << std::cos(l) * std::cos(m), std::sin(l) * std::cos(m), -std::sin(m), d,  //
      -std::sin(l), std::cos(l), 0, 0,                                                  //
      std::cos(l) * std::sin(m), std::sin(l) * std::sin(m), std::cos(m), 0,             //
      0, 0, 0, 1;
  EXPECT_TRUE(t.Matrix().isApprox(expected, 1e-14));
  // The first row is the rail direction expressed in the base frame (§4.3).
  EXPECT_TRUE(Vec3d(t.rotation.row(0).transpose()).isApprox(RailDirectionInBase(l, m), 1e-14));
}

TEST(RtuTest, MovingAlongTheRailTranslatesTheBaseAlongTheRailDirection) {
  // A fixed point seen from the base at rail positions 0 and D: its base coordinates change by
  // -D times the rail direction (the second point of §4.3's method 2 is P + D t for the reverse move).
  const double l = DegToRad(1.1), m = DegToRad(0.4), big_d = 1000.0;
  const Vec3d p_rail(2500, -300, 800);
  const Vec3d p_b0 = RailFromBase(l, m, 0.0).Inverse() * p_rail;
  const Vec3d p_b1 = RailFromBase(l, m, big_d).Inverse() * p_rail;
  EXPECT_TRUE((p_b0 - p_b1).isApprox(big_d * RailDirectionInBase(l, m), 1e-10));
}

TEST(RtuTest, RobotToRobotMatchesEq35) {
  const std::array<double, 4> psi = {4200.0, -15.0, 3.0, DegToRad(0.5)};
  const Rigid3d t = Rail1FromRail2(psi.data());
  const double c = std::cos(psi[3]), s = std::sin(psi[3]);
  Mat4d expected;
  expected << -1, 0, 0, psi[0], 0, -c, -s, psi[1], 0, -s, c, psi[2], 0, 0, 0, 1;
  EXPECT_TRUE(t.Matrix().isApprox(expected, 1e-14));
}

TEST(RtuTest, Base1FromBase2ComposesEq34) {
  const std::array<double, 2> rail1 = {DegToRad(0.2), DegToRad(-0.1)};
  const std::array<double, 2> rail2 = {DegToRad(-0.4), DegToRad(0.3)};
  const std::array<double, 4> psi = {5000.0, 20.0, -4.0, DegToRad(0.3)};
  const Rigid3d b1_b2 = Base1FromBase2(rail1.data(), 250.0, psi.data(), rail2.data(), 700.0);
  // With zero angles and zero twist the two bases face each other along x, 5000 - 250 - 700 apart.
  const std::array<double, 2> zero = {0, 0};
  const std::array<double, 4> psi0 = {5000.0, 0, 0, 0};
  const Rigid3d simple = Base1FromBase2(zero.data(), 250.0, psi0.data(), zero.data(), 700.0);
  EXPECT_TRUE(simple.translation.isApprox(Vec3d(5000 - 250 - 700, 0, 0), 1e-12));
  EXPECT_TRUE(simple.rotation.isApprox(RotZ(kPi).rotation, 1e-12));
  // Round trip through the inverse.
  const Rigid3d id = b1_b2 * b1_b2.Inverse();
  EXPECT_TRUE(id.Matrix().isApprox(Mat4d::Identity(), 1e-12));
}

}  // namespace
}  // namespace idi
