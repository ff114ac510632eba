#include "shared/geometry/lines.h"

#include <gtest/gtest.h>

namespace idi {
namespace {

TEST(LinesTest, PointToLineDistance) {
  const Line3d z_axis{Vec3d::Zero(), Vec3d::UnitZ()};
  EXPECT_DOUBLE_EQ(DistancePointToLine(z_axis, Vec3d(3, 4, 100)), 5.0);
  EXPECT_DOUBLE_EQ(ProjectOntoLine(z_axis, Vec3d(3, 4, 100)), 100.0);
  EXPECT_TRUE(PerpendicularToLine(z_axis, Vec3d(3, 4, 100)).isApprox(Vec3d(3, 4, 0)));
}

TEST(LinesTest, SkewLinesDistanceAndClosestPoints) {
  // x axis and a line parallel to y through (0, 0, 2): distance 2, closest at both origins.
  const Line3d a{Vec3d::Zero(), Vec3d::UnitX()};
  const Line3d b{Vec3d(0, 5, 2), Vec3d::UnitY()};
  EXPECT_NEAR(DistanceBetweenLines(a, b), 2.0, 1e-12);
  const auto st = ClosestPointsBetweenLines(a, b);
  ASSERT_TRUE(st.has_value());
  EXPECT_NEAR(st->first, 0.0, 1e-12);
  EXPECT_NEAR(st->second, -5.0, 1e-12);
  const Line3d c{Vec3d(0, 1, 0), Vec3d::UnitX()};
  EXPECT_FALSE(ClosestPointsBetweenLines(a, c).has_value());
  EXPECT_NEAR(DistanceBetweenLines(a, c), 1.0, 1e-12);
}

TEST(LinesTest, PointClosestToRaysRecoversTheirMeetingPoint) {
  const Vec3d target(100, -50, 2000);
  std::vector<Line3d> rays;
  for (const Vec3d& o : {Vec3d(0, 0, 0), Vec3d(500, 0, 0), Vec3d(0, 400, 100)}) {
    rays.push_back(LineThrough(o, target));
  }
  const auto p = PointClosestToLines(rays);
  ASSERT_TRUE(p.has_value());
  EXPECT_LT((*p - target).norm(), 1e-8);
  EXPECT_FALSE(PointClosestToLines({rays[0]}).has_value());
}

TEST(LinesTest, TwoDimensionalLines) {
  const Line2d horizontal = Line2Through(Vec2d(0, 3), Vec2d(10, 3));
  const Line2d vertical = Line2Through(Vec2d(2, -1), Vec2d(2, 8));
  EXPECT_NEAR(std::abs(horizontal.offset), 3.0, 1e-12);
  EXPECT_NEAR(horizontal.SignedDistance(Vec2d(5, 3)), 0.0, 1e-12);
  const auto x = IntersectLines2(horizontal, vertical);
  ASSERT_TRUE(x.has_value());
  EXPECT_TRUE(x->isApprox(Vec2d(2, 3), 1e-12));
  EXPECT_FALSE(IntersectLines2(horizontal, Line2Through(Vec2d(0, 0), Vec2d(1, 0))).has_value());
}

TEST(LinesTest, LinePlaneIntersection) {
  const Plane3d wall{Vec3d::UnitX(), 3000.0};
  const Line3d laser{Vec3d(0, 0, 1000), Vec3d(1, 1, 0).normalized()};
  const auto s = IntersectLinePlane(laser, wall);
  ASSERT_TRUE(s.has_value());
  EXPECT_TRUE(laser.PointAt(*s).isApprox(Vec3d(3000, 3000, 1000), 1e-12));
}

}  // namespace
}  // namespace idi
