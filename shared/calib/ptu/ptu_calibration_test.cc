#include "shared/calib/ptu/ptu_calibration.h"

#include <gtest/gtest.h>

#include <random>

#include "shared/calib/ptu/ptu_planning.h"
#include "shared/calib/ptu/ptu_simulation.h"

namespace idi::calib {
namespace {

// A small, fast data set: 60 planned poses from 120 candidates, 20 held-out.
PtuSyntheticData MakePtuData(uint64_t seed, double noise_px, const PtuTruthOptions& truth = {},
                             double margin_px = 80) {
  PtuSyntheticOptions o;
  o.seed = seed;
  o.noise_px = noise_px;
  o.truth = truth;
  o.plan.candidates = 120;
  o.plan.validation_poses = 20;
  o.plan.margin_px = margin_px;
  auto d = SimulatePtuDataset(o);
  IDI_CHECK(d.ok(), d.status().ToString());
  return *d;
}

double PtuParamError(const PtuCameraModel& est, const PtuCameraModel& truth, std::size_t k) {
  return k < est.ptu.size() ? est.ptu.value(k) - truth.ptu.value(k)
                            : est.intrinsics.value(k - est.ptu.size()) - truth.intrinsics.value(k - est.ptu.size());
}
double PtuParamStd(const PtuCameraModel& est, std::size_t k) {
  return k < est.ptu.size() ? est.ptu.stddev(k) : est.intrinsics.stddev(k - est.ptu.size());
}

TEST(PtuCalibration, RecoversTheTruthExactlyFromNoiseFreeData) {
  const PtuSyntheticData d = MakePtuData(3, 0.0);
  const auto r = CalibratePtu(d.calibration, {});
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_TRUE(r->gauge.empty()) << r->Summary();  // the model is minimal: no direction is invisible
  EXPECT_LT((r->point_mm - d.point_mm).norm(), 1e-5);
  for (std::size_t cam = 0; cam < 2; ++cam) {
    const PtuCameraCalibration& c = r->cameras[cam];
    EXPECT_EQ(c.side, d.truth[cam].side);
    EXPECT_LT(c.rms_px, 1e-6);
    for (std::size_t k = 0; k < kPtuParamCount + 4; ++k) {
      // 1e-6 of a millimetre or a radian (1e-4 px for fx..cy).
      EXPECT_NEAR(PtuParamError(c.model, d.truth[cam], k), 0, k < kPtuParamCount ? 1e-6 : 1e-4)
          << PtuCameraParameterNames(c.side)[k];
    }
  }
}

TEST(PtuCalibration, NoisySpotsMeetTheAcceptanceAndTheStdIsHonest) {
  const double noise = 0.2;
  const PtuSyntheticData d = MakePtuData(5, noise);
  const auto r = CalibratePtu(d.calibration, {});
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->rejected, 0);
  EXPECT_LT((r->point_mm - d.point_mm).norm(), 0.5);
  EXPECT_NEAR(std::sqrt(r->variance_factor), noise, 0.05);
  const auto v = ValidatePtu(*r, d.validation);
  ASSERT_TRUE(v.ok()) << v.status().ToString();
  EXPECT_LE(v->rms_px, 1.2 * noise);
  EXPECT_GE(v->rms_px, 0.8 * noise);  // held-out spots carry their own noise
  // Every estimate within 4.5 reported std of the truth.
  for (std::size_t cam = 0; cam < 2; ++cam) {
    const PtuCameraCalibration& c = r->cameras[cam];
    for (std::size_t k = 0; k < kPtuParamCount + 4; ++k) {
      const double sd = PtuParamStd(c.model, k);
      ASSERT_TRUE(std::isfinite(sd) && sd > 0) << PtuCameraParameterNames(c.side)[k];
      EXPECT_LT(std::abs(PtuParamError(c.model, d.truth[cam], k)), 4.5 * sd) << PtuCameraParameterNames(c.side)[k];
    }
    // k1, k2 not estimated: held at their start values, no std.
    EXPECT_TRUE(std::isnan(c.model.intrinsics.stddev(kK1)));
  }
  for (int i = 0; i < 3; ++i) {
    EXPECT_LT(std::abs(r->point_mm(i) - d.point_mm(i)), 4.5 * r->point_std_mm(i));
  }
}

TEST(PtuCalibration, AWrongSpotDoesNotPullTheFit) {
  const PtuSyntheticData d = MakePtuData(5, 0.2);
  const auto clean = CalibratePtu(d.calibration, {});
  ASSERT_TRUE(clean.ok());
  std::vector<PtuObservation> bad = d.calibration;
  // Three images where the detector latched on to something else: 8 to 60 px away.
  bad[4].pixel_px += Vec2d(60, -20);
  bad[17].pixel_px += Vec2d(-8, 3);
  bad[41].pixel_px += Vec2d(15, 25);
  const auto r = CalibratePtu(bad, {});
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->rejected, 3);
  for (std::size_t cam = 0; cam < 2; ++cam) {
    const PtuCameraCalibration& c = r->cameras[cam];
    const PtuCameraCalibration& ref = clean->cameras[cam];
    for (std::size_t k = 0; k < kPtuParamCount + 4; ++k) {
      // Losing three of 120 observations moves a parameter by a fraction of its std, not more.
      EXPECT_LT(std::abs(PtuParamError(c.model, ref.model, k)), 0.6 * PtuParamStd(ref.model, k))
          << PtuCameraParameterNames(c.side)[k];
    }
  }
  int flagged = 0;
  for (const auto& c : r->cameras) {
    for (bool in : c.inlier) flagged += in ? 0 : 1;
  }
  EXPECT_EQ(flagged, 3);
}

