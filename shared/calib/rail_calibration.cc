#include "shared/calib/rail_calibration.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>
#include <utility>
#include <vector>

#include "shared/optim/vicki_costs.h"

namespace idi::calib {
namespace {

using optim::ArmLineInRail1;
using optim::LineDistance;
using optim::LineJacobian;

// Expected std of a reading's signed line distance: spot noise of both lasers (along the common
// normal), each rail position's repeatability and the encoder rounding of both arms, through the
// derivatives of the distance with respect to the rail positions and joints.
std::optional<double> ReadingSigma(const RailReading& r, const ArmModel& a1, const ArmModel& a2,
                                   const std::array<double, 4>& psi, const RailNoiseModel& n) {
  const LineJacobian la = ArmLineInRail1(a1.robot.data(), a1.laser.data(), a1.rail.data(), r.rail1_mm, r.q1, nullptr,
                                         optim::kArm1Columns);
  const LineJacobian lb = ArmLineInRail1(a2.robot.data(), a2.laser.data(), a2.rail.data(), r.rail2_mm, r.q2, psi.data(),
                                         optim::kArm2Columns);
  LineDistance d;
  if (!optim::EvaluateLineDistance(la, lb, &d)) return std::nullopt;
  double var = 2.0 * n.spot_sigma_mm * n.spot_sigma_mm;
  var += n.rail_sigma_mm * n.rail_sigma_mm *
         (d.d_a(optim::kArm1Columns.position) * d.d_a(optim::kArm1Columns.position) +
          d.d_b(optim::kArm2Columns.position) * d.d_b(optim::kArm2Columns.position));
  if (n.encoder_rounding) {
    const auto s = optim::EncoderRoundingSigmaRad();
    for (int j = 0; j < kRx130Joints; ++j) {
      const double sj = s[static_cast<std::size_t>(j)];
      var += sj * sj * (std::pow(d.d_a(optim::kArm1Columns.joints + j), 2) + std::pow(d.d_b(optim::kArm2Columns.joints + j), 2));
    }
  }
  return std::sqrt(var);
}

struct RailBuilt {
  optim::Problem problem;
  std::vector<std::size_t> reading;
};

void BuildRail(std::array<double, 4>& psi, const std::vector<RailReading>& readings, const ArmModel& a1,
               const ArmModel& a2, const std::vector<double>& sigma, const std::vector<bool>& active, optim::Loss loss,
               RailBuilt* b) {
  b->problem.AddParameterBlock(psi.data(), kRobotToRobotParamCount);
  for (std::size_t i = 0; i < readings.size(); ++i) {
    if (!active[i] || !(sigma[i] > 0)) continue;
    const RailReading& r = readings[i];
    b->problem.AddResidual(std::make_shared<optim::RailResidual>(ArmLineInRailFrame(a1, r.q1, r.rail1_mm),
                                                                 ArmLineInRailFrame(a2, r.q2, r.rail2_mm), sigma[i]),
                           {psi.data()}, loss);
    b->reading.push_back(i);
  }
}

// psi from pairs of the same points seen in R1 (p1) and in R2 turned by Rz(pi) (q): p1 = Rx(alpha) q + t
// (eq. 3.5), alpha from the y-z parts (2D Procrustes), t from the centroids.
std::array<double, 4> PsiFromPointPairs(const std::vector<Vec3d>& p1, const std::vector<Vec3d>& q) {
  Vec3d c1 = Vec3d::Zero(), c2 = Vec3d::Zero();
  for (std::size_t i = 0; i < p1.size(); ++i) {
    c1 += p1[i];
    c2 += q[i];
  }
  c1 /= static_cast<double>(p1.size());
  c2 /= static_cast<double>(q.size());
  double sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < p1.size(); ++i) {
    const Vec2d u(q[i].y() - c2.y(), q[i].z() - c2.z());
    const Vec2d v(p1[i].y() - c1.y(), p1[i].z() - c1.z());
    sxx += u.dot(v);
    sxy += u.x() * v.y() - u.y() * v.x();
  }
  const double alpha = std::atan2(sxy, sxx);
  const Vec3d t = c1 - RotX(alpha).rotation * c2;
  return {t.x(), t.y(), t.z(), alpha};
}

// Closed-form start. The readings are grouped by the point they aim at (their near-intersections with
// the initial psi lie within 100 mm of each other); each group's point is located from robot 1's lines
// alone in R1 and from robot 2's lines alone in R2 (§4.5.4's closest point), which needs no psi at
// all; psi then follows from the point pairs. Without two such groups, the per-reading near-
// intersections are used instead, a few times over.
std::array<double, 4> ClosedFormPsi(const std::vector<RailReading>& readings, const ArmModel& a1, const ArmModel& a2,
                                    std::array<double, 4> psi) {
  std::vector<Line3d> la, lb;
  for (const RailReading& r : readings) {
    la.push_back(ArmLineInRailFrame(a1, r.q1, r.rail1_mm));
    lb.push_back(ArmLineInRailFrame(a2, r.q2, r.rail2_mm));
  }
  auto near_points = [&](const std::array<double, 4>& ps, std::vector<Vec3d>* p1, std::vector<Vec3d>* p2,
                         std::vector<std::size_t>* index) {
    const Rigid3d r1_from_r2 = Rail1FromRail2(ps.data());
    for (std::size_t i = 0; i < readings.size(); ++i) {
      const Line3d b{r1_from_r2 * lb[i].origin, r1_from_r2.RotateVector(lb[i].direction)};
      const auto st = ClosestPointsBetweenLines(la[i], b, 1e-6);
      if (!st || !(st->first > 0) || !(st->second > 0)) continue;
      p1->push_back(la[i].PointAt(st->first));
      p2->push_back(RotZ(kPi).rotation * lb[i].PointAt(st->second));
      if (index) index->push_back(i);
    }
  };
  std::vector<Vec3d> m1, m2;
  std::vector<std::size_t> idx;
  near_points(psi, &m1, &m2, &idx);
  std::vector<std::vector<std::size_t>> groups;
  std::vector<Vec3d> group_seed;
  for (std::size_t k = 0; k < m1.size(); ++k) {
    std::size_t g = 0;
    while (g < groups.size() && (group_seed[g] - m1[k]).norm() > 100.0) ++g;
    if (g == groups.size()) {
      groups.emplace_back();
      group_seed.push_back(m1[k]);
    }
    groups[g].push_back(idx[k]);
  }
  std::vector<Vec3d> p1, q;
  for (const auto& g : groups) {
    if (g.size() < 3) continue;
    std::vector<Line3d> ga, gb;
    for (std::size_t i : g) {
      ga.push_back(la[i]);
      gb.push_back(lb[i]);
    }
    const auto pa = PointClosestToLines(ga);
    const auto pb = PointClosestToLines(gb);
    if (!pa || !pb) continue;
    p1.push_back(*pa);
    q.push_back(RotZ(kPi).rotation * *pb);
  }
  if (p1.size() >= 2) return PsiFromPointPairs(p1, q);
  for (int iter = 0; iter < 10 && m1.size() >= 3; ++iter) {
    psi = PsiFromPointPairs(m1, m2);
    m1.clear();
    m2.clear();
    near_points(psi, &m1, &m2, nullptr);
  }
  return psi;
}

}  // namespace

