#include "rmp/track/polygon.h"

#include <gtest/gtest.h>

namespace idi::rmp {
namespace {

TEST(PointInPolygonTest, Square) {
  const std::vector<Vec2d> sq = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  EXPECT_TRUE(PointInPolygon(sq, {0.5, 0.5}));
  EXPECT_FALSE(PointInPolygon(sq, {1.5, 0.5}));
  EXPECT_FALSE(PointInPolygon(sq, {0.5, -0.01}));
}

// A camera footprint seen from the side can be concave: the notch of this U is outside.
TEST(PointInPolygonTest, ConcaveNotchIsOutside) {
  const std::vector<Vec2d> u = {{0, 0}, {3, 0}, {3, 2}, {2, 2}, {2, 1}, {1, 1}, {1, 2}, {0, 2}};
  EXPECT_TRUE(PointInPolygon(u, {0.5, 1.5}));
  EXPECT_TRUE(PointInPolygon(u, {2.5, 1.5}));
  EXPECT_TRUE(PointInPolygon(u, {1.5, 0.5}));
  EXPECT_FALSE(PointInPolygon(u, {1.5, 1.5}));
}

TEST(PointInPolygonTest, DegeneratePolygonsContainNothing) {
  EXPECT_FALSE(PointInPolygon({}, {0, 0}));
  EXPECT_FALSE(PointInPolygon({{0, 0}}, {0, 0}));
  EXPECT_FALSE(PointInPolygon({{-1, -1}, {1, 1}}, {0, 0}));
}

}  // namespace
}  // namespace idi::rmp
