#include "shared/kinematics/biclops.h"

#include <gtest/gtest.h>

#include <random>

#include "shared/util/units.h"

namespace idi {
namespace {

std::vector<double> NominalPtu(BiclopsSide side) {
  const ParamSet p(PtuParamSpecs(side));
  return p.values();
}

TEST(BiclopsTest, TcfMatrixMatchesEq310) {
  const double a = 0.3, b = 1.1, g = -0.7;
  const Rigid3d t = BaseFromTcf(10.0, 20.0, 30.0, a, b, g);
  const double ca = std::cos(a), sa = std::sin(a), cb = std::cos(b), sb = std::sin(b), cg = std::cos(g),
               sg = std::sin(g);
  Mat3d r;
  r << ca * cb * cg - sa * sg, -ca * cb * sg - sa * cg, ca * sb,  //
      sa * cb * cg + ca * sg, -sa * cb * sg + ca * cg, sa * sb,     //
      -sb * cg, sb * sg, cb;
  EXPECT_TRUE(t.rotation.isApprox(r, 1e-14));
  EXPECT_TRUE(t.translation.isApprox(Vec3d(10, 20, 30)));
}

TEST(BiclopsTest, TcfPoseRoundTrip) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ang(-3.0, 3.0), beta(0.05, 3.09);
  for (int i = 0; i < 50; ++i) {
    const TcfPose p{1.0 * i, -2.0 * i, 3.0, ang(rng), beta(rng), ang(rng)};
    const TcfPose back = TcfPoseFromTransform(BaseFromTcf(p));
    EXPECT_TRUE(BaseFromTcf(back).Matrix().isApprox(BaseFromTcf(p).Matrix(), 1e-12));
    EXPECT_NEAR(back.beta_rad, p.beta_rad, 1e-12);
  }
  for (double b : {0.0, kPi}) {  // gimbal lock: the rotation is still reproduced
    const TcfPose p{0, 0, 0, 0.4, b, 0.0};
    EXPECT_TRUE(BaseFromTcf(TcfPoseFromTransform(BaseFromTcf(p))).rotation.isApprox(BaseFromTcf(p).rotation, 1e-12));
  }
}

// Just outside the gimbal-lock band (a tool tilted by 2e-12 rad, e.g. a flange pose from IK pointing
// straight down): alpha and gamma from the third row and column alone are mostly rounding noise, and the
// pose rebuilt from them was off by up to 1e-4 rad. Gamma from what alpha and beta leave rebuilds it.
TEST(BiclopsTest, TcfPoseRoundTripNearGimbalLock) {
  for (const double a : {0.3, -2.0, 1.1}) {
    for (const double g : {0.7, -1.4, 2.9}) {
      const Rigid3d t = Translation(1.0, 2.0, 3.0) * RotZ(a) * RotY(1.0) * RotY(-1.0 + 2e-12) * RotZ(g);
      const Rigid3d back = BaseFromTcf(TcfPoseFromTransform(t));
      EXPECT_LT((back.rotation - t.rotation).cwiseAbs().maxCoeff(), 1e-12) << a << " " << g;
    }
  }
}

TEST(BiclopsTest, PtuBaseMatchesEq311) {
  std::vector<double> ptu(kPtuParamCount, 0.0);
  ptu[kPtuTx] = 1;
  ptu[kPtuTy] = 2;
  ptu[kPtuTz] = 3;
  const double x = 0.2, y = -0.4, z = 0.9;
  ptu[kPtuThetaX] = x;
  ptu[kPtuThetaY] = y;
  ptu[kPtuThetaZ] = z;
  // With pan = tilt = 0 and all DH parameters zero, ^E T_3 = ^E T_0.
  const Rigid3d t = TcfFromCamera(ptu.data(), 0.0, 0.0);
  const double cx = std::cos(x), sx = std::sin(x), cy = std::cos(y), sy = std::sin(y), cz = std::cos(z),
               sz = std::sin(z);
  Mat3d r;
  r << cy * cz, -cy * sz, sy,                   //
      sx * sy * cz + cx * sz, -sx * sy * sz + cx * cz, -sx * cy,  //
      -cx * sy * cz + sx * sz, cx * sy * sz + sx * cz, cx * cy;
  EXPECT_TRUE(t.rotation.isApprox(r, 1e-14));
  EXPECT_TRUE(t.translation.isApprox(Vec3d(1, 2, 3)));
}

TEST(BiclopsTest, PanRotatesAboutThePanAxis) {
  const auto ptu = NominalPtu(BiclopsSide::kLeft);
  // The pan axis is z of frame 0: the camera centre turns on a circle about it, keeping its height
  // along the axis and its distance from it.
  const Rigid3d e_from_0 = Translation(ptu[kPtuTx], ptu[kPtuTy], ptu[kPtuTz]) * RotX(ptu[kPtuThetaX]) *
                           RotY(ptu[kPtuThetaY]) * RotZ(ptu[kPtuThetaZ]);
  const Vec3d c0 = e_from_0.Inverse() * TcfFromCamera(ptu.data(), 0.0, 0.2).translation;
  const Vec3d c1 = e_from_0.Inverse() * TcfFromCamera(ptu.data(), 0.9, 0.2).translation;
  EXPECT_NEAR(c0.z(), c1.z(), 1e-12);
  EXPECT_NEAR(c0.head<2>().norm(), c1.head<2>().norm(), 1e-12);
  EXPECT_TRUE(c1.head<2>().isApprox(Eigen::Rotation2Dd(0.9) * c0.head<2>(), 1e-12));
}

TEST(BiclopsTest, ProjectionAgreesWithProjectionMatrix) {
  const auto ptu = NominalPtu(BiclopsSide::kRight);
  const CameraModel cam = BiclopsNominalCamera(BiclopsSide::kRight);
  const TcfPose pose{900, -200, 1400, 0.3, 2.8, -0.4};
  const Rigid3d base_from_tcf = BaseFromTcf(pose);
  const double pan = 0.15, tilt = -0.3;
  const Rigid3d base_from_cam = base_from_tcf * TcfFromCamera(ptu.data(), pan, tilt);
  // A point 1.5 m in front of the camera.
  const Vec3d point = base_from_cam * Vec3d(40, -25, 1500);
  Vec2d px;
  ASSERT_TRUE(ProjectThroughBiclops(base_from_tcf, ptu.data(), cam.params.data(), pan, tilt, point, &px));
  const Eigen::Matrix<double, 3, 4> p = ProjectionMatrix(cam, base_from_cam.Inverse());
  const Vec3d w = p * point.homogeneous();
  EXPECT_TRUE(px.isApprox(w.hnormalized(), 1e-10));
  EXPECT_NEAR(px.x(), 319.5 + 1240.0 * 40 / 1500, 1e-9);
  // A point behind the camera is refused.
  const Vec3d behind = base_from_cam * Vec3d(0, 0, -100);
  EXPECT_FALSE(ProjectThroughBiclops(base_from_tcf, ptu.data(), cam.params.data(), pan, tilt, behind, &px));
}

}  // namespace
}  // namespace idi
