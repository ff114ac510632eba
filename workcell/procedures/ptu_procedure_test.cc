#include "workcell/procedures/ptu_procedure.h"

#include <gtest/gtest.h>

#include <chrono>

#include "workcell/procedures/ptu_twin.h"

namespace idi::workcell {
namespace {

// A smaller run than the real procedure (fewer candidates and held-out poses) to stay fast.
PtuProcedureOptions SmallPtuRun(PtuTwin& twin) {
  PtuProcedureOptions o;
  o.robot = twin.arm_model();
  o.approx_point_mm = twin.approx_point_in_base();
  o.plan.candidates = 150;
  o.plan.validation_poses = 30;
  return o;
}

TEST(PtuProcedure, CalibratesTheTwinEndToEnd) {
  PtuTwinOptions to;
  to.seed = 4;
  PtuTwin twin(to);
  ASSERT_TRUE(twin.AimLaser().ok());
  const auto truth_point = twin.true_point_in_base();
  ASSERT_TRUE(truth_point.has_value());
  // The operator's idea of the point is off by centimetres (nominal laser arm, approximate wall).
  EXPECT_GT((twin.approx_point_in_base() - *truth_point).norm(), 5.0);
  PtuDevices dev = twin.Devices();
  const auto r = RunPtuCalibrationProcedure(dev, SmallPtuRun(twin));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_GE(r->survey.size(), 30u);
  EXPECT_EQ(r->calibration.size(), 120u);
  EXPECT_EQ(r->validation.size(), 60u);
  EXPECT_EQ(r->result.rejected, 0);
  EXPECT_LT((r->result.point_mm - *truth_point).norm(), 0.5) << r->Summary();
  EXPECT_LE(r->validation_errors.rms_px, 1.2 * to.spot_noise_px) << r->Summary();
  // The recorded PTU readings are the units' own (quantised) positions, inside their range.
  for (const auto& o : r->calibration) EXPECT_TRUE(calib::PtuRange{}.Contains(o.pan_rad, o.tilt_rad));
  EXPECT_FALSE(r->Summary().empty());
}

TEST(PtuProcedure, ASecondSpotInAnImageStopsTheRun) {
  PtuTwinOptions to;
  to.seed = 5;
  to.second_spot_image = 3;
  PtuTwin twin(to);
  ASSERT_TRUE(twin.AimLaser().ok());
  PtuDevices dev = twin.Devices();
  const auto r = RunPtuCalibrationProcedure(dev, SmallPtuRun(twin));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("2 spots in one image"), std::string::npos) << r.status().message();
}

TEST(PtuProcedure, AMissingSpotInTheCalibrationPassStopsTheRun) {
  PtuTwinOptions to;
  to.seed = 5;
  to.missing_spot_image = 100;  // after the survey's 60 images: in the calibration pass
  PtuTwin twin(to);
  ASSERT_TRUE(twin.AimLaser().ok());
  PtuDevices dev = twin.Devices();
  const auto r = RunPtuCalibrationProcedure(dev, SmallPtuRun(twin));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("the spot is missing"), std::string::npos) << r.status().message();
  EXPECT_NE(r.status().message().find("PTU calibration images: pose"), std::string::npos) << r.status().message();
}

TEST(PtuProcedure, MissingDevicesAreReported) {
  PtuDevices none;
  PtuProcedureOptions o;
  const auto r = RunPtuCalibrationProcedure(none, o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
}

// The realistic path: each image rendered (walls, the spot, optics, sensor noise) and the spot found
// by the feature detector through hal::CameraDevice. Fewer poses to keep the test fast.
TEST(PtuProcedure, RenderedImagesThroughTheSpotDetector) {
  PtuTwinOptions to;
  to.seed = 6;
  to.mode = PtuSpotMode::kImage;
  PtuTwin twin(to);
  ASSERT_TRUE(twin.AimLaser().ok());
  PtuDevices dev = twin.Devices();
  PtuProcedureOptions o = SmallPtuRun(twin);
  o.survey_poses = 20;
  o.survey_candidates = 40;
  o.plan.poses = 30;
  o.plan.candidates = 60;
  o.plan.validation_poses = 10;
  const auto r = RunPtuCalibrationProcedure(dev, o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const auto truth_point = twin.true_point_in_base();
  ASSERT_TRUE(truth_point.has_value());
  EXPECT_LT((r->result.point_mm - *truth_point).norm(), 1.0) << r->Summary();
  // The detector's centroid on a rendered spot is far better than the 0.2 px of the geometric mode.
  EXPECT_LT(r->validation_errors.rms_px, 0.2) << r->Summary();
}

}  // namespace
}  // namespace idi::workcell
