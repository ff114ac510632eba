#include "shared/grasp/grasp_planner.h"

#include <gtest/gtest.h>

#include <random>

#include "shared/util/units.h"

namespace idi {
namespace {

std::vector<Vec3d> BoxPoints(const Vec3d& centre, const Vec3d& size, double yaw) {
  std::vector<Vec3d> pts;
  for (int k = 0; k < 8; ++k) {
    const Vec3d local(((k & 1) ? 0.5 : -0.5) * size.x(), ((k & 2) ? 0.5 : -0.5) * size.y(), (k & 4) ? size.z() : 0.0);
    pts.push_back(centre + RotZ(yaw) * local);
  }
  return pts;
}

TEST(GraspPlannerTest, BoxIsGraspedAcrossItsNarrowSideThroughTheCentre) {
  // 160 x 80 x 60 mm box turned 30 degrees: the hand closes across the 80 mm side.
  const double yaw = DegToRad(30.0);
  const auto plan = PlanTopGrasp(BoxPoints(Vec3d(500, 200, 0), Vec3d(160, 80, 60), yaw), 0.0);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  EXPECT_NEAR(plan->width_mm, 80.0, 1e-6);
  EXPECT_LT(plan->centroid_offset_mm, 1e-6);
  // The grip axis is the box's local y axis (either sign).
  const Vec3d grip_axis = plan->world_from_grasp.rotation.col(0);
  EXPECT_NEAR(std::abs(grip_axis.dot(RotZ(yaw) * Vec3d::UnitY())), 1.0, 1e-9);
  // Hand approaches from above; contacts 25 mm below the top; lift is straight up.
  EXPECT_TRUE(plan->world_from_grasp.rotation.col(2).isApprox(Vec3d(0, 0, -1)));
  EXPECT_NEAR(plan->thumb_contact.z(), 35.0, 1e-9);
  EXPECT_NEAR(plan->world_from_lift.translation.z() - plan->world_from_grasp.translation.z(), 150.0, 1e-9);
  EXPECT_GT(plan->friction_margin_rad, 0.3);
}

TEST(GraspPlannerTest, TooWideObjectIsRefused) {
  const auto plan = PlanTopGrasp(BoxPoints(Vec3d(0, 0, 0), Vec3d(300, 260, 50), 0.0), 0.0);
  EXPECT_EQ(plan.status().code(), StatusCode::kNotFound);
}

TEST(GraspPlannerTest, TriangularPrismTakesTheTripod) {
  // An equilateral triangular prism has no opposing faces, so two-on-one would need a friction cone
  // of 30 degrees; with mu = 0.2 (11 degrees) only the tripod, its fingers pushing straight onto the
  // three faces, holds it.
  std::vector<Vec3d> tri;
  for (int k = 0; k < 3; ++k) {
    const double a = 2 * kPi * k / 3;
    for (double z : {0.0, 50.0}) tri.emplace_back(60 * std::cos(a), 60 * std::sin(a), z);
  }
  GraspOptions opt;
  opt.friction = 0.2;
  const auto plan = PlanTopGrasp(tri, 0.0, opt);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  EXPECT_NEAR(plan->spread_rad, kPi / 3, 1e-12);
  EXPECT_NEAR(plan->friction_margin_rad, std::atan(0.2), 1e-6);  // pushes exactly along the normals
  EXPECT_LT(plan->centroid_offset_mm, 1e-9);
  // Nearly frictionless fingers cannot hold a box with a tripod or a pinch off its faces' normals,
  // but the two-on-one across parallel faces needs no friction at all.
  opt.friction = 0.01;
  const auto box = PlanTopGrasp(BoxPoints(Vec3d::Zero(), Vec3d(120, 70, 50), 0.3), 0.0, opt);
  ASSERT_TRUE(box.ok());
  EXPECT_EQ(box->spread_rad, 0.0);
}

TEST(GraspPlannerTest, CylinderApproximatedByManyPoints) {
  std::vector<Vec3d> cyl;
  for (int k = 0; k < 24; ++k) {
    const double a = 2 * kPi * k / 24;
    for (double z : {0.0, 120.0}) cyl.emplace_back(200 + 40 * std::cos(a), -100 + 40 * std::sin(a), z);
  }
  const auto plan = PlanTopGrasp(cyl, 0.0);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  EXPECT_NEAR(plan->width_mm, 80.0 * std::cos(kPi / 24), 1.0);
  EXPECT_LT(plan->centroid_offset_mm, 2.0);
}

// A triangular prism lying on the table (ridge along y, 70 mm up; base 100 x 120 mm): its long sides are
// the sloped roof, where a finger pushing horizontally slips. With the model's edges the planner sees the
// cross-section narrow towards the ridge and grasps the vertical triangular ends, closing along y; from
// the points alone it would take the narrower base width across the roof.
TEST(GraspPlannerTest, PrismIsGraspedOnItsVerticalEndsNotTheRoof) {
  const std::vector<Vec3d> p = {{-50, -60, 0}, {50, -60, 0}, {0, -60, 70}, {-50, 60, 0}, {50, 60, 0}, {0, 60, 70}};
  const std::vector<std::pair<int, int>> edges = {{0, 1}, {1, 2}, {2, 0}, {3, 4}, {4, 5}, {5, 3}, {0, 3}, {1, 4}, {2, 5}};
  const auto plan = PlanTopGrasp(p, 0.0, GraspOptions{}, edges);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  const Vec3d axis = plan->world_from_grasp.rotation.col(0);
  EXPECT_LT(std::abs(axis.x()), 0.1) << "the grip closes along the ridge, onto the vertical ends";
  EXPECT_NEAR(plan->width_mm, 120.0, 1.0);
  const auto blind = PlanTopGrasp(p, 0.0);
  ASSERT_TRUE(blind.ok());
  EXPECT_GT(std::abs(blind->world_from_grasp.rotation.col(0).x()), 0.9) << "points alone: across the roof";
  EXPECT_EQ(PlanTopGrasp(p, 0.0, GraspOptions{}, {{0, 9}}).status().code(), StatusCode::kInvalidArgument);
}

TEST(GraspPlannerTest, BadInput) {
  EXPECT_EQ(PlanTopGrasp({}, 0.0).status().code(), StatusCode::kInvalidArgument);
  auto pts = BoxPoints(Vec3d::Zero(), Vec3d(80, 60, 50), 0);
  pts[3].x() = NAN;
  EXPECT_EQ(PlanTopGrasp(pts, 0.0).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(PlanTopGrasp(BoxPoints(Vec3d::Zero(), Vec3d(80, 60, 5), 0), 0.0).status().code(), StatusCode::kNotFound);
}

TEST(GraspPlannerTest, ConvexHull) {
  const auto hull = ConvexHull2d({Vec2d(0, 0), Vec2d(2, 0), Vec2d(1, 1), Vec2d(2, 2), Vec2d(0, 2), Vec2d(1, 0)});
  ASSERT_EQ(hull.size(), 4u);
  double area = 0;
  for (std::size_t i = 0; i < hull.size(); ++i) {
    const Vec2d& a = hull[i];
    const Vec2d& b = hull[(i + 1) % hull.size()];
    area += a.x() * b.y() - a.y() * b.x();
  }
  EXPECT_NEAR(area / 2, 4.0, 1e-12);  // counter-clockwise, positive
}

}  // namespace
}  // namespace idi