Line3d ArmLineInRailFrame(const ArmModel& arm, const Joints& q, double rail_mm) {
  const Line3d l = LaserLineInBase(arm.robot.data(), arm.laser.data(), q.data());
  const Rigid3d r_from_b = RailFromBase(arm.rail.value(kPhiL), arm.rail.value(kPhiM), rail_mm);
  return {r_from_b * l.origin, r_from_b.RotateVector(l.direction)};
}

std::array<double, kRobotToRobotParamCount> NominalPsi() { return {5650.0, 0.0, 0.0, 0.0}; }

Status RailNoiseModel::Check() const {
  if (!(spot_sigma_mm > 0) || !(rail_sigma_mm >= 0) || !std::isfinite(spot_sigma_mm) || !std::isfinite(rail_sigma_mm)) {
    return InvalidArgument("rail noise model: spot_sigma_mm must be > 0, rail_sigma_mm >= 0");
  }
  return Status::Ok();
}

Status RailCalibrationOptions::Check() const {
  IDI_RETURN_IF_ERROR(noise.Check());
  IDI_RETURN_IF_ERROR(solver.Check());
  IDI_RETURN_IF_ERROR(identifiability.Check());
  for (double v : initial_psi) {
    if (!std::isfinite(v)) return InvalidArgument("rail calibration: initial psi not finite");
  }
  if (min_readings_per_unknown < 1 || !(outlier_sigmas > 2) || max_outlier_rounds < 0) {
    return InvalidArgument("rail calibration: invalid options");
  }
  return Status::Ok();
}

