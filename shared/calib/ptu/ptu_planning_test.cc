#include "shared/calib/ptu/ptu_planning.h"

#include <gtest/gtest.h>

namespace idi::calib {
namespace {

TEST(AimPtuAt, PutsThePointOnTheTargetPixel) {
  const PtuCameraModel m = PtuCameraModel::Nominal(BiclopsSide::kRight);
  const Vec3d point(500, -3198, 1368);
  // An arm pose from which the right camera can see the point.
  PtuPlanOptions o;
  o.poses = o.candidates = 1;
  o.validation_poses = 0;
  o.margin_px = 200;
  const auto plan = PlanPtuAcquisition(Rx130Nominal(), Rx130JointLimits(),
                                       {PtuCameraModel::Nominal(BiclopsSide::kLeft), m}, point, o);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  const TcfPose tcf = plan->calibration[0].tcf;
  int solved = 0;
  for (const Vec2d& target : {Vec2d(319.5, 239.5), Vec2d(20, 30), Vec2d(600, 450), Vec2d(100, 400)}) {
    const auto aim = AimPtuAt(m, tcf, point, target, PtuRange{});
    if (!aim) continue;
    ++solved;
    EXPECT_TRUE(PtuRange{}.Contains((*aim)[0], (*aim)[1]));
    const auto px = m.Project(tcf, (*aim)[0], (*aim)[1], point);
    ASSERT_TRUE(px.has_value());
    EXPECT_LT((*px - target).norm(), 1e-4);
  }
  EXPECT_EQ(solved, 4);
  // A target the PTU cannot reach: the point straight along the pan axis (tilt would need ~90 deg).
  const Rigid3d base_from_0 = BaseFromTcf(tcf) * Translation(m.ptu.value(kPtuTx), m.ptu.value(kPtuTy),
                                                             m.ptu.value(kPtuTz)) *
                              RotZ(m.ptu.value(kPtuThetaZ));
  EXPECT_FALSE(AimPtuAt(m, tcf, base_from_0 * Vec3d(0, 0, 3000), Vec2d(319.5, 239.5), PtuRange{}).has_value());
}

TEST(PlanPtuAcquisition, KeepsInformativePosesWhereBothCamerasSeeThePoint) {
  const std::array<PtuCameraModel, 2> models = {PtuCameraModel::Nominal(BiclopsSide::kLeft),
                                                PtuCameraModel::Nominal(BiclopsSide::kRight)};
  const Vec3d point(700, -2148, 1254);
  PtuPlanOptions o;
  o.poses = 40;
  o.validation_poses = 10;
  o.candidates = 90;
  o.seed = 3;
  const ParamSet robot = Rx130Nominal();
  const JointLimits limits = Rx130JointLimits();
  const auto plan = PlanPtuAcquisition(robot, limits, models, point, o);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  EXPECT_EQ(plan->calibration.size(), 40u);
  EXPECT_EQ(plan->validation.size(), 10u);
  EXPECT_EQ(plan->candidates, 90);
  for (const auto* set : {&plan->calibration, &plan->validation}) {
    for (const PtuPlannedPose& p : *set) {
      EXPECT_TRUE(limits.Contains(p.q));
      const TcfPose tcf = TcfPoseFromTransform(Rx130BaseFromFlange(robot.data(), p.q.data()));
      EXPECT_NEAR((BaseFromTcf(tcf).translation - BaseFromTcf(p.tcf).translation).norm(), 0, 1e-9);
      for (std::size_t cam = 0; cam < 2; ++cam) {
        EXPECT_TRUE(o.range.Contains(p.pan_rad[cam], p.tilt_rad[cam]));
        const auto px = models[cam].Project(p.tcf, p.pan_rad[cam], p.tilt_rad[cam], point);
        ASSERT_TRUE(px.has_value());
        EXPECT_LT((*px - p.predicted_px[cam]).norm(), 1e-3);
        EXPECT_TRUE(models[cam].Camera().InImage(*px, o.margin_px - 1e-6));
      }
    }
  }
  // Every axis' extremes among the candidates are kept (persistent excitation).
  ASSERT_EQ(plan->coverage.size(), 10u);
  for (const PtuAxisCoverage& c : plan->coverage) {
    EXPECT_DOUBLE_EQ(c.min_deg, c.range_min_deg) << c.axis;
    EXPECT_DOUBLE_EQ(c.max_deg, c.range_max_deg) << c.axis;
  }
  EXPECT_TRUE(std::isfinite(plan->log_det));
  EXPECT_FALSE(plan->Summary().empty());
}

TEST(PlanPtuAcquisition, DOptimalBeatsTheFirstPoses) {
  const std::array<PtuCameraModel, 2> models = {PtuCameraModel::Nominal(BiclopsSide::kLeft),
                                                PtuCameraModel::Nominal(BiclopsSide::kRight)};
  const Vec3d point(700, -2148, 1254);
  PtuPlanOptions o;
  o.poses = 30;
  o.validation_poses = 0;
  o.candidates = 30;  // no choice: keeps all
  o.extremes_first = false;
  o.point_weight = 0;  // pure D-optimal
  const auto all = PlanPtuAcquisition(Rx130Nominal(), Rx130JointLimits(), models, point, o);
  ASSERT_TRUE(all.ok());
  o.candidates = 90;
  const auto chosen = PlanPtuAcquisition(Rx130Nominal(), Rx130JointLimits(), models, point, o);
  ASSERT_TRUE(chosen.ok());
  EXPECT_GT(chosen->log_det, all->log_det + 5);
}

TEST(PlanPtuAcquisition, FailsClearlyWhenTheSpotCannotBeSeen) {
  const std::array<PtuCameraModel, 2> models = {PtuCameraModel::Nominal(BiclopsSide::kLeft),
                                                PtuCameraModel::Nominal(BiclopsSide::kRight)};
  PtuPlanOptions o;
  o.poses = 10;
  o.validation_poses = 0;
  o.candidates = 10;
  o.max_draws = 50;
  o.min_distance_mm = 1e6;  // no camera is ever far enough
  const auto r = PlanPtuAcquisition(Rx130Nominal(), Rx130JointLimits(), models, Vec3d(700, -2148, 1254), o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("only 0 of 50 random arm poses"), std::string::npos) << r.status().message();
  o.candidates = 5;  // fewer candidates than poses
  EXPECT_EQ(PlanPtuAcquisition(Rx130Nominal(), Rx130JointLimits(), models, Vec3d::Zero(), o).status().code(),
            StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace idi::calib