// With a real lens in the twin, the distortion-free model of §6.2.2 leaves a systematic error; adding
// k1, k2 brings the held-out error back to the spot noise.
TEST(PtuCalibration, LensDistortionNeedsK1K2) {
  PtuTruthOptions truth;
  truth.k1 = -0.2;
  truth.k2 = 0.15;
  const double noise = 0.2;
  // Spots planned anywhere in the image (those the as-designed model misplaces off the image are lost).
  const PtuSyntheticData d = MakePtuData(9, noise, truth, 20);
  PtuCalibrationOptions without;
  const auto r0 = CalibratePtu(d.calibration, {}, without);
  ASSERT_TRUE(r0.ok()) << r0.status().ToString();
  const auto v0 = ValidatePtu(*r0, d.validation);
  ASSERT_TRUE(v0.ok());
  PtuCalibrationOptions with;
  with.estimate_distortion = true;
  const auto r1 = CalibratePtu(d.calibration, {}, with);
  ASSERT_TRUE(r1.ok()) << r1.status().ToString();
  const auto v1 = ValidatePtu(*r1, d.validation);
  ASSERT_TRUE(v1.ok());
  EXPECT_GT(v0->rms_px, 2.0 * noise) << "the distortion-free model should not fit a distorting lens";
  EXPECT_GT(r0->cameras[0].rms_px, 1.5 * noise);
  EXPECT_LE(v1->rms_px, 1.2 * noise);
  for (std::size_t cam = 0; cam < 2; ++cam) {
    const ParamSet& in = r1->cameras[cam].model.intrinsics;
    EXPECT_LT(std::abs(in.value(kK1) - truth.k1), 4.5 * in.stddev(kK1));
    EXPECT_LT(std::abs(in.value(kK2) - truth.k2), 4.5 * in.stddev(kK2));
  }
}

