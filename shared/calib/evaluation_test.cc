#include "shared/calib/evaluation.h"

#include <gtest/gtest.h>

namespace idi::calib {
namespace {

TEST(EvaluationTest, LinesThroughOnePointHaveNoSpread) {
  const Vec3d p(100, 4000, 50);
  std::vector<Line3d> lines;
  for (int i = 0; i < 10; ++i) {
    const Vec3d o(50.0 * i, 100.0 * (i % 3), 700.0 + 20.0 * i);
    lines.push_back(LineThrough(o, p));
  }
  const auto s = LaserSpread(lines);
  ASSERT_TRUE(s.ok());
  EXPECT_LT((s->center - p).norm(), 1e-9);
  EXPECT_LT(s->max_mm, 1e-9);
  EXPECT_EQ(s->projected.size(), 10u);
}

TEST(EvaluationTest, RadiiAboutAReferencePoint) {
  const Vec3d p(0, 5000, 0);
  // Two lines along +y offset by 3 mm and 4 mm: radii 3 and 4 on the plane through p.
  const std::vector<Line3d> lines = {{Vec3d(3, 0, 0), Vec3d::UnitY()}, {Vec3d(0, 0, -4), Vec3d::UnitY()}};
  const auto s = SpreadAbout(lines, p);
  ASSERT_TRUE(s.ok());
  EXPECT_NEAR(s->max_mm, 4.0, 1e-12);
  EXPECT_NEAR(s->mean_mm, 3.5, 1e-12);
  EXPECT_NEAR(s->std_mm, 0.5, 1e-12);
  EXPECT_FALSE(LaserSpread({lines[0]}).ok());
}

}  // namespace
}  // namespace idi::calib
