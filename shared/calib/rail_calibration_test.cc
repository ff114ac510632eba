#include "shared/calib/rail_calibration.h"

#include <gtest/gtest.h>

#include "shared/calib/calib_test_util.h"
#include "shared/calib/evaluation.h"

namespace idi::calib {
namespace {

using testing::PerturbedArm;

constexpr std::array<double, 4> kTruePsi = {5654.0, 3.0, -2.0, 0.0002};

// Readings where both arms aim exactly at points (R1 frame) from random rail positions.
std::vector<RailReading> ExactRailData(const ArmModel& a1, const ArmModel& a2, const std::vector<Vec3d>& points, int n,
                                       unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> rail(0.0, 1500.0);
  std::vector<RailReading> out;
  PlanOptions po;
  po.min_length_mm = 1500;
  const Rigid3d r1_from_r2 = Rail1FromRail2(kTruePsi.data());
  for (int i = 0; i < n; ++i) {
    const Vec3d p = points[static_cast<std::size_t>(i) % points.size()];
    RailReading r;
    r.rail1_mm = rail(rng);
    r.rail2_mm = rail(rng);
    const Vec3d p1 = RailFromBase(a1.rail.value(kPhiL), a1.rail.value(kPhiM), r.rail1_mm).Inverse() * p;
    const Vec3d p2 = (r1_from_r2 * RailFromBase(a2.rail.value(kPhiL), a2.rail.value(kPhiM), r.rail2_mm)).Inverse() * p;
    po.seed = seed + static_cast<unsigned>(i);
    const auto q1 = PlanAimConfigurations(a1.robot, a1.laser, p1, 1, Rx130JointLimits(), po);
    const auto q2 = PlanAimConfigurations(a2.robot, a2.laser, p2, 1, Rx130JointLimits(), po);
    IDI_CHECK(q1.ok() && q2.ok(), "test data: aiming failed");
    r.q1 = (*q1)[0];
    r.q2 = (*q2)[0];
    out.push_back(r);
  }
  return out;
}

const std::vector<Vec3d> kTwoWalls = {{1500, 4000, 500}, {3000, 4000, -600}, {4200, 4000, 900},
                                      {1800, -3500, 200}, {3500, -3500, -800}, {2800, 500, -1200}};
const std::vector<Vec3d> kOneWall = {{1500, 4000, 500}, {3000, 4000, -600}, {4200, 4000, 900}, {2200, 4000, -200}};

TEST(RailCalibrationTest, ExactDataRecoversPsiFromAClosedFormStart) {
  const ArmModel a1 = PerturbedArm(21), a2 = PerturbedArm(22);
  const auto data = ExactRailData(a1, a2, kTwoWalls, 60, 5);
  RailCalibrationOptions o;
  const auto r = CalibrateRail(data, a1, a2, o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  for (std::size_t k = 0; k < 4; ++k) EXPECT_NEAR(r->psi.value(k), kTruePsi[k], k == 3 ? 1e-9 : 1e-6) << k;
  // The closed-form start is already close: within a millimetre and a hundredth of a degree.
  for (std::size_t k = 0; k < 3; ++k) EXPECT_NEAR(r->start_psi[k], kTruePsi[k], 1.0);
  EXPECT_NEAR(r->start_psi[3], kTruePsi[3], DegToRad(0.01));
  EXPECT_LT(r->rms_distance_mm, 1e-6);
  EXPECT_TRUE(r->outliers.empty());
  // Evaluation (§5.4.4): with the calibrated psi the transferred lines meet robot 2's point.
  std::array<double, 4> psi;
  for (std::size_t k = 0; k < 4; ++k) psi[k] = r->psi.value(k);
  const auto held = ExactRailData(a1, a2, {{2500, 4000, 0}}, 20, 99);
  const auto good = RailTransferSpread(held, a1, a2, psi);
  const auto nominal = RailTransferSpread(held, a1, a2, NominalPsi());
  ASSERT_TRUE(good.ok() && nominal.ok());
  EXPECT_LT(good->mean_mm, 1e-5);
  EXPECT_GT(nominal->mean_mm, 1.0);
}

// An arm's own uncertainty carried into psi's: with only arm 1's a3 uncertain (0.1 mm), each psi
// parameter's variance is the readings' own (a priori) plus (dpsi/da3 * 0.1 mm)^2, where dpsi/da3 is
// how far psi moves when the same readings are solved with a3 off by 0.05 mm.
TEST(RailCalibrationTest, TheArmsCovarianceIsCarriedIntoPsisStd) {
  ArmModel a1 = PerturbedArm(21);
  const ArmModel a2 = PerturbedArm(22);
  const auto data = ExactRailData(a1, a2, kTwoWalls, 60, 5);
  const std::size_t a3 = *a1.robot.Find("a3");
  const double sigma = 0.1, delta = 0.05;
  a1.covariance = Eigen::MatrixXd::Zero(kArmModelParamCount, kArmModelParamCount);
  ArmModel a2_cov = a2;
  a2_cov.covariance = Eigen::MatrixXd::Zero(kArmModelParamCount, kArmModelParamCount);
  a1.covariance(static_cast<Eigen::Index>(a3), static_cast<Eigen::Index>(a3)) = sigma * sigma;
  const auto r = CalibrateRail(data, a1, a2_cov, {});
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_TRUE(r->arms_uncertainty_included);
  ArmModel shifted = a1;
  shifted.robot.set_value(a3, a1.robot.value(a3) + delta);
  const auto moved = CalibrateRail(data, shifted, a2, {});
  ASSERT_TRUE(moved.ok());
  EXPECT_FALSE(moved->arms_uncertainty_included);
  const auto prior = RailCovarianceAt(data, a1, a2, kTruePsi, {});
  ASSERT_TRUE(prior.ok());
  for (std::size_t k = 0; k < 4; ++k) {
    const double slope = (moved->psi.value(k) - r->psi.value(k)) / delta;
    const double expected =
        (*prior)(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(k)) + slope * sigma * slope * sigma;
    EXPECT_NEAR(r->psi.stddev(k) * r->psi.stddev(k), expected, 0.03 * expected) << k;
  }
  // psi_x moves with a3 about one for one: the arm's length error is the far arm's offset along the rail.
  EXPECT_GT(r->psi.stddev(kPsiX), 0.5 * sigma);
}

TEST(RailCalibrationTest, PointsOnOneWallConfoundPsiZAndPsiAlpha) {
  const ArmModel a1 = PerturbedArm(23), a2 = PerturbedArm(24);
  RailNoiseModel noise;
  const auto two = RailCovarianceAt(ExactRailData(a1, a2, kTwoWalls, 60, 6), a1, a2, kTruePsi, noise);
  const auto one = RailCovarianceAt(ExactRailData(a1, a2, kOneWall, 60, 6), a1, a2, kTruePsi, noise);
  ASSERT_TRUE(two.ok() && one.ok());
  auto corr = [](const Eigen::Matrix4d& c) { return c(kPsiZ, kPsiAlpha) / std::sqrt(c(kPsiZ, kPsiZ) * c(kPsiAlpha, kPsiAlpha)); };
  EXPECT_GT(std::abs(corr(*one)), 0.95);
  EXPECT_LT(std::abs(corr(*two)), 0.9);
  EXPECT_GT((*one)(kPsiZ, kPsiZ), 4.0 * (*two)(kPsiZ, kPsiZ));
}

// Readings that all aim at one point cannot determine every psi: those the analysis names
// undetermined get an infinite std in the result (before, the pseudo-inverse's finite value).
TEST(RailCalibrationTest, UndeterminedPsiHaveNoFiniteStd) {
  const ArmModel a1 = PerturbedArm(23), a2 = PerturbedArm(24);
  const auto data = ExactRailData(a1, a2, {kTwoWalls[0]}, 40, 8);
  const auto r = CalibrateRail(data, a1, a2, {});
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_FALSE(r->identifiability.undetermined.empty()) << r->Summary();
  for (const int k : r->identifiability.undetermined) {
    EXPECT_TRUE(std::isinf(r->psi.stddev(static_cast<std::size_t>(k)))) << k;
  }
}

// The minimum number of readings holds for the readings kept: six of 25 readings with robot 2's rail
// reading 30 mm off are left out, and the 19 kept are under the 20 needed.
TEST(RailCalibrationTest, TooFewReadingsLeftAfterTheOutliersIsAFailure) {
  const ArmModel a1 = PerturbedArm(25), a2 = PerturbedArm(26);
  auto data = ExactRailData(a1, a2, kTwoWalls, 25, 7);
  for (int i = 0; i < 6; ++i) data[static_cast<std::size_t>(3 * i + 1)].rail2_mm += 30.0;
  const auto r = CalibrateRail(data, a1, a2, {});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition) << r.status().ToString();
  EXPECT_NE(r.status().message().find("6 readings were left out as outliers"), std::string::npos)
      << r.status().message();
}

// The joint calibration's start results must be complete and of the data given: an empty start, or
// one whose outliers name readings the data do not have, is refused (before: a throw from an empty
// parameter set, or a write past the end of the outlier flags).
TEST(RailCalibrationTest, JointCalibrationRefusesStartsOfOtherData) {
  const ArmModel a1 = PerturbedArm(25), a2 = PerturbedArm(26);
  const Vec3d point(500, 4000, 200);
  const RobotCalibrationData d1 = testing::ExactRobotData(a1, point, 1000.0, 70, 3);
  const RobotCalibrationData d2 = testing::ExactRobotData(a2, point, 1000.0, 70, 4);
  const auto rail = ExactRailData(a1, a2, kTwoWalls, 25, 7);
  RobotCalibrationResult s1, s2;
  s1.params = s2.params = PackRobotCalibration(a1.robot, a1.laser, point, a1.rail);
  RailCalibrationResult sr;
  for (std::size_t k = 0; k < 4; ++k) sr.psi.set_value(k, kTruePsi[k]);
  auto run = [&] { return CalibrateArmsAndRail(d1, d2, rail, s1, s2, sr, {}, {}, {}).status(); };
  RobotCalibrationResult empty;
  EXPECT_EQ(CalibrateArmsAndRail(d1, d2, rail, empty, s2, sr, {}, {}, {}).status().code(),
            StatusCode::kInvalidArgument);
  s2.outliers.push_back({});
  s2.outliers.back().index = 140;  // d2 has 140 readings: 0 to 139
  Status st = run();
  EXPECT_EQ(st.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(st.message().find("robot 2's start names reading 141"), std::string::npos) << st.ToString();
  s2.outliers.clear();
  sr.outliers = {25};
  st = run();
  EXPECT_EQ(st.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(st.message().find("the rail's start names reading 26"), std::string::npos) << st.ToString();
}

TEST(RailCalibrationTest, TooFewOrNanReadingsAreRefused) {
  const ArmModel a1 = PerturbedArm(25), a2 = PerturbedArm(26);
  auto data = ExactRailData(a1, a2, kTwoWalls, 19, 7);
  EXPECT_EQ(CalibrateRail(data, a1, a2, {}).status().code(), StatusCode::kInvalidArgument);
  data = ExactRailData(a1, a2, kTwoWalls, 25, 7);
  data[3].rail2_mm = std::nan("");
  data[3].row = 5;
  const auto r = CalibrateRail(data, a1, a2, {});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("line 5"), std::string::npos);
}

}  // namespace
}  // namespace idi::calib
