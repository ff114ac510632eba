#include "shared/camera/pinhole.h"

#include <gtest/gtest.h>

#include <cmath>

namespace idi {
namespace {

CameraModel DistortedCamera() {
  CameraModel c;
  c.params = {812.0, 808.0, 321.3, 238.7, -0.21, 0.09, 0.0012, -0.0008, -0.01};
  return c;
}

TEST(PinholeTest, ProjectsHandComputedPoint) {
  CameraModel c;  // fx = fy = 800, principal point at the image centre (319.5, 239.5)
  const auto px = Project(c, Vec3d(0.1, -0.05, 2.0));
  ASSERT_TRUE(px.has_value());
  EXPECT_NEAR(px->x(), 319.5 + 800 * 0.05, 1e-12);
  EXPECT_NEAR(px->y(), 239.5 - 800 * 0.025, 1e-12);
  EXPECT_FALSE(Project(c, Vec3d(0, 0, -1)).has_value());
  EXPECT_FALSE(Project(c, Vec3d(0, 0, 0)).has_value());
}

TEST(PinholeTest, PixelCentreConvention) {
  CameraModel c;
  EXPECT_TRUE(c.InImage(Vec2d(-0.5, -0.5)));
  EXPECT_TRUE(c.InImage(Vec2d(639.5, 479.5)));
  EXPECT_FALSE(c.InImage(Vec2d(639.6, 10)));
  // The optical axis lands on the principal point, which is the centre of a 640x480 image.
  EXPECT_TRUE(Project(c, Vec3d(0, 0, 1))->isApprox(Vec2d(319.5, 239.5)));
}

TEST(PinholeTest, DistortionHandComputed) {
  // Only k1 = 0.1: (0.5, 0) has r^2 = 0.25 so it moves out by a factor 1.025.
  CameraModel c;
  c.params[kK1] = 0.1;
  const Vec2d px = *Project(c, Vec3d(0.5, 0.0, 1.0));
  EXPECT_NEAR(px.x(), 319.5 + 800 * 0.5 * 1.025, 1e-9);
  EXPECT_NEAR(px.y(), 239.5, 1e-12);
}

TEST(PinholeTest, UnprojectInvertsProject) {
  const CameraModel c = DistortedCamera();
  for (double x = -0.35; x <= 0.35; x += 0.07) {
    for (double y = -0.28; y <= 0.28; y += 0.07) {
      const Vec3d p(x * 3.0, y * 3.0, 3.0);
      const Vec2d px = *Project(c, p);
      const Vec3d ray = PixelToRay(c, px);
      EXPECT_LT((ray - p.normalized()).norm(), 1e-11) << x << ", " << y;
    }
  }
}

// k1 = -0.3 alone: r (1 - 0.3 r^2) grows up to r = 1/sqrt(0.9) = 1.054 (distorted radius 0.703) and
// then folds back. A point beyond the fold is not projected (it landed on a pixel inside the image),
// and a pixel no ray reaches, or one the iteration cannot invert, has no ray (before: the fold's
// point, in the opposite direction, or an unconverged one, both as valid).
TEST(PinholeTest, StrongBarrelDistortionBeyondItsFoldHasNoPixelAndNoRay) {
  CameraModel c;
  c.params = {400, 400, 319.5, 239.5, -0.3, 0, 0, 0, 0};
  EXPECT_NEAR(MonotonicRadius(c), 1 / std::sqrt(0.9), 1e-9);
  EXPECT_TRUE(std::isinf(MonotonicRadius(CameraModel{})));
  EXPECT_TRUE(Project(c, Vec3d(1.0, 0, 1)).has_value());
  EXPECT_FALSE(Project(c, Vec3d(2.0, 0, 1)).has_value());
  // Pixels at distorted radius 1.0 and 0.8 (> 0.703): no ray.
  EXPECT_FALSE(PixelToNormalized(c, Vec2d(-0.5, -0.5)).allFinite());
  EXPECT_FALSE(PixelToNormalized(c, Vec2d(639.5, 239.5)).allFinite());
  // Inside the fold, the inverse is exact.
  const Vec2d px = *Project(c, Vec3d(0.9, 0.3, 1));
  EXPECT_LT((PixelToNormalized(c, px) - Vec2d(0.9, 0.3)).norm(), 1e-9);
  const Status st = CheckDistortionCoversImage(c);
  EXPECT_EQ(st.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(st.message().find("folds back"), std::string::npos) << st.ToString();
  c.params[kFx] = c.params[kFy] = 800;  // the corners at distorted radius 0.5: within the fold
  EXPECT_TRUE(CheckDistortionCoversImage(c).ok());
  EXPECT_TRUE(CheckDistortionCoversImage(DistortedCamera()).ok());
  // Pincushion that folds further out (k1 0.2, k2 -0.05: r_max 1.88): the point at r = 1.6 distorts to
  // 1.895, and its inverse is found (started at the distorted radius, beyond r_max, the iteration
  // settled on the fold's branch, 2.108, and the pixel had no ray).
  CameraModel pin;
  pin.params = {400, 400, 319.5, 239.5, 0.2, -0.05, 0, 0, 0};
  const Vec2d far = *Project(pin, Vec3d(1.6, 0, 1));
  EXPECT_LT((PixelToNormalized(pin, far) - Vec2d(1.6, 0)).norm(), 1e-9);
}

TEST(PinholeTest, UndistortPixelIsIdentityWithoutDistortion) {
  CameraModel c;
  EXPECT_TRUE(UndistortPixel(c, Vec2d(10.25, 400.75)).isApprox(Vec2d(10.25, 400.75), 1e-12));
}

TEST(PinholeTest, ParamSetRoundTrip) {
  const CameraModel c = DistortedCamera();
  const ParamSet set = CameraToParamSet(c);
  EXPECT_EQ(set.spec(0).Key(), "fx_px");
  EXPECT_EQ(set.spec(4).Key(), "k1");
  const CameraModel back = CameraFromParamSet(set, 640, 480);
  EXPECT_EQ(back.params, c.params);
}

}  // namespace
}  // namespace idi
