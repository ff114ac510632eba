#include "shared/reconstruction/epipolar.h"

#include <gtest/gtest.h>

#include <random>

#include "tests/support/wireframe_views.h"

#include "shared/util/units.h"

namespace idi {
namespace {


TEST(EpipolarTest, FundamentalSatisfiesTheEpipolarConstraint) {
  const Mat3d k = (Mat3d() << 1200, 0, 320, 0, 1190, 240, 0, 0, 1).finished();
  const Rigid3d c1 = test::LookAt(Vec3d(1000, -800, 600), Vec3d(0, 0, 100));
  const Rigid3d c2 = test::LookAt(Vec3d(-300, -1100, 900), Vec3d(50, 20, 80));
  const auto p1 = MakeProjection(k, c1), p2 = MakeProjection(k, c2);
  const auto f = FundamentalFromProjections(p1, p2);
  ASSERT_TRUE(f.has_value());
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-150, 150);
  for (int i = 0; i < 50; ++i) {
    const Vec3d x(u(rng), u(rng), 100 + u(rng));
    const Vec2d x1 = (p1 * x.homogeneous()).hnormalized();
    const Vec2d x2 = (p2 * x.homogeneous()).hnormalized();
    EXPECT_LT(EpipolarDistance(*f, x1, x2), 1e-8);
    EXPECT_LT(std::abs(EpipolarLineInFirst(*f, x2).SignedDistance(x1)), 1e-8);
  }
  // Agrees with the essential-matrix route F ~ K^-T [t]x R K^-1 for the relative pose cam2_from_cam1.
  const Rigid3d rel = c2 * c1.Inverse();
  Mat3d tx;
  tx << 0, -rel.translation.z(), rel.translation.y(), rel.translation.z(), 0, -rel.translation.x(),
      -rel.translation.y(), rel.translation.x(), 0;
  Mat3d f_e = k.inverse().transpose() * tx * rel.rotation * k.inverse();
  f_e /= f_e.norm();
  const double sign = (f_e.array() * f->array()).sum() > 0 ? 1.0 : -1.0;
  EXPECT_LT((sign * f_e - *f).norm(), 1e-9);
}

TEST(EpipolarTest, CameraCentreIsTheNullVector) {
  const Mat3d k = (Mat3d() << 800, 0, 320, 0, 800, 240, 0, 0, 1).finished();
  const Rigid3d c = test::LookAt(Vec3d(10, 20, 30), Vec3d(0, 0, 0));
  const auto centre = CameraCentre(MakeProjection(k, c));
  ASSERT_TRUE(centre.has_value());
  EXPECT_LT((*centre - Vec3d(10, 20, 30)).norm(), 1e-9);
  // Same centre twice: no epipolar geometry.
  EXPECT_FALSE(FundamentalFromProjections(MakeProjection(k, c), MakeProjection(k, RotZ(0.1) * c)).has_value());
}

TEST(EpipolarTest, HomogeneousLineRoundTrip) {
  const Line2d l = Line2Through(Vec2d(3, 4), Vec2d(10, -2));
  const Line2d back = LineFromHomogeneous(2.5 * HomogeneousLine(l));
  EXPECT_TRUE(back.normal.isApprox(l.normal));
  EXPECT_NEAR(back.offset, l.offset, 1e-12);
}

}  // namespace
}  // namespace idi