TEST(PtuCalibration, OneCameraAloneAndSeparatePointsWork) {
  const PtuSyntheticData d = MakePtuData(4, 0.2);
  const auto left = CalibratePtu(SelectCamera(d.calibration, BiclopsSide::kLeft), {});
  ASSERT_TRUE(left.ok()) << left.status().ToString();
  ASSERT_EQ(left->cameras.size(), 1u);
  EXPECT_EQ(left->cameras[0].side, BiclopsSide::kLeft);
  EXPECT_LT((left->point_mm - d.point_mm).norm(), 1.5);
  PtuCalibrationOptions separate;
  separate.shared_point = false;
  const auto both = CalibratePtu(d.calibration, {}, separate);
  ASSERT_TRUE(both.ok()) << both.status().ToString();
  ASSERT_EQ(both->cameras.size(), 2u);
  EXPECT_NE(both->cameras[0].point_mm, both->cameras[1].point_mm);
  for (const auto& c : both->cameras) EXPECT_LT((c.point_mm - d.point_mm).norm(), 1.5);
}

// When the arm only translates (the TCF orientation never changes), moving the point and both PTU
// bases by the same vector changes no image: three invisible directions, found and fixed.
TEST(PtuCalibration, FindsAndFixesTheGaugeOfAnArmThatNeverTurns) {
  PtuSyntheticData d = MakePtuData(6, 0.0);
  const PtuCameraModel nominal_left = PtuCameraModel::Nominal(BiclopsSide::kLeft);
  std::vector<PtuObservation> obs;
  const Rigid3d turn = BaseFromTcf(d.calibration[0].tcf);
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> u(-400, 400);
  std::uniform_real_distribution<double> ux(20, 620), uy(20, 460);
  // Same orientation everywhere: pan and tilt aimed anew for each translated pose.
  for (int i = 0; static_cast<int>(obs.size()) < 60 && i < 1000; ++i) {
    Rigid3d pose = turn;
    pose.translation += Vec3d(u(rng), u(rng), u(rng));
    PtuObservation o;
    o.camera = BiclopsSide::kLeft;
    o.tcf = TcfPoseFromTransform(pose);
    o.pixel_px = Vec2d(ux(rng), uy(rng));
    const auto aim = AimPtuAt(d.truth[0], o.tcf, d.point_mm, o.pixel_px, PtuRange{});
    if (!aim) continue;
    o.pan_rad = (*aim)[0];
    o.tilt_rad = (*aim)[1];
    obs.push_back(o);
  }
  ASSERT_EQ(obs.size(), 60u);
  PtuCalibrationOptions options;
  options.initial_point_mm = d.point_mm + Vec3d(20, 20, -20);
  const auto r = CalibratePtu(obs, {nominal_left}, options);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->gauge.size(), 3u) << r->Summary();
  for (const PtuGaugeFix& g : r->gauge) {
    EXPECT_TRUE(g.fixed_parameter == "left.tx" || g.fixed_parameter == "left.ty" || g.fixed_parameter == "left.tz")
        << g.fixed_parameter << ": " << g.combination;
    EXPECT_NE(g.combination.find("point."), std::string::npos) << g.combination;
  }
  EXPECT_LT(r->cameras[0].rms_px, 1e-4) << r->Summary();
}