Result<Eigen::Matrix4d> RailCovarianceAt(const std::vector<RailReading>& readings, const ArmModel& arm1,
                                         const ArmModel& arm2, const std::array<double, 4>& psi_in,
                                         const RailNoiseModel& noise) {
  IDI_RETURN_IF_ERROR(noise.Check());
  std::array<double, 4> psi = psi_in;
  std::vector<double> sigma(readings.size(), 0.0);
  for (std::size_t i = 0; i < readings.size(); ++i) sigma[i] = ReadingSigma(readings[i], arm1, arm2, psi, noise).value_or(0.0);
  RailBuilt b;
  BuildRail(psi, readings, arm1, arm2, sigma, std::vector<bool>(readings.size(), true), {}, &b);
  IDI_ASSIGN_OR_RETURN(const optim::DenseEvaluation ev, optim::EvaluateDense(b.problem));
  IDI_ASSIGN_OR_RETURN(const optim::CovarianceReport rep, optim::AnalyzeJacobian(ev.jacobian, 1.0));
  return Eigen::Matrix4d(rep.covariance);
}

Result<RailCalibrationResult> CalibrateRail(const std::vector<RailReading>& readings, const ArmModel& arm1,
                                            const ArmModel& arm2, const RailCalibrationOptions& o) {
  IDI_RETURN_IF_ERROR(o.Check());
  for (const ArmModel* a : {&arm1, &arm2}) {
    if (a->robot.size() != kRx130ParamCount || a->laser.size() != kLaserParamCount || a->rail.size() != kRailParamCount) {
      return InvalidArgument("rail calibration: each arm needs 18 robot, 4 laser and 2 rail parameters");
    }
  }
  const int needed = o.min_readings_per_unknown * kRobotToRobotParamCount;
  if (static_cast<int>(readings.size()) < needed) {
    return InvalidArgument("rail calibration: " + std::to_string(readings.size()) + " readings are too few: 4 unknowns need at least " +
                           std::to_string(needed));
  }
  for (std::size_t i = 0; i < readings.size(); ++i) {
    const RailReading& r = readings[i];
    bool finite = std::isfinite(r.rail1_mm) && std::isfinite(r.rail2_mm);
    for (int j = 0; j < kRx130Joints; ++j) finite = finite && std::isfinite(r.q1[static_cast<std::size_t>(j)]) && std::isfinite(r.q2[static_cast<std::size_t>(j)]);
    if (!finite) {
      return InvalidArgument("rail calibration: reading " + std::to_string(i + 1) +
                             (r.row > 0 ? " (line " + std::to_string(r.row) + ")" : "") + " has a value that is not a finite number");
    }
  }
  RailCalibrationResult out;
  std::array<double, 4> psi = ClosedFormPsi(readings, arm1, arm2, o.initial_psi);
  out.start_psi = psi;
  out.start = "closed form: each aimed point located by each arm alone, psi from the point pairs (2D Procrustes)";
  std::vector<double> sigma(readings.size(), 0.0);
  for (std::size_t i = 0; i < readings.size(); ++i) sigma[i] = ReadingSigma(readings[i], arm1, arm2, psi, o.noise).value_or(0.0);
  std::vector<bool> active(readings.size(), true);
  for (std::size_t i = 0; i < readings.size(); ++i) {
    if (!(sigma[i] > 0)) active[i] = false;  // parallel lasers: no information
  }
  auto residual_mm = [&](std::size_t i) {
    const Line3d a = ArmLineInRailFrame(arm1, readings[i].q1, readings[i].rail1_mm);
    const Line3d b2 = ArmLineInRailFrame(arm2, readings[i].q2, readings[i].rail2_mm);
    const Rigid3d t = Rail1FromRail2(psi.data());
    const Line3d b{t * b2.origin, t.RotateVector(b2.direction)};
    const auto st = ClosestPointsBetweenLines(a, b, 1e-9);
    return std::pair<double, double>(DistanceBetweenLines(a, b), st ? 0.5 * (st->first + st->second) : 0.0);
  };
  auto solve = [&](const optim::Loss& loss) -> Status {
    RailBuilt b;
    BuildRail(psi, readings, arm1, arm2, sigma, active, loss, &b);
    IDI_ASSIGN_OR_RETURN(out.summary, optim::SolveLevenbergMarquardt(b.problem, o.solver));
    out.cost_per_iteration.insert(out.cost_per_iteration.end(), out.summary.cost_per_iteration.begin(),
                                  out.summary.cost_per_iteration.end());
    return Status::Ok();
  };
  // Whether the last solve was not plain least squares over the readings now active: the robust one,
  // or one before the last round left readings out.
  bool refit = false;
  for (int round = 0; round <= o.max_outlier_rounds; ++round) {
    IDI_RETURN_IF_ERROR(solve(round == 0 ? optim::Loss{optim::LossKind::kCauchy, 3.0} : optim::Loss{}));
    std::vector<double> w;
    for (std::size_t i = 0; i < readings.size(); ++i) {
      if (active[i]) w.push_back(residual_mm(i).first / sigma[i]);
    }
    std::vector<double> sorted = w;
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
    const double robust = sorted[sorted.size() / 2] / 0.6745;  // |N(0,1)| has median 0.6745
    bool changed = false;
    for (std::size_t i = 0; i < readings.size(); ++i) {
      if (!active[i]) continue;
      const double d = residual_mm(i).first;
      if (d / sigma[i] > o.outlier_sigmas * robust && d > o.outlier_floor_mm) {
        active[i] = false;
        out.outliers.push_back(static_cast<int>(i));
        changed = true;
      }
    }
    refit = changed || round == 0;
    if (!changed && round > 0) break;
  }
  // The readings kept must still meet the minimum (outlier rounds may have left out many).
  const int kept = static_cast<int>(std::count(active.begin(), active.end(), true));
  if (kept < needed) {
    return FailedPrecondition(
        "rail calibration: " + std::to_string(out.outliers.size()) + " readings were left out as outliers (and " +
        std::to_string(static_cast<int>(readings.size()) - kept - static_cast<int>(out.outliers.size())) +
        " carry no information); the " + std::to_string(kept) + " kept are too few (" + std::to_string(needed) +
        " needed)");
  }
  // psi is the least-squares fit of the readings kept.
  if (refit) IDI_RETURN_IF_ERROR(solve(optim::Loss{}));
  RailBuilt b;
  BuildRail(psi, readings, arm1, arm2, sigma, active, {}, &b);
  IDI_ASSIGN_OR_RETURN(const optim::DenseEvaluation ev, optim::EvaluateDense(b.problem));
  out.variance_factor = optim::VarianceFactor(ev.residuals, kRobotToRobotParamCount);
  IDI_ASSIGN_OR_RETURN(out.identifiability, optim::AnalyzeJacobian(ev.jacobian, out.variance_factor, o.identifiability));
  double s2 = 0, n2 = 0;
  for (std::size_t i = 0; i < readings.size(); ++i) {
    if (!active[i]) continue;
    const auto [d, len] = residual_mm(i);
    s2 += d * d;
    n2 += len > 0 ? (d / len) * (d / len) : 0.0;
    ++out.readings_used;
  }
  out.rms_distance_mm = std::sqrt(s2 / std::max(1, out.readings_used));
  out.rms_normalized = std::sqrt(n2 / std::max(1, out.readings_used));
  Eigen::Matrix4d cov = out.identifiability.covariance;  // scaled by sigma0^2
  for (int k = 0; k < kRobotToRobotParamCount; ++k)
    out.std_given_arms[static_cast<std::size_t>(k)] = out.identifiability.stddev(k);
  if (arm1.covariance.rows() == kArmModelParamCount && arm2.covariance.rows() == kArmModelParamCount &&
      out.identifiability.rank == kRobotToRobotParamCount) {
    // psi minimises |r(psi, arms)|^2, so dpsi/darms = -(Jp^T Jp)^-1 Jp^T Ja (whitened residuals), and the
    // arms' covariance adds A Ca A^T. Ja by central differences of the residuals at the solution.
    const Eigen::MatrixXd& jp = ev.jacobian;
    Eigen::MatrixXd ja(jp.rows(), 2 * kArmModelParamCount);
    for (int a = 0; a < 2; ++a) {
      const ArmModel& base = a == 0 ? arm1 : arm2;
      for (int j = 0; j < kArmModelParamCount; ++j) {
        const double h = std::max(1e-9, 1e-2 * std::sqrt(std::max(0.0, base.covariance(j, j))));
        Eigen::VectorXd r[2];
        for (int side = 0; side < 2; ++side) {
          ArmModel m = base;
          const double step = side == 0 ? h : -h;
          const auto u = static_cast<std::size_t>(j);
          if (j < kRx130ParamCount) {
            m.robot.set_value(u, m.robot.value(u) + step);
          } else if (j < kRx130ParamCount + kLaserParamCount) {
            m.laser.set_value(u - kRx130ParamCount, m.laser.value(u - kRx130ParamCount) + step);
          } else {
            const std::size_t v = u - kRx130ParamCount - kLaserParamCount;
            m.rail.set_value(v, m.rail.value(v) + step);
          }
          std::array<double, 4> p = psi;
          RailBuilt bj;
          BuildRail(p, readings, a == 0 ? m : arm1, a == 0 ? arm2 : m, sigma, active, {}, &bj);
          IDI_ASSIGN_OR_RETURN(const optim::DenseEvaluation e, optim::EvaluateDense(bj.problem));
          r[side] = e.residuals;
        }
        if (r[0].size() != jp.rows() || r[1].size() != jp.rows())
          return Internal("rail calibration: residual count changed");
        ja.col(a * kArmModelParamCount + j) = (r[0] - r[1]) / (2.0 * h);
      }
    }
    const Eigen::Matrix4d jtj = jp.transpose() * jp;
    const Eigen::MatrixXd sens = jtj.ldlt().solve(jp.transpose() * ja);
    Eigen::MatrixXd ca = Eigen::MatrixXd::Zero(2 * kArmModelParamCount, 2 * kArmModelParamCount);
    ca.topLeftCorner(kArmModelParamCount, kArmModelParamCount) = arm1.covariance;
    ca.bottomRightCorner(kArmModelParamCount, kArmModelParamCount) = arm2.covariance;
    const Eigen::Matrix4d added = sens * ca * sens.transpose();
    if (added.allFinite()) {
      // The readings' own noise a priori (sigma0^2 > 1 here is mostly the arms' errors, now counted).
      cov = Eigen::Matrix4d(jtj.inverse()) + added;
      out.arms_uncertainty_included = true;
    }
  }
  for (int k = 0; k < kRobotToRobotParamCount; ++k) {
    out.psi.set_value(static_cast<std::size_t>(k), psi[static_cast<std::size_t>(k)]);
    out.psi.set_stddev(static_cast<std::size_t>(k), std::sqrt(std::max(0.0, cov(k, k))));
  }
  // What the data cannot determine has no finite std (the pseudo-inverse gives one).
  for (const int k : out.identifiability.undetermined) {
    out.psi.set_stddev(static_cast<std::size_t>(k), std::numeric_limits<double>::infinity());
  }
  return out;
}

