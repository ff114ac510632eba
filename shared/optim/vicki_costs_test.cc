#include "shared/optim/vicki_costs.h"

#include <gtest/gtest.h>

#include <functional>
#include <random>

namespace idi::optim {
namespace {

// A robot, laser and rail somewhat off nominal, as a calibration would see them.
struct Fixture {
  ParamSet robot = Rx130Nominal();
  ParamSet laser = LaserNominal();
  std::array<double, 2> phi{0.01, -0.004};
  std::array<double, 4> psi{5654.0, 3.0, -2.0, 0.0003};
  Joints q = JointsFromDeg({12, -35, 70, 20, 40, -30});
  Fixture() {
    std::mt19937 rng(7);
    std::normal_distribution<double> n(0.0, 1.0);
    for (std::size_t i = 0; i < robot.size(); ++i) {
      robot.set_value(i, robot.value(i) + (robot.spec(i).unit == Unit::kDegree ? 0.002 : 0.5) * n(rng));
    }
    for (std::size_t i = 0; i < laser.size(); ++i) {
      laser.set_value(i, (laser.spec(i).unit == Unit::kDegree ? 0.01 : 1.0) * n(rng));
    }
  }
};

// Central differences of f over the values x (in place), column by column.
Eigen::MatrixXd NumericJacobian(double* x, int n, int m, const std::function<Eigen::VectorXd()>& f, double h) {
  Eigen::MatrixXd j(m, n);
  for (int k = 0; k < n; ++k) {
    const double x0 = x[k];
    x[k] = x0 + h;
    const Eigen::VectorXd fp = f();
    x[k] = x0 - h;
    const Eigen::VectorXd fm = f();
    x[k] = x0;
    j.col(k) = (fp - fm) / (2 * h);
  }
  return j;
}

TEST(VickiCostsTest, AimResidualIsEq42NormalisedDistance) {
  Fixture fx;
  const Line3d line = LaserLineInBase(fx.robot.data(), fx.laser.data(), fx.q.data());
  const Vec3d point = line.PointAt(3000.0) + Vec3d(0.3, -0.2, 0.1);
  AimEvaluation e;
  ASSERT_TRUE(EvaluateAim(fx.robot.data(), fx.laser.data(), fx.q, point, &e));
  EXPECT_NEAR(e.r.norm(), DistancePointToLine(line, point) / ProjectOntoLine(line, point), 1e-15);
  EXPECT_NEAR(e.length_mm, ProjectOntoLine(line, point), 1e-9);
  // Behind the laser: refused.
  EXPECT_FALSE(EvaluateAim(fx.robot.data(), fx.laser.data(), fx.q, line.PointAt(-100.0), &e));
}

TEST(VickiCostsTest, AimJacobianMatchesCentralDifferences) {
  Fixture fx;
  const Line3d line = LaserLineInBase(fx.robot.data(), fx.laser.data(), fx.q.data());
  Vec3d point = line.PointAt(4000.0) + Vec3d(2.0, 1.0, -1.0);
  AimEvaluation e;
  ASSERT_TRUE(EvaluateAim(fx.robot.data(), fx.laser.data(), fx.q, point, &e));
  auto r_of = [&]() -> Eigen::VectorXd {
    AimEvaluation x;
    EXPECT_TRUE(EvaluateAim(fx.robot.data(), fx.laser.data(), fx.q, point, &x));
    return x.r;
  };
  const Eigen::MatrixXd jr = NumericJacobian(fx.robot.data(), 18, 2, r_of, 1e-6);
  const Eigen::MatrixXd jl = NumericJacobian(fx.laser.data(), 4, 2, r_of, 1e-6);
  const Eigen::MatrixXd jq = NumericJacobian(fx.q.data(), 6, 2, r_of, 1e-7);
  const Eigen::MatrixXd jp = NumericJacobian(point.data(), 3, 2, r_of, 1e-3);
  EXPECT_LT((jr - e.d_chain.leftCols<18>()).cwiseAbs().maxCoeff(), 1e-9) << jr << "\n\n" << e.d_chain.leftCols<18>();
  EXPECT_LT((jl - e.d_chain.middleCols<4>(18)).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((jq - e.d_chain.middleCols<6>(22)).cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_LT((jp - e.d_point).cwiseAbs().maxCoeff(), 1e-11);
}

TEST(VickiCostsTest, AimResidualBlocksIncludingTheDirectionAndOffset) {
  Fixture fx;
  const Line3d line = LaserLineInBase(fx.robot.data(), fx.laser.data(), fx.q.data());
  std::array<double, 3> p{0, 0, 0};
  const Vec3d target = line.PointAt(3500.0);
  const double offset = -1000.0;
  const Vec3d p0 = target - offset * RailDirectionInBase(fx.phi[0], fx.phi[1]) + Vec3d(0.5, 0.2, -0.3);
  p = {p0.x(), p0.y(), p0.z()};
  const Eigen::Matrix2d w = Eigen::Matrix2d::Identity() * 1e4;
  const AimResidual res(fx.q, offset, w);
  std::vector<const double*> params{fx.robot.data(), fx.laser.data(), p.data(), fx.phi.data()};
  Eigen::Vector2d r;
  std::array<double, 2 * 18> j0{};
  std::array<double, 2 * 4> j1{};
  std::array<double, 2 * 3> j2{};
  std::array<double, 2 * 2> j3{};
  std::array<double*, 4> jac{j0.data(), j1.data(), j2.data(), j3.data()};
  ASSERT_TRUE(res.Evaluate(params.data(), r.data(), jac.data()));
  auto r_of = [&]() -> Eigen::VectorXd {
    Eigen::Vector2d x;
    EXPECT_TRUE(res.Evaluate(params.data(), x.data(), nullptr));
    return x;
  };
  const Eigen::MatrixXd jphi = NumericJacobian(fx.phi.data(), 2, 2, r_of, 1e-7);
  const Eigen::MatrixXd jp = NumericJacobian(p.data(), 3, 2, r_of, 1e-3);
  for (int i = 0; i < 2; ++i) {
    for (int k = 0; k < 2; ++k) EXPECT_NEAR(j3[static_cast<std::size_t>(i * 2 + k)], jphi(i, k), 1e-6 * std::abs(jphi(i, k)) + 1e-8);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(j2[static_cast<std::size_t>(i * 3 + k)], jp(i, k), 1e-7);
  }
  // d r / d offset by differencing two residuals with offsets 1 mm apart.
  const AimResidual res_plus(fx.q, offset + 1e-3, w), res_minus(fx.q, offset - 1e-3, w);
  Eigen::Vector2d rp, rm;
  ASSERT_TRUE(res_plus.Evaluate(params.data(), rp.data(), nullptr));
  ASSERT_TRUE(res_minus.Evaluate(params.data(), rm.data(), nullptr));
  EXPECT_LT(((rp - rm) / 2e-3 - res.DerivativeWrtOffset(params.data())).norm(), 1e-7);
}

TEST(VickiCostsTest, ArmLinesInRail1AgreeWithEquations33To35) {
  Fixture fx;
  const std::array<double, 2> phi2{-0.01, 0.0017};
  const Joints q2 = JointsFromDeg({-20, -50, 95, -10, 60, 15});
  const Line3d l1 = LaserLineInBase(fx.robot.data(), fx.laser.data(), fx.q.data());
  const Line3d l2 = LaserLineInBase(fx.robot.data(), fx.laser.data(), q2.data());
  const Rigid3d r1_from_b1 = RailFromBase(fx.phi[0], fx.phi[1], 300.0);
  const Rigid3d r1_from_b2 = Rail1FromRail2(fx.psi.data()) * RailFromBase(phi2[0], phi2[1], 750.0);
  const LineJacobian a = ArmLineInRail1(fx.robot.data(), fx.laser.data(), fx.phi.data(), 300.0, fx.q, nullptr, kArm1Columns);
  const LineJacobian b = ArmLineInRail1(fx.robot.data(), fx.laser.data(), phi2.data(), 750.0, q2, fx.psi.data(), kArm2Columns);
  EXPECT_LT((a.origin - r1_from_b1 * l1.origin).norm(), 1e-9);
  EXPECT_LT((a.direction - r1_from_b1.RotateVector(l1.direction)).norm(), 1e-12);
  EXPECT_LT((b.origin - r1_from_b2 * l2.origin).norm(), 1e-9);
  EXPECT_LT((b.direction - r1_from_b2.RotateVector(l2.direction)).norm(), 1e-12);
}

TEST(VickiCostsTest, RailResidualsMatchCentralDifferences) {
  Fixture fx;
  ParamSet robot2 = fx.robot;
  ParamSet laser2 = fx.laser;
  std::array<double, 2> phi2{-0.01, 0.0017};
  const Joints q2 = JointsFromDeg({-160, -50, 95, -10, 60, 15});
  // Robot 2 aims roughly at the same region; the lines are skew, which is all the residual needs.
  const RailArmsResidual full(fx.q, 200.0, q2, 400.0, 0.05);
  std::vector<double*> blocks{fx.psi.data(), fx.robot.data(), fx.laser.data(), fx.phi.data(), robot2.data(), laser2.data(), phi2.data()};
  std::vector<const double*> params(blocks.begin(), blocks.end());
  const std::array<int, 7> sizes{4, 18, 4, 2, 18, 4, 2};
  std::vector<std::vector<double>> jstore;
  std::vector<double*> jac;
  for (int s : sizes) jstore.emplace_back(static_cast<std::size_t>(s), 0.0);
  for (auto& v : jstore) jac.push_back(v.data());
  double r = 0;
  ASSERT_TRUE(full.Evaluate(params.data(), &r, jac.data()));
  auto r_of = [&]() -> Eigen::VectorXd {
    Eigen::VectorXd x(1);
    EXPECT_TRUE(full.Evaluate(params.data(), x.data(), nullptr));
    return x;
  };
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    const Eigen::MatrixXd num = NumericJacobian(blocks[b], sizes[b], 1, r_of, b == 0 ? 1e-4 : 1e-5);
    for (int k = 0; k < sizes[b]; ++k) {
      EXPECT_NEAR(jstore[b][static_cast<std::size_t>(k)], num(0, k), 1e-5 * std::abs(num(0, k)) + 1e-6) << "block " << b << " col " << k;
    }
  }
  // The psi-only residual with precomputed lines gives the same value and psi derivatives.
  const LineJacobian a = ArmLineInRail1(fx.robot.data(), fx.laser.data(), fx.phi.data(), 200.0, fx.q, nullptr, kArm1Columns);
  const Line3d l2 = LaserLineInBase(robot2.data(), laser2.data(), q2.data());
  const Rigid3d r2_from_b2 = RailFromBase(phi2[0], phi2[1], 400.0);
  const RailResidual rail({a.origin, a.direction}, {r2_from_b2 * l2.origin, r2_from_b2.RotateVector(l2.direction)}, 0.05);
  double r2 = 0;
  std::array<double, 4> jpsi{};
  double* jp = jpsi.data();
  const double* pp = fx.psi.data();
  ASSERT_TRUE(rail.Evaluate(&pp, &r2, &jp));
  EXPECT_NEAR(r2, r, 1e-9 * std::max(1.0, std::abs(r)));
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(jpsi[static_cast<std::size_t>(k)], jstore[0][static_cast<std::size_t>(k)], 1e-9 * std::max(1.0, std::abs(jpsi[static_cast<std::size_t>(k)])));
}

TEST(VickiCostsTest, NoiseCovarianceScalesWithLengthAndEncoders) {
  Fixture fx;
  const Line3d line = LaserLineInBase(fx.robot.data(), fx.laser.data(), fx.q.data());
  AimEvaluation e;
  ASSERT_TRUE(EvaluateAim(fx.robot.data(), fx.laser.data(), fx.q, line.PointAt(5000.0), &e));
  AimNoiseModel spot_only;
  const Eigen::Matrix2d c = AimNoiseCovariance(e, spot_only);
  EXPECT_NEAR(c(0, 0), std::pow(0.05 / 5000.0, 2), 1e-18);
  // A plane normal to the beam gives the same; an oblique plane less along one axis.
  spot_only.plane_normal = line.direction;
  EXPECT_NEAR(AimNoiseCovariance(e, spot_only)(1, 1), c(1, 1), 1e-18);
  AimNoiseModel encoders;
  encoders.spot_sigma_mm = 0.0;
  encoders.joint_sigma_rad = EncoderRoundingSigmaRad();
  const Eigen::Matrix2d ce = AimNoiseCovariance(e, encoders);
  EXPECT_GT(ce.trace(), 0.0);
  EXPECT_LT(std::sqrt(ce.trace()) * 5000.0, 0.01);  // encoder rounding: well under 10 um on the wall
}

}  // namespace
}  // namespace idi::optim
