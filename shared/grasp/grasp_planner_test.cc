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

// A post as wide as the finger spacing (50 mm, like a bracket's leg), measured with a millimetre of error
// so its two wide faces come out shifted by 0.8 mm against each other: fingers 1 and 2 are centred on
// the far face's end edges, one of them just past it, and their pads (20 mm wide) still overlap it by
// about 10 mm. The grasp across the 16 mm thickness must be found, not refused because the ray through a
// pad's centre misses the face.
TEST(GraspPlannerTest, PostAsWideAsTheFingerSpacingIsGrippedAcrossItsThickness) {
  std::vector<Vec3d> post;
  for (double z : {0.0, 80.0}) {
    post.emplace_back(-25.4, 0.0, z);
    post.emplace_back(24.6, 0.0, z);
    post.emplace_back(25.4, 16.0, z);
    post.emplace_back(-24.6, 16.0, z);
  }
  const std::vector<std::pair<int, int>> edges = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                                  {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
  const auto plan = PlanTopGrasp(post, 0.0, {}, edges);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  EXPECT_NEAR(plan->width_mm, 16.0, 0.1);
  EXPECT_NEAR(std::abs(plan->world_from_grasp.rotation.col(0).y()), 1.0, 1e-3) << "closes across the thickness";
  EXPECT_LT(plan->centroid_offset_mm, 1.0);
}

// A bracket as the simulated day reconstructed it (seed 1, scene 2, the day's calibration; table top at
// z = 0): 9 of its 12 corners - the leg's far inner top corner, the far end of the leg's foot joint and
// one foot corner were not found - and the 10 edges between them. The leg is 64.6 mm wide, 12.6 mm
// thick and 76.6 mm tall. Its inner face is seen only at its near end, so the section through the leg is
// a thin triangle; the grasp is across the leg's thickness, thumb on its outer face. An eleventh edge,
// from the leg's top inner corner to the foot's far corner, joined two points that a hidden corner's
// image happened to align in two views (see ModelOptions::min_edge_spread_deg); with it, the leg's
// section becomes a ramp 45 deg off vertical and no grasp fits.
TEST(GraspPlannerTest, ReconstructedBracketMissingThreeCornersIsGrippedAcrossItsLeg) {
  const std::vector<Vec3d> points = {{-7.48, -26.61, 76.51},
                                     {22.78, 56.37, -0.01},
                                     {-7.60, -26.66, -0.02},
                                     {-3.20, -14.70, 12.46},
                                     {53.25, -48.61, -0.01},
                                     {-3.20, -14.76, 76.82},
                                     {53.27, -48.57, 76.57},
                                     {83.35, 34.38, 12.45},
                                     {22.51, 56.38, 12.44}};
  std::vector<std::pair<int, int>> edges = {{0, 2}, {0, 5}, {0, 6}, {1, 2}, {2, 4}, {3, 5}, {3, 8}, {4, 6}, {7, 8}};
  const auto plan = PlanTopGrasp(points, 0.0, {}, edges);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  EXPECT_NEAR(plan->width_mm, 12.6, 0.5) << "across the leg's thickness";
  const Vec2d outer_face = (points[6] - points[0]).head<2>().normalized();
  EXPECT_LT(std::abs(plan->world_from_grasp.rotation.col(0).head<2>().dot(outer_face)), 0.02)
      << "the grip axis is square to the leg's faces";
  EXPECT_GT(plan->thumb_contact.z(), 12.5) << "on the leg, above the foot";
  EXPECT_GT(plan->friction_margin_rad, DegToRad(5.0));

  edges.emplace_back(5, 7);  // the accidental edge
  EXPECT_EQ(PlanTopGrasp(points, 0.0, {}, edges).status().code(), StatusCode::kNotFound);
}

// A bracket as the twin's scan reconstructed it (seed 3, scene 9, true calibration; table top at z = 0):
// 6 of its 12 corners and 4 edges. One edge crosses the leg, so the section there is guessed from the
// segments between points below and above - inside a convex object, but across this L they span the
// open side, where there is nothing to push on. The planner had gripped it there, and the thumb met the
// real face 71 deg off and slipped. No finger goes on a guessed section: no grasp (the scan then takes
// more views, or reports that none fits).
TEST(GraspPlannerTest, NoFingerIsPlacedOnASectionGuessedFromSegmentsBetweenPoints) {
  const std::vector<Vec3d> bracket = {{0.41, 4.94, 84.35},
                                      {0.24, 5.01, 13.08},
                                      {107.10, 73.43, 13.02},
                                      {85.78, -15.33, 84.41},
                                      {82.68, -28.34, 0.06},
                                      {21.27, 93.78, 13.07}};
  const std::vector<std::pair<int, int>> edges = {{0, 1}, {0, 3}, {1, 5}, {2, 5}};
  EXPECT_EQ(PlanTopGrasp(bracket, 0.0, {}, edges).status().code(), StatusCode::kNotFound);
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

TEST(GraspPlannerTest, BracketWhoseLegWasSeenFromOneSideIsGraspedAcrossTheLeg) {
  // An L-bracket on the table (z = 0) as the scan reconstructed it: the foot's top corners, the leg's
  // outer face (four corners, its vertical edges) and the corner where the leg's inner face meets the
  // foot, but not the inner face itself. The leg is 13 mm thick and 65 mm wide; the foot reaches
  // 80 mm from it.
  const std::vector<Vec3d> points = {
      {29.7, 82.9, 12.5},   // 0: foot, far corner
      {4.0, 11.8, 12.6},    // 1: the leg's inner face meets the foot
      {-0.2, -0.1, 0.0},    // 2: leg, outer face, bottom
      {90.6, 61.3, 12.5},   // 3: foot, far corner
      {60.6, -22.1, 76.7},  // 4: leg, outer face, top
      {-0.1, 0.1, 76.6},    // 5: leg, outer face, top
      {60.8, -21.9, -0.2},  // 6: leg, outer face, bottom
  };
  const std::vector<std::pair<int, int>> edges = {{0, 1}, {0, 3}, {2, 5}, {2, 6}, {4, 5}, {4, 6}};
  const auto plan = PlanTopGrasp(points, 0.0, {}, edges);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  // Not the convex object the points would outline: the hand closes across the leg, the thumb on its
  // seen face, fingers 1 and 2 behind it (on the side of the foot), at the leg's thickness.
  EXPECT_EQ(plan->spread_rad, 0.0);
  EXPECT_NEAR(plan->width_mm, 12.8, 1.0);
  const Vec2d face = Vec2d(60.7, -22.0).normalized();
  const Vec2d thumb = plan->thumb_contact.head<2>();
  EXPECT_LT(std::abs(face.x() * thumb.y() - face.y() * thumb.x()), 1.0) << "the thumb is on the leg's seen face";
  const Vec2d axis = plan->world_from_grasp.rotation.col(0).head<2>();
  EXPECT_NEAR(std::abs(axis.dot(face)), 0.0, 0.01) << "the grip is across the leg";
  EXPECT_GT(axis.dot(Vec2d(29.7, 82.9)), 0.0) << "fingers 1 and 2 on the foot's side";
  // In the leg, 25 mm below its top (well above the foot).
  EXPECT_NEAR(plan->thumb_contact.z(), 76.7 - 25.0, 0.1);
}

// The alternatives for an arm that cannot reach the best grasp: best first, the first one PlanTopGrasp's,
// no grasp twice. On the box the two-on-one grasp across its 80 mm side has two orientations (thumb on
// either face) of equal quality, then come worse ones (across the 160 mm side, off-centre).
TEST(GraspPlannerTest, AlternativesComeBestFirstAndDistinct) {
  const auto box = BoxPoints(Vec3d(500, 200, 0), Vec3d(160, 80, 60), DegToRad(30.0));
  const auto best = PlanTopGrasp(box, 0.0);
  const auto plans = PlanTopGrasps(box, 0.0, {}, {}, 6);
  ASSERT_TRUE(best.ok() && plans.ok());
  ASSERT_GE(plans->size(), 3u);
  EXPECT_LE(plans->size(), 6u);
  EXPECT_TRUE(plans->front().world_from_grasp.translation.isApprox(best->world_from_grasp.translation));
  EXPECT_TRUE(plans->front().world_from_grasp.rotation.isApprox(best->world_from_grasp.rotation));
  EXPECT_DOUBLE_EQ(plans->front().quality, best->quality);
  int across_narrow_side = 0;
  for (std::size_t i = 0; i < plans->size(); ++i) {
    const GraspPlan& p = (*plans)[i];
    if (i > 0) {
      EXPECT_LE(p.quality, (*plans)[i - 1].quality) << "plan " << i;
    }
    across_narrow_side += std::abs(p.width_mm - 80.0) < 1e-6 && p.centroid_offset_mm < 1e-6 ? 1 : 0;
    for (std::size_t j = 0; j < i; ++j) {
      const GraspPlan& q = (*plans)[j];
      const bool same = (p.world_from_grasp.translation - q.world_from_grasp.translation).norm() < 2.0 &&
                        p.world_from_grasp.rotation.col(0).dot(q.world_from_grasp.rotation.col(0)) > 0.999 &&
                        p.spread_rad == q.spread_rad;
      EXPECT_FALSE(same) << "plans " << j << " and " << i << " are one grasp";
    }
  }
  EXPECT_GE(across_narrow_side, 2) << "both orientations of the best grasp";
  EXPECT_EQ(PlanTopGrasps(box, 0.0, {}, {}, 1)->size(), 1u);
  EXPECT_EQ(PlanTopGrasps(box, 0.0, {}, {}, 0).status().code(), StatusCode::kInvalidArgument);
}

TEST(GraspPlannerTest, BadInput) {
  EXPECT_EQ(PlanTopGrasp({}, 0.0).status().code(), StatusCode::kInvalidArgument);
  auto pts = BoxPoints(Vec3d::Zero(), Vec3d(80, 60, 50), 0);
  pts[3].x() = NAN;
  EXPECT_EQ(PlanTopGrasp(pts, 0.0).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(PlanTopGrasp(BoxPoints(Vec3d::Zero(), Vec3d(80, 60, 5), 0), 0.0).status().code(), StatusCode::kNotFound);
  // A 10 mm high box: a NaN table height, or a NaN or negative clearance, turned the height and
  // clearance checks off, and the contacts came out below the table top (reported as a grasp).
  const auto flat = BoxPoints(Vec3d::Zero(), Vec3d(80, 60, 10), 0);
  EXPECT_EQ(PlanTopGrasp(flat, NAN).status().code(), StatusCode::kInvalidArgument);
  for (const double clearance : {static_cast<double>(NAN), -20.0}) {
    GraspOptions o;
    o.table_clearance_mm = clearance;
    EXPECT_EQ(PlanTopGrasp(flat, 0.0, o).status().code(), StatusCode::kInvalidArgument) << clearance;
  }
  GraspOptions o;
  o.hand.finger_reach_mm = INFINITY;
  EXPECT_EQ(PlanTopGrasp(flat, 0.0, o).status().code(), StatusCode::kInvalidArgument);
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