Eigen::MatrixXd ArmCovarianceFromUnknowns(const Eigen::MatrixXd& unknowns) {
  constexpr int kPoint = kRx130ParamCount + kLaserParamCount;  // the fixed point's 3 follow robot and laser
  constexpr int n = kArmModelParamCount + 3;
  if (unknowns.rows() != n || unknowns.cols() != n || !unknowns.allFinite()) return {};
  auto index = [](int i) { return static_cast<Eigen::Index>(i < kPoint ? i : i + 3); };
  Eigen::MatrixXd c(kArmModelParamCount, kArmModelParamCount);
  for (int i = 0; i < kArmModelParamCount; ++i) {
    for (int j = 0; j < kArmModelParamCount; ++j) c(i, j) = unknowns(index(i), index(j));
  }
  return c;
}

ArmModel ArmFromRobotCalibration(const RobotCalibrationResult& r) {
  ArmModel m;
  m.robot = r.robot;
  m.laser = r.laser;
  m.rail = r.rail;
  m.covariance = ArmCovarianceFromUnknowns(r.covariance);
  return m;
}

std::string RailCalibrationResult::Summary() const {
  std::ostringstream s;
  s << "rail calibration: " << readings_used << " readings used, " << outliers.size() << " outliers left out; "
    << summary.iterations << " LM iterations (" << summary.termination << "); RMS line distance " << rms_distance_mm
    << " mm (normalised " << rms_normalized << "), sigma0^2 " << variance_factor << "; condition number "
    << identifiability.condition_number;
  if (arms_uncertainty_included) {
    s << "; std with the arms' own uncertainty: psi_x " << psi.stddev(0) << " mm (" << std_given_arms[0]
      << " mm with the arms taken as exact)";
  }
  if (!summary.converged) {
    s << "; warning: the last solve stopped before converging, psi and its std may not be at the optimum";
  }
  return s.str();
}

