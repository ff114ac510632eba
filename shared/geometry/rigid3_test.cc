#include "shared/geometry/rigid3.h"

#include <gtest/gtest.h>

#include "shared/util/units.h"

namespace idi {
namespace {

constexpr double kTol = 1e-12;

TEST(Rigid3Test, ElementaryRotationsMatchHandValues) {
  // Rz(90°) maps x to y; Rx(90°) maps y to z; Ry(90°) maps z to x.
  EXPECT_TRUE((RotZ(kPi / 2) * Vec3d::UnitX()).isApprox(Vec3d::UnitY(), kTol));
  EXPECT_TRUE((RotX(kPi / 2) * Vec3d::UnitY()).isApprox(Vec3d::UnitZ(), kTol));
  EXPECT_TRUE((RotY(kPi / 2) * Vec3d::UnitZ()).isApprox(Vec3d::UnitX(), kTol));
}

TEST(Rigid3Test, CompositionAppliesRightToLeft) {
  // b_from_a translates by (1,0,0); c_from_b rotates 90° about z: c_from_a maps the origin to (0,1,0).
  const Rigid3d c_from_a = RotZ(kPi / 2) * Translation(1.0, 0.0, 0.0);
  EXPECT_TRUE((c_from_a * Vec3d::Zero()).isApprox(Vec3d(0, 1, 0), kTol));
}

TEST(Rigid3Test, InverseRoundTrip) {
  const Rigid3d t = Translation(3.0, -2.0, 5.0) * RotX(0.3) * RotY(-1.1) * RotZ(2.2);
  const Rigid3d id = t * t.Inverse();
  EXPECT_TRUE(id.rotation.isApprox(Mat3d::Identity(), kTol));
  EXPECT_LT(id.translation.norm(), kTol);
  const Vec3d p(0.4, 7.0, -3.0);
  EXPECT_TRUE((t.Inverse() * (t * p)).isApprox(p, kTol));
  EXPECT_TRUE(t.Matrix().inverse().isApprox(t.Inverse().Matrix(), 1e-10));
}

TEST(Rigid3Test, DhLinkEqualsProductOfElementaryTransforms) {
  // Eq. 3.1: Rx(alpha) Tx(a) Rz(theta) Tz(d).
  const double alpha = -1.2, a = 3.5, theta = 0.7, d = -2.25;
  const Rigid3d expected = RotX(alpha) * Translation(a, 0.0, 0.0) * RotZ(theta) * Translation(0.0, 0.0, d);
  const Rigid3d dh = DhLink(alpha, a, theta, d);
  EXPECT_TRUE(dh.rotation.isApprox(expected.rotation, kTol));
  EXPECT_TRUE(dh.translation.isApprox(expected.translation, kTol));
}

TEST(Rigid3Test, HayatiLinkEqualsProductOfElementaryTransforms) {
  // Eq. 3.2: Rx(alpha) Tx(a) Ry(beta) Rz(theta).
  const double alpha = 0.01, a = 625.0, beta = -0.02, theta = -3.0;
  const Rigid3d expected = RotX(alpha) * Translation(a, 0.0, 0.0) * RotY(beta) * RotZ(theta);
  const Rigid3d h = HayatiLink(alpha, a, beta, theta);
  EXPECT_TRUE(h.rotation.isApprox(expected.rotation, kTol));
  EXPECT_TRUE(h.translation.isApprox(expected.translation, kTol));
}

TEST(Rigid3Test, DhLinkHandComputed) {
  // alpha = 90°, a = 2, theta = 90°, d = 3: the origin of frame i lands at (a, -d sin(alpha), d cos(alpha))
  // = (2, -3, 0), and x_i = (cos theta, cos alpha sin theta, sin alpha sin theta) = (0, 0, 1).
  const Rigid3d t = DhLink(kPi / 2, 2.0, kPi / 2, 3.0);
  EXPECT_TRUE(t.translation.isApprox(Vec3d(2, -3, 0), kTol));
  EXPECT_TRUE(t.rotation.col(0).isApprox(Vec3d(0, 0, 1), kTol));
  EXPECT_NEAR(RotationAngle(Mat3d(Mat3d::Identity())), 0.0, kTol);
  EXPECT_NEAR(RotationAngle(RotZ(0.5).rotation), 0.5, 1e-9);
}

TEST(Rigid3Test, ZeroParametersGiveIdentity) {
  const Rigid3d dh = DhLink(0.0, 0.0, 0.0, 0.0);
  const Rigid3d h = HayatiLink(0.0, 0.0, 0.0, 0.0);
  EXPECT_TRUE(dh.Matrix().isApprox(Mat4d::Identity(), kTol));
  EXPECT_TRUE(h.Matrix().isApprox(Mat4d::Identity(), kTol));
}

}  // namespace
}  // namespace idi
