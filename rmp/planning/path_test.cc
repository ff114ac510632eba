#include "rmp/planning/path.h"

#include <gtest/gtest.h>

#include <cmath>

namespace idi::rmp {
namespace {

TEST(CornerGeometryTest, CutAndRadiusAreInverse) {
  for (double turn_deg : {10.0, 45.0, 90.0, 120.0, 150.0}) {
    const double turn = turn_deg * kPi / 180.0;
    EXPECT_NEAR(CornerCut(RadiusForCut(0.03, turn), turn), 0.03, 1e-12) << turn_deg;
  }
  // 90 deg: cut = r (sqrt(2) - 1); 120 deg: cut = r.
  EXPECT_NEAR(CornerCut(1.0, kPi / 2), std::sqrt(2.0) - 1.0, 1e-12);
  EXPECT_NEAR(CornerCut(1.0, 2 * kPi / 3), 1.0, 1e-12);
}

TEST(SmoothPathTest, RoundsARightAngleWithTheRequestedArc) {
  const std::vector<Vec2d> l = {{0, 0}, {2, 0}, {2, 2}};
  const SmoothPath path = SmoothPath::Build(l, {0.2});
  ASSERT_FALSE(path.empty());
  ASSERT_EQ(path.radii().size(), 1u);
  EXPECT_NEAR(path.radii()[0], 0.2, 1e-12);
  // Length: two legs shortened by the tangent (r tan 45 = r) plus a quarter circle.
  EXPECT_NEAR(path.length(), 4.0 - 0.4 + 0.2 * kPi / 2, 1e-9);
  // Closest approach to the vertex is the corner cut.
  double min_d = 1e9;
  for (double s = 0; s <= path.length(); s += 1e-3) min_d = std::min(min_d, (path.At(s).xy - Vec2d(2, 0)).norm());
  EXPECT_NEAR(min_d, CornerCut(0.2, kPi / 2), 1e-4);
  // Heading continuous, curvature +1/r (left turn) on the arc.
  double prev = path.At(0).heading;
  for (double s = 0; s <= path.length(); s += 1e-3) {
    const PathPoint p = path.At(s);
    EXPECT_LT(std::abs(WrapAngle(p.heading - prev)), 0.01);
    prev = p.heading;
  }
  EXPECT_NEAR(path.At(1.8 + 0.1).curvature, 5.0, 1e-9);
  EXPECT_NEAR(path.At(path.length()).xy.x(), 2.0, 1e-9);
  EXPECT_NEAR(path.At(path.length()).xy.y(), 2.0, 1e-9);
}

TEST(SmoothPathTest, ProjectionGivesSignedLateralErrorAndHeadingError) {
  const SmoothPath path = SmoothPath::Build({{0, 0}, {2, 0}, {2, -2}}, {0.3});  // right turn
  const PathProjection left = path.Project({1.0, 0.05}, 0.1);
  EXPECT_NEAR(left.s, 1.0, 1e-9);
  EXPECT_NEAR(left.lateral_m, 0.05, 1e-9);
  EXPECT_NEAR(left.heading_error, 0.1, 1e-9);
  // On the arc (a right turn: centre at (1.7, -0.3)); a point on the outer side is to the left.
  const Vec2d centre(1.7, -0.3);
  const Vec2d mid = centre + 0.35 * Vec2d(std::cos(kPi / 4), std::sin(kPi / 4));
  const PathProjection on_arc = path.Project(mid, -kPi / 4);
  EXPECT_NEAR(on_arc.lateral_m, 0.05, 1e-9);
  EXPECT_NEAR(on_arc.heading_error, 0.0, 1e-9);
  EXPECT_LT(path.At(on_arc.s).curvature, 0.0);
}

TEST(SmoothPathTest, ShrinksCornersToFitShortLegs) {
  // Short segments (a curve made of 10 cm pieces): each corner may use at most half of each leg.
  std::vector<Vec2d> pts;
  for (int i = 0; i <= 8; ++i) pts.emplace_back(std::cos(i * 0.2) , std::sin(i * 0.2));
  const SmoothPath path = SmoothPath::Build(pts, std::vector<double>(pts.size() - 2, 10.0));
  for (std::size_t i = 0; i < path.radii().size(); ++i) {
    const double leg = (pts[1] - pts[0]).norm();
    EXPECT_LE(path.radii()[i] * std::tan(0.1), 0.5 * leg + 1e-9);
  }
  // The smoothed path stays within the corner cut of the polyline.
  for (double s = 0; s <= path.length(); s += 0.01) EXPECT_LT(DistanceToPolyline(pts, path.At(s).xy), 0.01);
}

TEST(SimplifyPolylineTest, KeepsCornersDropsCollinearPoints) {
  std::vector<Vec2d> pts;
  for (int i = 0; i <= 100; ++i) pts.emplace_back(i * 0.01, 0.0);
  for (int i = 1; i <= 100; ++i) pts.emplace_back(1.0, i * 0.01);
  const auto simple = SimplifyPolyline(pts, 0.002);
  ASSERT_EQ(simple.size(), 3u);
  EXPECT_NEAR((simple[1] - Vec2d(1, 0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(PolylineLength(simple), 2.0, 1e-12);
}

}  // namespace
}  // namespace idi::rmp