Result<JointCalibrationResult> CalibrateArmsAndRail(const RobotCalibrationData& data1, const RobotCalibrationData& data2,
                                                    const std::vector<RailReading>& rail,
                                                    const RobotCalibrationResult& start1,
                                                    const RobotCalibrationResult& start2,
                                                    const RailCalibrationResult& start_rail,
                                                    const RobotNoiseModel& robot_noise, const RailNoiseModel& rail_noise,
                                                    const optim::SolverOptions& solver) {
  IDI_RETURN_IF_ERROR(robot_noise.Check());
  IDI_RETURN_IF_ERROR(rail_noise.Check());
  // The start results must be of these data (their outliers index them) and complete.
  const std::array<std::pair<const RobotCalibrationResult*, const RobotCalibrationData*>, 2> arms_in{
      std::pair{&start1, &data1}, std::pair{&start2, &data2}};
  for (std::size_t k = 0; k < 2; ++k) {
    const auto& [start, data] = arms_in[k];
    const std::string which = "joint calibration: robot " + std::to_string(k + 1) + "'s start";
    if (start->params.size() != static_cast<std::size_t>(kRobotCalibrationUnknowns)) {
      return InvalidArgument(which + " has " + std::to_string(start->params.size()) + " parameters, not the " +
                             std::to_string(kRobotCalibrationUnknowns) + " of a robot calibration");
    }
    for (const OutlierReading& o : start->outliers) {
      if (o.index < 0 || o.index >= static_cast<int>(data->readings.size())) {
        return InvalidArgument(which + " names reading " + std::to_string(o.index + 1) + " an outlier, of " +
                               std::to_string(data->readings.size()) + ": it is not of these data");
      }
    }
  }
  if (start_rail.psi.size() != static_cast<std::size_t>(kRobotToRobotParamCount)) {
    return InvalidArgument("joint calibration: the rail's start has no robot-to-robot transform");
  }
  for (const int i : start_rail.outliers) {
    if (i < 0 || i >= static_cast<int>(rail.size())) {
      return InvalidArgument("joint calibration: the rail's start names reading " + std::to_string(i + 1) +
                             " an outlier, of " + std::to_string(rail.size()) + ": it is not of these data");
    }
  }
  // Per arm: robot (18), laser (4), point (3), phi (2) blocks.
  struct Blocks {
    std::array<double, kRx130ParamCount> robot{};
    std::array<double, kLaserParamCount> laser{};
    std::array<double, 3> point{};
    std::array<double, kRailParamCount> phi{};
  };
  std::array<Blocks, 2> arm;
  const std::array<const RobotCalibrationResult*, 2> starts{&start1, &start2};
  const std::array<const RobotCalibrationData*, 2> datas{&data1, &data2};
  for (std::size_t k = 0; k < 2; ++k) {
    std::size_t i = 0;
    for (double& v : arm[k].robot) v = starts[k]->params.value(i++);
    for (double& v : arm[k].laser) v = starts[k]->params.value(i++);
    for (double& v : arm[k].point) v = starts[k]->params.value(i++);
    for (double& v : arm[k].phi) v = starts[k]->params.value(i++);
  }
  std::array<double, 4> psi;
  for (std::size_t k = 0; k < 4; ++k) psi[k] = start_rail.psi.value(k);
  optim::Problem problem;
  for (Blocks& b : arm) {
    problem.AddParameterBlock(b.robot.data(), kRx130ParamCount);
    problem.AddParameterBlock(b.laser.data(), kLaserParamCount);
    problem.AddParameterBlock(b.point.data(), 3);
    problem.AddParameterBlock(b.phi.data(), kRailParamCount);
  }
  problem.AddParameterBlock(psi.data(), kRobotToRobotParamCount);
  // Chapter 4 readings of each arm, with the weights of their separate solutions (outliers left out).
  optim::AimNoiseModel aim_noise;
  aim_noise.spot_sigma_mm = robot_noise.spot_sigma_mm;
  aim_noise.plane_normal = robot_noise.plane_normal;
  if (robot_noise.encoder_rounding) aim_noise.joint_sigma_rad = optim::EncoderRoundingSigmaRad();
  for (std::size_t k = 0; k < 2; ++k) {
    std::vector<bool> out(datas[k]->readings.size(), false);
    for (const OutlierReading& o : starts[k]->outliers) out[static_cast<std::size_t>(o.index)] = true;
    const Vec3d p(arm[k].point[0], arm[k].point[1], arm[k].point[2]);
    for (std::size_t i = 0; i < datas[k]->readings.size(); ++i) {
      if (out[i]) continue;
      const AimReading& r = datas[k]->readings[i];
      const std::optional<double> offset =
          r.set == 2 ? std::optional<double>(SetTwoOffset(datas[k]->method, datas[k]->distance_mm)) : std::nullopt;
      optim::AimEvaluation e;
      if (!optim::EvaluateAim(arm[k].robot.data(), arm[k].laser.data(), r.q, optim::AimedPoint(p, arm[k].phi.data(), offset), &e)) {
        continue;
      }
      const Eigen::LLT<Eigen::Matrix2d> llt(optim::AimNoiseCovariance(e, aim_noise));
      if (llt.info() != Eigen::Success) continue;  // no noise model at this reading (as no evaluation)
      const Eigen::Matrix2d l = llt.matrixL();
      std::vector<double*> blocks{arm[k].robot.data(), arm[k].laser.data(), arm[k].point.data()};
      if (offset) blocks.push_back(arm[k].phi.data());
      problem.AddResidual(std::make_shared<optim::AimResidual>(r.q, offset, Eigen::Matrix2d(l.inverse())), blocks);
    }
  }
  // Rail readings: both arms free.
  ArmModel m1, m2;
  for (std::size_t i = 0; i < kRx130ParamCount; ++i) {
    m1.robot.set_value(i, arm[0].robot[i]);
    m2.robot.set_value(i, arm[1].robot[i]);
  }
  for (std::size_t i = 0; i < kLaserParamCount; ++i) {
    m1.laser.set_value(i, arm[0].laser[i]);
    m2.laser.set_value(i, arm[1].laser[i]);
  }
  for (std::size_t i = 0; i < kRailParamCount; ++i) {
    m1.rail.set_value(i, arm[0].phi[i]);
    m2.rail.set_value(i, arm[1].phi[i]);
  }
  std::vector<bool> rail_out(rail.size(), false);
  for (int i : start_rail.outliers) rail_out[static_cast<std::size_t>(i)] = true;
  for (std::size_t i = 0; i < rail.size(); ++i) {
    if (rail_out[i]) continue;
    const auto sigma = ReadingSigma(rail[i], m1, m2, psi, rail_noise);
    if (!sigma) continue;
    problem.AddResidual(std::make_shared<optim::RailArmsResidual>(rail[i].q1, rail[i].rail1_mm, rail[i].q2, rail[i].rail2_mm, *sigma),
                        {psi.data(), arm[0].robot.data(), arm[0].laser.data(), arm[0].phi.data(), arm[1].robot.data(),
                         arm[1].laser.data(), arm[1].phi.data()});
  }
  JointCalibrationResult out;
  IDI_ASSIGN_OR_RETURN(out.summary, optim::SolveLevenbergMarquardt(problem, solver));
  IDI_ASSIGN_OR_RETURN(const optim::DenseEvaluation ev, optim::EvaluateDense(problem));
  const int n = problem.num_free_parameters();
  IDI_ASSIGN_OR_RETURN(const optim::CovarianceReport rep,
                       optim::AnalyzeJacobian(ev.jacobian, optim::VarianceFactor(ev.residuals, n)));
  out.condition_number = rep.condition_number;
  int col = 0;
  for (std::size_t k = 0; k < 2; ++k) {
    RobotCalibrationResult& r = k == 0 ? out.arm1 : out.arm2;
    r.params = ParamSet(RobotCalibrationSpecs());
    std::size_t i = 0;
    auto put = [&](double v) {
      r.params.set_value(i, v);
      r.params.set_stddev(i, rep.stddev(col));
      ++i;
      ++col;
    };
    for (double v : arm[k].robot) put(v);
    for (double v : arm[k].laser) put(v);
    for (double v : arm[k].point) put(v);
    for (double v : arm[k].phi) put(v);
    r.robot = r.params.Slice(0, kRx130ParamCount);
    r.laser = r.params.Slice(kRx130ParamCount, kLaserParamCount);
    r.rail = r.params.Slice(kRx130ParamCount + kLaserParamCount + 3, kRailParamCount);
    r.point_mm = Vec3d(arm[k].point[0], arm[k].point[1], arm[k].point[2]);
  }
  for (std::size_t k = 0; k < 4; ++k) {
    out.psi.set_value(k, psi[k]);
    out.psi.set_stddev(k, rep.stddev(col++));
  }
  return out;
}

}  // namespace idi::calib
