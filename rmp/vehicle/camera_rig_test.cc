#include "rmp/vehicle/camera_rig.h"

#include <gtest/gtest.h>

#include <cmath>

#include "shared/util/units.h"

namespace idi::rmp {
namespace {

RigCamera Camera(double pitch_deg) {
  RigCamera c;
  c.intrinsics.params = {600, 600, 319.5, 239.5, 0, 0, 0, 0, 0};
  c.vehicle_from_camera = LookAheadCameraPose(0.2, 0.0, 1.0, 0.0, DegToRad(pitch_deg));
  return c;
}

TEST(CameraRigTest, OpticalAxisHitsTheGroundWhereTrigonometrySays) {
  // Camera 1 m up pitched 45° down: the image centre sees the ground 1 m ahead of the camera.
  const RigCamera c = Camera(45);
  const auto px = GroundPointToPixel(c, Vec2d(1.2, 0.0));
  ASSERT_TRUE(px.has_value());
  EXPECT_NEAR(px->x(), 319.5, 1e-9);
  EXPECT_NEAR(px->y(), 239.5, 1e-9);
  // A point to the left of the vehicle (y > 0) appears left in the image (smaller x).
  EXPECT_LT(GroundPointToPixel(c, Vec2d(1.2, 0.1))->x(), 319.5);
  // Closer points appear lower in the image (larger y).
  EXPECT_GT(GroundPointToPixel(c, Vec2d(1.0, 0.0))->y(), 239.5);
  EXPECT_FALSE(GroundPointToPixel(c, Vec2d(-1.0, 0.0)).has_value());
}

// A step that is not positive walked the border for ever (filling memory); no footprint instead.
TEST(CameraRigTest, FootprintOfABadStepOrRangeIsEmpty) {
  const RigCamera c = Camera(45);
  EXPECT_TRUE(GroundFootprint(c, 0.0).empty());
  EXPECT_TRUE(GroundFootprint(c, -16.0).empty());
  EXPECT_TRUE(GroundFootprint(c, std::nan("")).empty());
  EXPECT_TRUE(GroundFootprint(c, 16.0, 0.0).empty());
  EXPECT_TRUE(GroundFootprint(c, 16.0, std::nan("")).empty());
  EXPECT_FALSE(GroundFootprint(c, 16.0, 4.0).empty());
}

TEST(CameraRigTest, FootprintIsAheadOfTheVehicleAndBounded) {
  const RigCamera c = Camera(45);
  const auto poly = GroundFootprint(c);
  ASSERT_GT(poly.size(), 50u);
  for (const Vec2d& p : poly) {
    EXPECT_GT(p.x(), 0.2);
    EXPECT_LT((p - Vec2d(0.2, 0)).norm(), 15.0 + 1e-9);
  }
  // Nearest ground seen: the bottom image row. Its angle below the optical axis is atan(240/600).
  double nearest = 1e9;
  for (const Vec2d& p : poly) nearest = std::min(nearest, p.x());
  const double angle = DegToRad(45.0) + std::atan(240.0 / 600.0);
  EXPECT_NEAR(nearest, 0.2 + 1.0 / std::tan(angle), 0.02);
}

}  // namespace
}  // namespace idi::rmp
