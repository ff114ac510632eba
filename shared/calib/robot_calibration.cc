#include "shared/calib/robot_calibration.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <sstream>

#include "shared/geometry/lines.h"
#include "shared/optim/vicki_costs.h"
#include "shared/util/statistics.h"

namespace idi::calib {
namespace {

using optim::AimEvaluation;
using optim::AimResidual;

// The 27 unknowns as the solver's parameter blocks.
struct Unknowns {
  std::array<double, kRx130ParamCount> robot{};
  std::array<double, kLaserParamCount> laser{};
  std::array<double, 3> point{};
  std::array<double, kRailParamCount> phi{};
};

Unknowns UnknownsFrom(const ParamSet& p) {
  Unknowns u;
  std::size_t k = 0;
  for (double& v : u.robot) v = p.value(k++);
  for (double& v : u.laser) v = p.value(k++);
  for (double& v : u.point) v = p.value(k++);
  for (double& v : u.phi) v = p.value(k++);
  return u;
}

ParamSet ParamsFrom(const Unknowns& u) {
  ParamSet p(RobotCalibrationSpecs());
  std::size_t k = 0;
  for (double v : u.robot) p.set_value(k++, v);
  for (double v : u.laser) p.set_value(k++, v);
  for (double v : u.point) p.set_value(k++, v);
  for (double v : u.phi) p.set_value(k++, v);
  return p;
}

std::optional<double> OffsetOf(const AimReading& r, const RobotCalibrationData& d) {
  if (r.set == 1) return std::nullopt;
  return SetTwoOffset(d.method, d.distance_mm);
}

optim::AimNoiseModel AimNoise(const RobotNoiseModel& n) {
  optim::AimNoiseModel m;
  m.spot_sigma_mm = n.spot_sigma_mm;
  m.plane_normal = n.plane_normal;
  if (n.encoder_rounding) m.joint_sigma_rad = optim::EncoderRoundingSigmaRad();
  return m;
}

// Evaluates eq. 4.2 (unwhitened) for one reading at u; nullopt if the point is not in front of the laser.
std::optional<AimEvaluation> Evaluate(const Unknowns& u, const AimReading& r, const RobotCalibrationData& d) {
  const Vec3d p(u.point[0], u.point[1], u.point[2]);
  AimEvaluation e;
  if (!optim::EvaluateAim(u.robot.data(), u.laser.data(), r.q, optim::AimedPoint(p, u.phi.data(), OffsetOf(r, d)), &e)) {
    return std::nullopt;
  }
  return e;
}

// Whitening of each reading at u: W = L^-1 with L L^T the reading's noise covariance. nullopt for readings
// that cannot be evaluated there.
std::vector<std::optional<Eigen::Matrix2d>> Weights(const Unknowns& u, const RobotCalibrationData& d,
                                                    const RobotNoiseModel& noise) {
  std::vector<std::optional<Eigen::Matrix2d>> w(d.readings.size());
  const optim::AimNoiseModel model = AimNoise(noise);
  for (std::size_t i = 0; i < d.readings.size(); ++i) {
    const auto e = Evaluate(u, d.readings[i], d);
    if (!e) continue;
    const Eigen::Matrix2d cov = optim::AimNoiseCovariance(*e, model);
    Eigen::LLT<Eigen::Matrix2d> llt(cov);
    if (llt.info() != Eigen::Success) continue;
    const Eigen::Matrix2d l = llt.matrixL();
    w[i] = l.inverse();
  }
  return w;
}

// The least-squares problem over the active readings.
struct Built {
  optim::Problem problem;
  std::vector<std::shared_ptr<AimResidual>> residuals;
  std::vector<std::size_t> reading;  // residual block -> reading index
};

void Build(Unknowns& u, const RobotCalibrationData& d, const std::vector<std::optional<Eigen::Matrix2d>>& w,
           const std::vector<bool>& active, optim::Loss loss, Built* b) {
  b->problem.AddParameterBlock(u.robot.data(), kRx130ParamCount);
  b->problem.AddParameterBlock(u.laser.data(), kLaserParamCount);
  b->problem.AddParameterBlock(u.point.data(), 3);
  b->problem.AddParameterBlock(u.phi.data(), kRailParamCount);
  for (std::size_t i = 0; i < d.readings.size(); ++i) {
    if (!active[i] || !w[i]) continue;
    const AimReading& r = d.readings[i];
    auto res = std::make_shared<AimResidual>(r.q, OffsetOf(r, d), *w[i]);
    std::vector<double*> blocks{u.robot.data(), u.laser.data(), u.point.data()};
    if (r.set == 2) blocks.push_back(u.phi.data());
    b->problem.AddResidual(res, blocks, loss);
    b->residuals.push_back(res);
    b->reading.push_back(i);
  }
}

struct ReadingFit {
  bool ok = false;
  double normalized = 0;  // |r| of eq. 4.2
  double miss_mm = 0;
  double whitened = 0;
};

std::vector<ReadingFit> Fits(const Unknowns& u, const RobotCalibrationData& d,
                             const std::vector<std::optional<Eigen::Matrix2d>>& w) {
  std::vector<ReadingFit> f(d.readings.size());
  for (std::size_t i = 0; i < d.readings.size(); ++i) {
    const auto e = Evaluate(u, d.readings[i], d);
    if (!e || !w[i]) continue;
    f[i].ok = true;
    f[i].normalized = e->r.norm();
    f[i].miss_mm = e->r.norm() * e->length_mm;
    f[i].whitened = (*w[i] * e->r).norm();
  }
  return f;
}

// Robust sigma of whitened 2-vectors: the median norm of a 2D Gaussian is sigma sqrt(2 ln 2).
double RobustSigma(const std::vector<ReadingFit>& fits, const std::vector<bool>& active) {
  std::vector<double> n;
  for (std::size_t i = 0; i < fits.size(); ++i) {
    if (active[i] && fits[i].ok) n.push_back(fits[i].whitened);
  }
  return Median(n) / std::sqrt(2.0 * std::log(2.0));
}

ResidualStats Stats(const std::vector<ReadingFit>& fits, const std::vector<bool>& active, double variance_factor) {
  ResidualStats s;
  std::vector<double> miss;
  double sum_n2 = 0, sum_m2 = 0;
  for (std::size_t i = 0; i < fits.size(); ++i) {
    if (!active[i] || !fits[i].ok) continue;
    ++s.readings;
    sum_n2 += fits[i].normalized * fits[i].normalized;
    sum_m2 += fits[i].miss_mm * fits[i].miss_mm;
    s.max_miss_mm = std::max(s.max_miss_mm, fits[i].miss_mm);
    miss.push_back(fits[i].miss_mm);
  }
  if (s.readings > 0) {
    s.rms_normalized = std::sqrt(sum_n2 / s.readings);
    s.rms_miss_mm = std::sqrt(sum_m2 / s.readings);
  }
  s.median_miss_mm = Median(miss);
  s.variance_factor = variance_factor;
  return s;
}

Result<Unknowns> ClosedFormStart(const RobotCalibrationData& d, const RobotCalibrationOptions& o) {
  std::array<std::vector<Line3d>, 2> lines;
  for (const AimReading& r : d.readings) {
    lines[static_cast<std::size_t>(r.set - 1)].push_back(
        LaserLineInBase(o.initial_robot.data(), o.initial_laser.data(), r.q.data()));
  }
  const auto p1 = PointClosestToLines(lines[0]);
  const auto p2 = PointClosestToLines(lines[1]);
  if (!p1 || !p2) {
    return FailedPrecondition(std::string("robot calibration: the laser lines of set ") + (p1 ? "2" : "1") +
                              " do not cross near one point (all nearly parallel): cannot locate the aimed point");
  }
  const double offset = SetTwoOffset(d.method, d.distance_mm);
  Vec3d t = (*p2 - *p1) / offset;
  if (!(t.norm() > 0.1)) {
    return FailedPrecondition("robot calibration: the two sets aim at points only " + FormatNumber((*p2 - *p1).norm()) +
                              " mm apart, but the known distance is " + FormatNumber(d.distance_mm) +
                              " mm: check --distance-mm and the set column");
  }
  t.normalize();
  Unknowns u;
  for (std::size_t i = 0; i < u.robot.size(); ++i) u.robot[i] = o.initial_robot.value(i);
  for (std::size_t i = 0; i < u.laser.size(); ++i) u.laser[i] = o.initial_laser.value(i);
  const Vec3d p = 0.5 * (*p1 + (*p2 - offset * t));
  u.point = {p.x(), p.y(), p.z()};
  u.phi[kPhiL] = std::atan2(t.y(), t.x());
  u.phi[kPhiM] = std::atan2(-t.z(), std::hypot(t.x(), t.y()));
  return u;
}

// Every reading in set 1 or 2 with finite joints (the problem's blocks and the selection's sets follow
// the set: another value made them disagree, an abort).
Status CheckReadings(const RobotCalibrationData& d, const std::string& what) {
  for (std::size_t i = 0; i < d.readings.size(); ++i) {
    const AimReading& r = d.readings[i];
    const std::string where =
        "reading " + std::to_string(i + 1) + (r.row > 0 ? " (line " + std::to_string(r.row) + ")" : "");
    if (r.set != 1 && r.set != 2) {
      return InvalidArgument(what + ": " + where + ": set must be 1 or 2, got " + std::to_string(r.set));
    }
    for (std::size_t j = 0; j < r.q.size(); ++j) {
      if (!std::isfinite(r.q[j])) {
        return InvalidArgument(what + ": " + where + ": joint " + std::to_string(j + 1) + " is not a finite number");
      }
    }
  }
  return Status::Ok();
}

// §4.3.2's minimums again over the readings kept once the outliers are left out: a set emptied by
// the outlier rounds leaves phi and the scale undetermined.
Status CheckInliers(const RobotCalibrationData& d, const std::vector<bool>& active, const RobotCalibrationOptions& o) {
  std::array<int, 2> per_set = {0, 0};
  int kept = 0;
  for (std::size_t i = 0; i < d.readings.size(); ++i) {
    if (!active[i]) continue;
    ++per_set[static_cast<std::size_t>(d.readings[i].set - 1)];
    ++kept;
  }
  const int left_out = static_cast<int>(d.readings.size()) - kept;
  const int needed = o.min_readings_per_unknown * kRobotCalibrationUnknowns;
  if (kept < needed) {
    return FailedPrecondition("robot calibration: " + std::to_string(left_out) +
                              " readings were left out as outliers; the " + std::to_string(kept) +
                              " kept are too few (" + std::to_string(needed) + " needed)");
  }
  for (std::size_t s = 0; s < 2; ++s) {
    if (per_set[s] < o.min_readings_per_set) {
      return FailedPrecondition("robot calibration: " + std::to_string(left_out) +
                                " readings were left out as outliers; set " + std::to_string(s + 1) + " keeps " +
                                std::to_string(per_set[s]) + ", need at least " +
                                std::to_string(o.min_readings_per_set));
    }
  }
  return Status::Ok();
}

struct Attempt {
  Unknowns u;
  optim::SolverSummary summary;
  std::vector<bool> active;
  std::vector<std::optional<Eigen::Matrix2d>> weights;
  bool accepted = false;
  std::string why;
};

// One solve from `start`: a robust (Cauchy) solve, then outlier rounds of plain least squares, each
// leaving out readings beyond the robust threshold, and a last least-squares solve when the last round
// left readings out. Accepted when it converged, fits the point and keeps enough readings.
// `name` says which start this is; each solve's label (name: kind) goes to `labels`, beside its start in
// `starts`.
Attempt SolveFrom(const Unknowns& start,
                  const RobotCalibrationData& d,
                  const RobotCalibrationOptions& o,
                  const std::vector<bool>& free_robot,
                  const std::string& name,
                  std::vector<double>* history,
                  std::vector<int>* starts,
                  std::vector<std::string>* labels) {
  Attempt a;
  a.u = start;
  a.weights = Weights(a.u, d, o.noise);
  a.active.assign(d.readings.size(), true);
  optim::SolverOptions so = o.solver;
  // Staged starts hold some robot parameters at their start values (a staged start's first stage).
  bool any_fixed = false;
  for (bool f : free_robot) any_fixed |= !f;
  auto solve = [&](const optim::Loss& loss, const std::string& kind) -> bool {
    Built b;
    Build(a.u, d, a.weights, a.active, loss, &b);
    if (any_fixed) {
      // A parameter block is all or nothing in the problem; hold the block and let the others move.
      b.problem.SetConstant(a.u.robot.data());
    }
    auto s = optim::SolveLevenbergMarquardt(b.problem, so);
    if (!s.ok()) {
      a.why = s.status().message();
      return false;
    }
    a.summary = *s;
    starts->push_back(static_cast<int>(history->size()));
    labels->push_back(name + ": " + kind);
    history->insert(history->end(), s->cost_per_iteration.begin(), s->cost_per_iteration.end());
    return true;
  };
  // Whether the last solve was not plain least squares over the readings now active: the robust one,
  // or one before the last round left readings out.
  bool refit = false;
  for (int round = 0; round <= o.max_outlier_rounds; ++round) {
    const bool robust = round == 0;
    if (!solve(robust ? optim::Loss{optim::LossKind::kCauchy, 3.0} : optim::Loss{},
               robust ? std::string(any_fixed ? "robot held, robust (Cauchy loss)" : "robust (Cauchy loss)")
                      : "least squares, outlier round " + std::to_string(round))) {
      return a;
    }
    if (any_fixed) break;
    const std::vector<ReadingFit> fits = Fits(a.u, d, a.weights);
    const double sigma = RobustSigma(fits, a.active);
    bool changed = false;
    for (std::size_t i = 0; i < fits.size(); ++i) {
      if (!a.active[i]) continue;
      if (!fits[i].ok || (fits[i].whitened > o.outlier_sigmas * sigma && fits[i].miss_mm > o.outlier_floor_mm)) {
        a.active[i] = false;
        changed = true;
      }
    }
    refit = changed || round == 0;
    if (!changed && round > 0) break;
  }
  // The parameters (and the covariance at them) are the least-squares fit of the readings kept.
  if (refit && !solve(optim::Loss{}, "least squares of the readings kept")) return a;
  const ResidualStats st = Stats(Fits(a.u, d, a.weights), a.active, 0);
  if (!a.summary.usable) {
    a.why = "solver: " + a.summary.message;
  } else if (!(st.rms_miss_mm <= o.max_rms_miss_mm)) {
    a.why = "the fit misses the point by " + FormatNumber(st.rms_miss_mm) + " mm RMS";
  } else if (const Status kept = CheckInliers(d, a.active, o); !kept.ok()) {
    a.why = kept.message();  // another start may leave fewer readings out
  } else {
    a.accepted = true;
  }
  return a;
}

}  // namespace

const char* MethodName(TranslationMethod m) { return m == TranslationMethod::kTranslate ? "translate" : "two-points"; }

Result<TranslationMethod> ParseMethod(const std::string& text) {
  if (text == "translate") return TranslationMethod::kTranslate;
  if (text == "two-points") return TranslationMethod::kTwoPoints;
  return InvalidArgument("method '" + text + "': expected translate or two-points");
}

double SetTwoOffset(TranslationMethod method, double distance_mm) {
  return method == TranslationMethod::kTranslate ? -distance_mm : distance_mm;
}

Status RobotNoiseModel::Check() const {
  if (!(spot_sigma_mm > 0) || !std::isfinite(spot_sigma_mm) || !(distance_sigma_mm >= 0) ||
      !std::isfinite(distance_sigma_mm)) {
    return InvalidArgument("noise model: spot_sigma_mm must be > 0 and distance_sigma_mm >= 0 (finite)");
  }
  if (plane_normal && !(plane_normal->norm() > 0.5 && plane_normal->allFinite())) {
    return InvalidArgument("noise model: plane_normal must be a unit vector");
  }
  return Status::Ok();
}

Status RobotCalibrationOptions::Check() const {
  IDI_RETURN_IF_ERROR(noise.Check());
  IDI_RETURN_IF_ERROR(solver.Check());
  IDI_RETURN_IF_ERROR(identifiability.Check());
  if (initial_robot.size() != kRx130ParamCount || initial_laser.size() != kLaserParamCount) {
    return InvalidArgument("robot calibration: initial parameters must be 18 robot and 4 laser values");
  }
  if (min_readings_per_unknown < 1 || min_readings_per_set < 3 || !(outlier_sigmas > 2) || !(outlier_floor_mm >= 0) ||
      max_outlier_rounds < 0 || !(max_rms_miss_mm > 0) || max_restarts < 0) {
    return InvalidArgument("robot calibration: invalid options");
  }
  return Status::Ok();
}

std::vector<ParamSpec> RobotCalibrationSpecs() {
  std::vector<ParamSpec> s = Rx130ParamSpecs();
  for (const ParamSpec& l : LaserParamSpecs()) s.push_back(l);
  s.push_back({"point_x", Unit::kMillimetre, 0.0, "aimed point (set 1), robot base frame"});
  s.push_back({"point_y", Unit::kMillimetre, 0.0, "aimed point (set 1), robot base frame"});
  s.push_back({"point_z", Unit::kMillimetre, 0.0, "aimed point (set 1), robot base frame"});
  for (const ParamSpec& r : RailParamSpecs()) s.push_back(r);
  return s;
}

ParamSet PackRobotCalibration(const ParamSet& robot, const ParamSet& laser, const Vec3d& point, const ParamSet& rail) {
  ParamSet p(RobotCalibrationSpecs());
  std::size_t k = 0;
  for (std::size_t i = 0; i < robot.size(); ++i) p.set_value(k++, robot.value(i));
  for (std::size_t i = 0; i < laser.size(); ++i) p.set_value(k++, laser.value(i));
  for (int i = 0; i < 3; ++i) p.set_value(k++, point(i));
  for (std::size_t i = 0; i < rail.size(); ++i) p.set_value(k++, rail.value(i));
  return p;
}

Status ValidateRobotCalibrationData(const RobotCalibrationData& d, const RobotCalibrationOptions& o) {
  if (!(d.distance_mm > 0) || !std::isfinite(d.distance_mm)) {
    return InvalidArgument("robot calibration: the known distance must be a positive number of mm, got " +
                           FormatNumber(d.distance_mm));
  }
  IDI_RETURN_IF_ERROR(CheckReadings(d, "robot calibration"));
  std::array<int, 2> per_set{0, 0};
  for (const AimReading& r : d.readings) ++per_set[static_cast<std::size_t>(r.set - 1)];
  const int needed = o.min_readings_per_unknown * kRobotCalibrationUnknowns;
  if (static_cast<int>(d.readings.size()) < needed) {
    return InvalidArgument("robot calibration: " + std::to_string(d.readings.size()) + " readings are too few: " +
                           std::to_string(kRobotCalibrationUnknowns) + " unknowns need at least " + std::to_string(needed) +
                           " (" + std::to_string(o.min_readings_per_unknown) + " per unknown, §4.3.2)");
  }
  for (int s = 0; s < 2; ++s) {
    if (per_set[static_cast<std::size_t>(s)] < o.min_readings_per_set) {
      return InvalidArgument("robot calibration: set " + std::to_string(s + 1) + " has " +
                             std::to_string(per_set[static_cast<std::size_t>(s)]) + " readings, need at least " +
                             std::to_string(o.min_readings_per_set) + " (both sets are needed to fix the scale)");
    }
  }
  return Status::Ok();
}

Result<Eigen::MatrixXd> RobotCovarianceAt(const RobotCalibrationData& data, const ParamSet& params,
                                          const RobotNoiseModel& noise) {
  IDI_RETURN_IF_ERROR(noise.Check());
  if (params.size() != static_cast<std::size_t>(kRobotCalibrationUnknowns)) {
    return InvalidArgument("RobotCovarianceAt: expected the 27 calibration unknowns");
  }
  IDI_RETURN_IF_ERROR(CheckReadings(data, "RobotCovarianceAt"));
  Unknowns u = UnknownsFrom(params);
  const auto w = Weights(u, data, noise);
  Built b;
  Build(u, data, w, std::vector<bool>(data.readings.size(), true), {}, &b);
  IDI_ASSIGN_OR_RETURN(const optim::DenseEvaluation ev, optim::EvaluateDense(b.problem));
  IDI_ASSIGN_OR_RETURN(optim::CovarianceReport rep, optim::AnalyzeJacobian(ev.jacobian, 1.0));
  Eigen::VectorXd drdd = Eigen::VectorXd::Zero(ev.residuals.size());
  const double sign = data.method == TranslationMethod::kTranslate ? -1.0 : 1.0;
  std::array<const double*, 4> p{u.robot.data(), u.laser.data(), u.point.data(), u.phi.data()};
  for (std::size_t k = 0; k < b.residuals.size(); ++k) {
    drdd.segment<2>(static_cast<Eigen::Index>(2 * k)) = sign * b.residuals[k]->DerivativeWrtOffset(p.data());
  }
  const Eigen::VectorXd g = -rep.covariance * (ev.jacobian.transpose() * drdd);
  return Eigen::MatrixXd(rep.covariance + noise.distance_sigma_mm * noise.distance_sigma_mm * g * g.transpose());
}

Result<Eigen::MatrixXd> RobotReadingJacobians(const RobotCalibrationData& data, const ParamSet& params,
                                              const RobotNoiseModel& noise) {
  IDI_RETURN_IF_ERROR(noise.Check());
  if (params.size() != static_cast<std::size_t>(kRobotCalibrationUnknowns)) {
    return InvalidArgument("RobotReadingJacobians: expected the 27 calibration unknowns");
  }
  IDI_RETURN_IF_ERROR(CheckReadings(data, "RobotReadingJacobians"));
  const Unknowns u = UnknownsFrom(params);
  const auto w = Weights(u, data, noise);
  Eigen::MatrixXd j = Eigen::MatrixXd::Zero(2 * static_cast<Eigen::Index>(data.readings.size()), kRobotCalibrationUnknowns);
  std::array<const double*, 4> p{u.robot.data(), u.laser.data(), u.point.data(), u.phi.data()};
  Eigen::Matrix<double, 2, kRobotCalibrationUnknowns, Eigen::RowMajor> row;
  for (std::size_t i = 0; i < data.readings.size(); ++i) {
    if (!w[i]) continue;
    const AimReading& r = data.readings[i];
    const AimResidual res(r.q, OffsetOf(r, data), *w[i]);
    Eigen::Matrix<double, 2, kRx130ParamCount, Eigen::RowMajor> jr;
    Eigen::Matrix<double, 2, kLaserParamCount, Eigen::RowMajor> jl;
    Eigen::Matrix<double, 2, 3, Eigen::RowMajor> jp;
    Eigen::Matrix<double, 2, kRailParamCount, Eigen::RowMajor> jd = Eigen::Matrix<double, 2, kRailParamCount, Eigen::RowMajor>::Zero();
    std::array<double*, 4> jac{jr.data(), jl.data(), jp.data(), jd.data()};
    Eigen::Vector2d rv;
    if (!res.Evaluate(p.data(), rv.data(), jac.data())) continue;
    row << jr, jl, jp, jd;
    j.middleRows<2>(2 * static_cast<Eigen::Index>(i)) = row;
  }
  return j;
}

Result<RobotCalibrationResult> CalibrateRobot(const RobotCalibrationData& data, const RobotCalibrationOptions& o) {
  IDI_RETURN_IF_ERROR(o.Check());
  IDI_RETURN_IF_ERROR(ValidateRobotCalibrationData(data, o));
  IDI_ASSIGN_OR_RETURN(const Unknowns start, ClosedFormStart(data, o));
  RobotCalibrationResult out;
  out.start = "closed form: nominal model, point closest to each set's laser lines (§4.5.4)";
  const std::vector<bool> all_free(kRx130ParamCount, true);
  Attempt best = SolveFrom(
      start, data, o, all_free, "closed-form start", &out.cost_per_iteration, &out.solve_starts, &out.solve_labels);
  std::mt19937 rng(o.restart_seed);
  while (!best.accepted && out.restarts < o.max_restarts) {
    ++out.restarts;
    Unknowns s = start;
    if (out.restarts == 1) {
      // Staged: first the point, direction and laser with the robot held nominal, then everything.
      Attempt stage = SolveFrom(start,
                                data,
                                o,
                                std::vector<bool>(kRx130ParamCount, false),
                                "restart 1, stage 1",
                                &out.cost_per_iteration,
                                &out.solve_starts,
                                &out.solve_labels);
      s = stage.u;
    } else {
      // Perturbed (the dissertation's random restarts, §4.3.2), smaller each time.
      std::normal_distribution<double> n(0.0, 1.0);
      const double scale = 1.0 / out.restarts;
      const ParamSet specs(RobotCalibrationSpecs());
      for (std::size_t i = 0; i < s.robot.size(); ++i) {
        s.robot[i] += scale * (specs.spec(i).unit == Unit::kDegree ? DegToRad(0.05) : 0.5) * n(rng);
      }
    }
    Attempt a = SolveFrom(s,
                          data,
                          o,
                          all_free,
                          out.restarts == 1 ? std::string("restart 1, stage 2")
                                            : "restart " + std::to_string(out.restarts) + " (perturbed)",
                          &out.cost_per_iteration,
                          &out.solve_starts,
                          &out.solve_labels);
    if (a.accepted || !best.summary.usable) best = std::move(a);
  }
  if (!best.summary.usable) {
    return NotConverged("robot calibration did not converge: " + best.why);
  }
  if (!best.accepted) {
    return NotConverged("robot calibration: no acceptable solution after " + std::to_string(out.restarts) +
                        " restarts: " + best.why);
  }
  IDI_RETURN_IF_ERROR(CheckInliers(data, best.active, o));
  Unknowns& u = best.u;
  out.summary = best.summary;
  // Outliers: readings left out, with their miss at the solution.
  const std::vector<ReadingFit> fits = Fits(u, data, best.weights);
  const double sigma = RobustSigma(fits, best.active);
  for (std::size_t i = 0; i < data.readings.size(); ++i) {
    if (best.active[i]) continue;
    OutlierReading r;
    r.index = static_cast<int>(i);
    r.set = data.readings[i].set;
    r.row = data.readings[i].row;
    r.miss_mm = fits[i].ok ? fits[i].miss_mm : std::numeric_limits<double>::infinity();
    r.sigmas = fits[i].ok && sigma > 0 ? fits[i].whitened / sigma : std::numeric_limits<double>::infinity();
    out.outliers.push_back(r);
  }
  // Covariance at the solution over the inliers.
  Built b;
  Build(u, data, best.weights, best.active, {}, &b);
  IDI_ASSIGN_OR_RETURN(const optim::DenseEvaluation ev, optim::EvaluateDense(b.problem));
  const double s02 = optim::VarianceFactor(ev.residuals, kRobotCalibrationUnknowns);
  IDI_ASSIGN_OR_RETURN(out.identifiability, optim::AnalyzeJacobian(ev.jacobian, 1.0, o.identifiability));
  const Eigen::MatrixXd unscaled = out.identifiability.covariance;
  out.identifiability.variance_factor = s02;
  out.identifiability.covariance *= s02;
  out.identifiability.stddev *= std::sqrt(s02);
  Eigen::VectorXd drdd = Eigen::VectorXd::Zero(ev.residuals.size());
  const double sign = data.method == TranslationMethod::kTranslate ? -1.0 : 1.0;
  std::array<const double*, 4> p{u.robot.data(), u.laser.data(), u.point.data(), u.phi.data()};
  for (std::size_t k = 0; k < b.residuals.size(); ++k) {
    drdd.segment<2>(static_cast<Eigen::Index>(2 * k)) = sign * b.residuals[k]->DerivativeWrtOffset(p.data());
  }
  out.distance_sensitivity = -unscaled * (ev.jacobian.transpose() * drdd);
  const double sd = o.noise.distance_sigma_mm;
  out.covariance = out.identifiability.covariance + sd * sd * out.distance_sensitivity * out.distance_sensitivity.transpose();
  out.residuals = Stats(fits, best.active, s02);

  out.params = ParamsFrom(u);
  for (std::size_t i = 0; i < out.params.size(); ++i) {
    const bool undetermined = std::find(out.identifiability.undetermined.begin(), out.identifiability.undetermined.end(),
                                        static_cast<int>(i)) != out.identifiability.undetermined.end();
    out.params.set_stddev(i, undetermined ? std::numeric_limits<double>::infinity()
                                          : std::sqrt(std::max(0.0, out.covariance(static_cast<Eigen::Index>(i),
                                                                                    static_cast<Eigen::Index>(i)))));
  }
  out.robot = out.params.Slice(0, kRx130ParamCount);
  out.laser = out.params.Slice(kRx130ParamCount, kLaserParamCount);
  out.rail = out.params.Slice(kRx130ParamCount + kLaserParamCount + 3, kRailParamCount);
  out.point_mm = Vec3d(u.point[0], u.point[1], u.point[2]);
  return out;
}

std::string RobotCalibrationResult::Summary() const {
  std::ostringstream s;
  s << "ViCKi robot calibration: " << residuals.readings << " readings used, " << outliers.size() << " outliers left out; "
    << summary.iterations << " LM iterations (" << summary.termination << "), " << restarts << " restarts; "
    << "RMS miss " << residuals.rms_miss_mm << " mm (eq. 4.2 RMS " << residuals.rms_normalized << "), sigma0^2 "
    << residuals.variance_factor << "; Jacobian condition number " << identifiability.condition_number;
  return s.str();
}

}  // namespace idi::calib