TEST(PtuCalibration, BadDataGivesAClearMessage) {
  const PtuSyntheticData d = MakePtuData(3, 0.2);
  {  // too few poses
    std::vector<PtuObservation> few(d.calibration.begin(), d.calibration.begin() + 20);
    const auto r = CalibratePtu(few, {});
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("too few poses"), std::string::npos) << r.status().message();
  }
  {  // fewer residuals than parameters with the per-camera minimum lowered to 1 (before: an SVD read
     // past its singular values)
    std::vector<PtuObservation> few(d.calibration.begin(), d.calibration.begin() + 10);
    PtuCalibrationOptions o;
    o.min_observations_per_camera = 1;
    const auto r = CalibratePtu(few, {}, o);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("too few observations"), std::string::npos) << r.status().message();
  }
  {  // a pose outside the PTU's range
    std::vector<PtuObservation> obs = d.calibration;
    obs[7].tilt_rad = DegToRad(40.0);
    obs[7].source_line = 9;
    PtuCalibrationOptions o;
    o.source = "obs.csv";
    const auto r = CalibratePtu(obs, {}, o);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), StatusCode::kOutOfRange);
    EXPECT_NE(r.status().message().find("obs.csv:9: tilt = 40"), std::string::npos) << r.status().message();
  }
  {  // two spots in one image
    std::vector<PtuObservation> obs = d.calibration;
    PtuObservation twin = obs[11];
    twin.pixel_px += Vec2d(40, 0);
    obs.push_back(twin);
    const auto r = CalibratePtu(obs, {});
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("second spot"), std::string::npos) << r.status().message();
  }
  {  // non-finite value
    std::vector<PtuObservation> obs = d.calibration;
    obs[2].pixel_px.x() = std::numeric_limits<double>::quiet_NaN();
    EXPECT_FALSE(CalibratePtu(obs, {}).ok());
  }
  {  // an unknown parameter to hold fixed
    PtuCalibrationOptions o;
    o.fixed = {"left.nonsense"};
    const auto r = CalibratePtu(d.calibration, {}, o);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("left.nonsense"), std::string::npos);
  }
  {  // validation of a camera that was not calibrated
    const auto left = CalibratePtu(SelectCamera(d.calibration, BiclopsSide::kLeft), {});
    ASSERT_TRUE(left.ok());
    EXPECT_FALSE(ValidatePtu(*left, d.validation).ok());
    EXPECT_TRUE(ValidatePtu(*left, SelectCamera(d.validation, BiclopsSide::kLeft)).ok());
  }
}

// A fit stopped at the iteration limit is usable but says so: the result's termination, and a warning
// in the summary (before, nothing told it from a converged fit).
TEST(PtuCalibration, AFitStoppedAtTheIterationLimitSaysSo) {
  const PtuSyntheticData d = MakePtuData(5, 0.2);
  const auto done = CalibratePtu(d.calibration, {});
  ASSERT_TRUE(done.ok()) << done.status().ToString();
  EXPECT_EQ(done->termination, "convergence");
  EXPECT_EQ(done->Summary().find("warning"), std::string::npos) << done->Summary();
  PtuCalibrationOptions o;
  o.max_iterations = 1;
  const auto cut = CalibratePtu(d.calibration, {}, o);
  ASSERT_TRUE(cut.ok()) << cut.status().ToString();
  EXPECT_EQ(cut->termination, "no_convergence");
  EXPECT_NE(cut->Summary().find("warning: the last solve stopped before converging"), std::string::npos)
      << cut->Summary();
}

TEST(PtuCalibration, HeldFixedParametersKeepTheirStartValues) {
  const PtuSyntheticData d = MakePtuData(8, 0.2);
  PtuCalibrationOptions o;
  o.fixed = {"right.theta_x", "left.fy"};
  const auto r = CalibratePtu(d.calibration, {}, o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const PtuCameraModel nominal_right = PtuCameraModel::Nominal(BiclopsSide::kRight);
  const PtuCameraModel nominal_left = PtuCameraModel::Nominal(BiclopsSide::kLeft);
  EXPECT_EQ(r->Camera(BiclopsSide::kRight)->model.ptu.value(kPtuThetaX), nominal_right.ptu.value(kPtuThetaX));
  EXPECT_EQ(r->Camera(BiclopsSide::kLeft)->model.intrinsics.value(kFy), nominal_left.intrinsics.value(kFy));
  EXPECT_NE(std::find(r->held_fixed.begin(), r->held_fixed.end(), "left.fy"), r->held_fixed.end());
}

TEST(PtuTriangulation, ParallelRaysAreRejected) {
  const PtuCameraModel m = PtuCameraModel::Nominal(BiclopsSide::kLeft);
  std::vector<PtuObservation> obs(2);
  for (auto& o : obs) o.pixel_px = Vec2d(319.5, 239.5);
  obs[1].tcf.x_mm = 0;  // identical rays
  const auto r = TriangulatePtuPoint(obs, {m});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition);
}

}  // namespace
}  // namespace idi::calib
