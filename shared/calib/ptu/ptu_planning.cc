#include "shared/calib/ptu/ptu_planning.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <limits>
#include <random>

#include "shared/optim/ptu/ptu_cost.h"

namespace idi::calib {
namespace {

double WrapToPi(double a) {
  a = std::remainder(a, 2 * kPi);
  return a <= -kPi ? a + 2 * kPi : a;
}

// Newton's method on project(pan, tilt) = target from one start.
std::optional<std::array<double, 2>> AimPtuFrom(const PtuCameraModel& model, const TcfPose& tcf, const Vec3d& point,
                                                const Vec2d& target, double pan, double tilt) {
  auto project = [&](double p, double t) { return model.Project(tcf, p, t, point); };
  std::optional<Vec2d> f = project(pan, tilt);
  if (!f || !model.Camera().InImage(*f, -4 * model.width)) return std::nullopt;
  Vec2d r = *f - target;
  for (int it = 0; it < 40; ++it) {
    if (r.norm() < 1e-7) return std::array<double, 2>{pan, tilt};
    constexpr double kH = 1e-6;
    const auto fp = project(pan + kH, tilt);
    const auto ft = project(pan, tilt + kH);
    if (!fp || !ft) return std::nullopt;
    Eigen::Matrix2d j;
    j.col(0) = (*fp - *f) / kH;
    j.col(1) = (*ft - *f) / kH;
    if (std::abs(j.determinant()) < 1e-9) return std::nullopt;
    Eigen::Vector2d step = -j.inverse() * r;
    const double len = step.norm();
    if (len > 0.3) step *= 0.3 / len;
    bool improved = false;
    for (int halving = 0; halving < 12 && !improved; ++halving) {
      const auto fn = project(pan + step.x(), tilt + step.y());
      if (fn && (*fn - target).norm() < r.norm()) {
        pan += step.x();
        tilt += step.y();
        f = fn;
        r = *fn - target;
        improved = true;
      }
      step *= 0.5;
    }
    if (!improved) return std::nullopt;
  }
  return r.norm() < 1e-4 ? std::optional<std::array<double, 2>>(std::array<double, 2>{pan, tilt}) : std::nullopt;
}

// Rows of the column-unscaled Jacobian of both cameras' residuals at one planned pose: columns are
// every estimated parameter of the left camera, of the right camera, then the point.
Eigen::MatrixXd PlanJacobian(const std::array<PtuCameraModel, 2>& models, const PtuPlannedPose& pose,
                             const Vec3d& point) {
  constexpr int kPerCamera = kPtuParamCount + kCameraParamCount;
  Eigen::MatrixXd j = Eigen::MatrixXd::Zero(4, 2 * kPerCamera + 3);
  for (int cam = 0; cam < 2; ++cam) {
    const PtuCameraModel& m = models[static_cast<std::size_t>(cam)];
    std::vector<double> ptu = m.ptu.values(), intr = m.intrinsics.values();
    double x[3] = {point.x(), point.y(), point.z()};
    const optim::PtuSpotResidual f(BaseFromTcf(pose.tcf), pose.pan_rad[static_cast<std::size_t>(cam)],
                                   pose.tilt_rad[static_cast<std::size_t>(cam)],
                                   pose.predicted_px[static_cast<std::size_t>(cam)], 1.0);
    const std::vector<double*> blocks = optim::PtuSpotBlocks(ptu.data(), intr.data(), x);
    std::vector<std::array<double, 6>> storage(blocks.size());
    std::vector<double*> jac(blocks.size());
    for (std::size_t b = 0; b < blocks.size(); ++b) jac[b] = storage[b].data();
    double r[2];
    if (!f.Evaluate(blocks.data(), r, jac.data())) continue;
    for (int k = 0; k < kPerCamera; ++k) {
      j(2 * cam, cam * kPerCamera + k) = storage[static_cast<std::size_t>(k)][0];
      j(2 * cam + 1, cam * kPerCamera + k) = storage[static_cast<std::size_t>(k)][1];
    }
    for (int k = 0; k < 3; ++k) {
      j(2 * cam, 2 * kPerCamera + k) = storage[static_cast<std::size_t>(kPerCamera)][static_cast<std::size_t>(k)];
      j(2 * cam + 1, 2 * kPerCamera + k) = storage[static_cast<std::size_t>(kPerCamera)][static_cast<std::size_t>(3 + k)];
    }
  }
  // p1, p2, k3 are never estimated.
  for (int cam = 0; cam < 2; ++cam) {
    for (int k : {kP1, kP2, kK3}) j.col(cam * kPerCamera + kPtuParamCount + k).setZero();
  }
  return j;
}

double AxisValueDeg(const PtuPlannedPose& p, int axis) {
  switch (axis) {
    case 0: return RadToDeg(p.pan_rad[0]);
    case 1: return RadToDeg(p.tilt_rad[0]);
    case 2: return RadToDeg(p.pan_rad[1]);
    case 3: return RadToDeg(p.tilt_rad[1]);
    default: return RadToDeg(p.q[static_cast<std::size_t>(axis - 4)]);
  }
}
constexpr int kPlanAxes = 4 + kRx130Joints;
const char* const kPlanAxisNames[kPlanAxes] = {"left.pan", "left.tilt", "right.pan", "right.tilt", "j1", "j2",
                                               "j3",       "j4",        "j5",        "j6"};

}  // namespace

std::optional<std::array<double, 2>> AimPtuAt(const PtuCameraModel& model, const TcfPose& tcf, const Vec3d& point_mm,
                                              const Vec2d& target_px, const PtuRange& range) {
  // Start pans around the direction of the point seen from the PTU base (frame 0, eq. 3.11).
  const double* p = model.ptu.data();
  const Rigid3d e_from_0 =
      Translation(p[kPtuTx], p[kPtuTy], p[kPtuTz]) * RotX(p[kPtuThetaX]) * RotY(p[kPtuThetaY]) * RotZ(p[kPtuThetaZ]);
  const Vec3d p0 = (BaseFromTcf(tcf) * e_from_0).Inverse() * point_mm;
  const double azimuth = std::atan2(p0.y(), p0.x());
  for (int k = 0; k < 8; ++k) {
    const auto sol = AimPtuFrom(model, tcf, point_mm, target_px, WrapToPi(azimuth + k * kPi / 4), 0.0);
    if (!sol) continue;
    const double pan = WrapToPi((*sol)[0]);
    const double tilt = WrapToPi((*sol)[1]);
    if (range.Contains(pan, tilt)) return std::array<double, 2>{pan, tilt};
  }
  return std::nullopt;
}

Status PtuPlanOptions::Check() const {
  if (poses < 1 || validation_poses < 0 || candidates < poses + validation_poses || max_draws < candidates ||
      !(margin_px >= 0) || !(min_distance_mm >= 0) || !(joint_range_fraction > 0 && joint_range_fraction <= 1) ||
      !(point_weight >= 0)) {
    return InvalidArgument(
        "PtuPlanOptions: need poses >= 1, candidates >= poses + validation_poses, max_draws >= candidates, "
        "margin_px >= 0, joint_range_fraction in (0, 1], point_weight >= 0");
  }
  return range.Check();
}

std::string PtuPlan::Summary() const {
  std::string s = fmt::format("{} calibration + {} validation poses from {} candidates ({} joint draws), log det {:.1f}",
                              calibration.size(), validation.size(), candidates, draws, log_det);
  for (const auto& c : coverage) {
    s += fmt::format("\n  {:<10} {:8.1f} .. {:8.1f} deg (candidates {:8.1f} .. {:8.1f})", c.axis, c.min_deg, c.max_deg,
                     c.range_min_deg, c.range_max_deg);
  }
  return s;
}

Result<PtuPlan> PlanPtuAcquisition(const ParamSet& robot, const JointLimits& limits,
                                   const std::array<PtuCameraModel, 2>& models, const Vec3d& approx_point_mm,
                                   const PtuPlanOptions& options) {
  IDI_RETURN_IF_ERROR(options.Check());
  if (robot.size() != kRx130ParamCount) return InvalidArgument("PlanPtuAcquisition: robot model has the wrong size");
  if (models[0].side != BiclopsSide::kLeft || models[1].side != BiclopsSide::kRight) {
    return InvalidArgument("PlanPtuAcquisition: models must be {left, right}");
  }
  if (!approx_point_mm.allFinite()) return InvalidArgument("PlanPtuAcquisition: approximate point not finite");
  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  PtuPlan plan;
  std::vector<PtuPlannedPose> cands;
  while (static_cast<int>(cands.size()) < options.candidates && plan.draws < options.max_draws) {
    ++plan.draws;
    PtuPlannedPose pose;
    for (std::size_t k = 0; k < kRx130Joints; ++k) {
      const double mid = 0.5 * (limits.min[k] + limits.max[k]);
      const double half = 0.5 * (limits.max[k] - limits.min[k]) * options.joint_range_fraction;
      pose.q[k] = mid + half * (2 * unit(rng) - 1);
    }
    if (!limits.Contains(pose.q)) continue;
    const Rigid3d flange = Rx130BaseFromFlange(robot.data(), pose.q.data());
    if (flange.translation.z() < options.min_flange_z_mm ||
        flange.translation.head<2>().norm() < options.min_flange_radius_mm) {
      continue;
    }
    pose.tcf = TcfPoseFromTransform(flange);
    bool ok = true;
    for (std::size_t cam = 0; cam < 2 && ok; ++cam) {
      const PtuCameraModel& m = models[cam];
      const Vec2d target(options.margin_px - 0.5 + unit(rng) * (m.width - 2 * options.margin_px),
                         options.margin_px - 0.5 + unit(rng) * (m.height - 2 * options.margin_px));
      const auto aim = AimPtuAt(m, pose.tcf, approx_point_mm, target, options.range);
      if (!aim) {
        ok = false;
        break;
      }
      pose.pan_rad[cam] = (*aim)[0];
      pose.tilt_rad[cam] = (*aim)[1];
      pose.predicted_px[cam] = target;
      const Vec3d cam_pos = m.BaseFromCamera(pose.tcf, pose.pan_rad[cam], pose.tilt_rad[cam]).translation;
      ok = (approx_point_mm - cam_pos).norm() >= options.min_distance_mm;
    }
    if (ok) cands.push_back(pose);
  }
  plan.candidates = static_cast<int>(cands.size());
  const int needed = options.poses + options.validation_poses;
  if (plan.candidates < needed) {
    return FailedPrecondition(fmt::format(
        "acquisition planning: only {} of {} random arm poses let both cameras see the spot within the PTU's range; "
        "{} are needed (move the spot or the arm's working region)",
        plan.candidates, plan.draws, needed));
  }

  // Column-scaled Jacobians of every candidate.
  std::vector<Eigen::MatrixXd> jac;
  jac.reserve(cands.size());
  for (const auto& c : cands) jac.push_back(PlanJacobian(models, c, approx_point_mm));
  const Eigen::Index n = jac[0].cols();
  Eigen::VectorXd norm2 = Eigen::VectorXd::Zero(n);
  for (const auto& j : jac) norm2 += j.colwise().squaredNorm().transpose();
  std::vector<Eigen::Index> cols;
  for (Eigen::Index k = 0; k < n; ++k) {
    if (norm2(k) > 0) cols.push_back(k);
  }
  const Eigen::Index m = static_cast<Eigen::Index>(cols.size());
  const double ncand = static_cast<double>(cands.size());
  for (auto& j : jac) {
    Eigen::MatrixXd js(j.rows(), m);
    for (Eigen::Index k = 0; k < m; ++k) {
      js.col(k) = j.col(cols[static_cast<std::size_t>(k)]) / std::sqrt(norm2(cols[static_cast<std::size_t>(k)]) / ncand);
    }
    j = std::move(js);
  }
  // Columns are scaled so that an average candidate brings unit information per parameter (log_det is
  // then comparable between plans); the ridge is a small fraction of that, so the first picks are
  // compared fairly.
  Eigen::MatrixXd info = Eigen::MatrixXd::Identity(m, m) * 1e-3;
  std::vector<bool> taken(cands.size(), false);
  std::vector<std::size_t> chosen;
  auto take = [&](std::size_t i) {
    if (taken[i]) return;
    taken[i] = true;
    chosen.push_back(i);
    info += jac[i].transpose() * jac[i];
  };
  for (int axis = 0; options.extremes_first && axis < kPlanAxes && static_cast<int>(chosen.size()) + 2 <= options.poses;
       ++axis) {
    std::size_t lo = 0, hi = 0;
    for (std::size_t i = 1; i < cands.size(); ++i) {
      if (AxisValueDeg(cands[i], axis) < AxisValueDeg(cands[lo], axis)) lo = i;
      if (AxisValueDeg(cands[i], axis) > AxisValueDeg(cands[hi], axis)) hi = i;
    }
    take(lo);
    take(hi);
  }
  while (static_cast<int>(chosen.size()) < options.poses) {
    const Eigen::MatrixXd inv = info.ldlt().solve(Eigen::MatrixXd::Identity(m, m));
    const Eigen::Matrix3d point_cov = inv.bottomRightCorner<3, 3>();
    double best_gain = -std::numeric_limits<double>::infinity();
    std::size_t best = 0;
    for (std::size_t i = 0; i < cands.size(); ++i) {
      if (taken[i]) continue;
      // Matrix determinant lemma for the whole information, Woodbury for the point's covariance.
      const Eigen::MatrixXd ji = jac[i] * inv;  // rows x m
      const Eigen::MatrixXd s = Eigen::MatrixXd::Identity(jac[i].rows(), jac[i].rows()) + ji * jac[i].transpose();
      const Eigen::LDLT<Eigen::MatrixXd> s_ldlt(s);
      double gain = s_ldlt.vectorD().array().log().sum();
      if (options.point_weight > 0) {
        const Eigen::MatrixXd jp = ji.rightCols(3);  // the point's columns are the last three
        const Eigen::Matrix3d new_cov = point_cov - jp.transpose() * s_ldlt.solve(jp);
        gain += options.point_weight * (std::log(point_cov.determinant()) - std::log(new_cov.determinant()));
      }
      if (gain > best_gain) {
        best_gain = gain;
        best = i;
      }
    }
    take(best);
  }
  Eigen::MatrixXd kept = Eigen::MatrixXd::Zero(m, m);
  for (std::size_t i : chosen) kept += jac[i].transpose() * jac[i];
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(kept);
  plan.log_det = ldlt.vectorD().array().log().sum();
  for (std::size_t i : chosen) plan.calibration.push_back(cands[i]);
  std::vector<std::size_t> rest;
  for (std::size_t i = 0; i < cands.size(); ++i) {
    if (!taken[i]) rest.push_back(i);
  }
  std::shuffle(rest.begin(), rest.end(), rng);
  for (int k = 0; k < options.validation_poses; ++k) plan.validation.push_back(cands[rest[static_cast<std::size_t>(k)]]);
  // Execution order: sweep joint 1 so the arm does not shuttle back and forth.
  auto by_j1 = [](const PtuPlannedPose& a, const PtuPlannedPose& b) { return a.q[0] < b.q[0]; };
  std::sort(plan.calibration.begin(), plan.calibration.end(), by_j1);
  std::sort(plan.validation.begin(), plan.validation.end(), by_j1);
  for (int axis = 0; axis < kPlanAxes; ++axis) {
    PtuAxisCoverage c;
    c.axis = kPlanAxisNames[axis];
    c.min_deg = c.range_min_deg = 1e300;
    c.max_deg = c.range_max_deg = -1e300;
    for (const auto& p : plan.calibration) {
      c.min_deg = std::min(c.min_deg, AxisValueDeg(p, axis));
      c.max_deg = std::max(c.max_deg, AxisValueDeg(p, axis));
    }
    for (const auto& p : cands) {
      c.range_min_deg = std::min(c.range_min_deg, AxisValueDeg(p, axis));
      c.range_max_deg = std::max(c.range_max_deg, AxisValueDeg(p, axis));
    }
    plan.coverage.push_back(c);
  }
  return plan;
}

}  // namespace idi::calib
