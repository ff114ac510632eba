#include "shared/calib/acquisition.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <random>

#include "shared/kinematics/aiming.h"

namespace idi::calib {
namespace {

double ScaledConditionNumber(const Eigen::MatrixXd& info) {
  const Eigen::VectorXd d = info.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXd s = d.asDiagonal() * info * d.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(s);
  const Eigen::VectorXd ev = es.eigenvalues();
  if (!(ev(0) > 0)) return std::numeric_limits<double>::infinity();
  return ev(ev.size() - 1) / ev(0);
}

// 2 x 6 Jacobian of the spot on the plane with respect to the joints (central differences).
std::optional<Eigen::Matrix<double, 2, 6>> SpotJacobian(const ParamSet& robot, const ParamSet& laser,
                                                       const Rigid3d& base_from_plane, const Joints& q) {
  Eigen::Matrix<double, 2, 6> j;
  const double h = 1e-6;
  for (std::size_t k = 0; k < 6; ++k) {
    Joints qp = q, qm = q;
    qp[k] += h;
    qm[k] -= h;
    const auto sp = SpotOnPlane(robot, laser, base_from_plane, qp);
    const auto sm = SpotOnPlane(robot, laser, base_from_plane, qm);
    if (!sp || !sm) return std::nullopt;
    j.col(static_cast<Eigen::Index>(k)) = (*sp - *sm) / (2 * h);
  }
  return j;
}

Joints Clamp(Joints q, const JointLimits& limits, double margin) {
  for (std::size_t i = 0; i < q.size(); ++i) q[i] = std::clamp(q[i], limits.min[i] + margin, limits.max[i] - margin);
  return q;
}

}  // namespace

Status PlanOptions::Check() const {
  if (!(near_deg > 0 && near_deg < 90) || !(wrist_margin_deg >= 0 && wrist_margin_deg < 80) || !(limit_margin_deg >= 0) ||
      !(min_length_mm > 0) || max_draws <= 0) {
    return InvalidArgument("acquisition plan: invalid options");
  }
  return Status::Ok();
}

Status AimLoopOptions::Check() const {
  if (!(tolerance_mm > 0) || max_iterations <= 0 || !(max_step_rad > 0) || !(limit_margin_rad >= 0) ||
      final_corrections < 0) {
    return InvalidArgument("closed-loop aiming: invalid options");
  }
  return Status::Ok();
}

Result<std::vector<Joints>> PlanAimConfigurations(const ParamSet& robot, const ParamSet& laser,
                                                  const Vec3d& target_in_base, int count, const JointLimits& limits,
                                                  const PlanOptions& o, const ProgressFn& progress) {
  IDI_RETURN_IF_ERROR(o.Check());
  if (count <= 0) return InvalidArgument("acquisition plan: count must be positive");
  if (!target_in_base.allFinite()) return InvalidArgument("acquisition plan: target is not finite");
  std::mt19937_64 rng(o.seed);
  const double margin = DegToRad(o.limit_margin_deg);
  const double cos_near = std::cos(DegToRad(o.near_deg));
  const double wrist = DegToRad(o.wrist_margin_deg);
  std::array<std::uniform_real_distribution<double>, kRx130Joints> draw;
  for (std::size_t i = 0; i < draw.size(); ++i) draw[i] = std::uniform_real_distribution<double>(limits.min[i] + margin, limits.max[i] - margin);
  IkOptions ik;
  ik.limit_margin_rad = margin;
  ik.min_laser_length_mm = o.min_length_mm;
  ik.tolerance_mm = 1e-6;
  std::vector<Joints> out;
  int draws = 0;
  while (static_cast<int>(out.size()) < count) {
    if (++draws > o.max_draws) {
      return NotFound("acquisition plan: only " + std::to_string(out.size()) + " of " + std::to_string(count) +
                      " configurations aim at the target after " + std::to_string(o.max_draws) +
                      " random draws: is the target reachable and in front of the robot?");
    }
    Joints q;
    for (std::size_t i = 0; i < q.size(); ++i) q[i] = draw[i](rng);
    if (std::abs(q[4]) < wrist) continue;
    const Line3d line = LaserLineInBase(robot.data(), laser.data(), q.data());
    const Vec3d to = target_in_base - line.origin;
    if (to.dot(line.direction) < cos_near * to.norm()) continue;
    const auto aimed = AimLaserAt(robot, laser, q, target_in_base, limits, ik);
    if (!aimed.ok()) continue;
    const Joints& qa = aimed->q;
    if (std::abs(qa[4]) < wrist || !limits.Contains(qa, 0.5 * margin)) continue;
    const Line3d la = LaserLineInBase(robot.data(), laser.data(), qa.data());
    if (ProjectOntoLine(la, target_in_base) < o.min_length_mm) continue;
    out.push_back(qa);
    if (progress) progress(static_cast<int>(out.size()), count);
  }
  return out;
}

std::vector<double> FileUnitWeights() {
  const std::vector<ParamSpec> specs = RobotCalibrationSpecs();
  std::vector<double> w;
  for (std::size_t i = 0; i < specs.size(); ++i) {
    const bool point = i >= kRx130ParamCount + kLaserParamCount && i < kRx130ParamCount + kLaserParamCount + 3;
    w.push_back(point ? 0.0 : (specs[i].unit == Unit::kDegree ? kDegPerRad * kDegPerRad : 1.0));
  }
  return w;
}

Result<SelectionResult> SelectForConditioning(const RobotCalibrationData& pool, const ParamSet& params,
                                              const RobotNoiseModel& noise, int per_set,
                                              const std::vector<double>& a_weights) {
  if (per_set <= 0) return InvalidArgument("selection: per_set must be positive");
  IDI_ASSIGN_OR_RETURN(const Eigen::MatrixXd j_all, RobotReadingJacobians(pool, params, noise));
  const Eigen::Index n = j_all.cols();
  if (!a_weights.empty() && static_cast<Eigen::Index>(a_weights.size()) != n) {
    return InvalidArgument("selection: expected one A-optimal weight per unknown");
  }
  // Scale the unknowns to unit information over the whole pool (log det gains do not depend on it,
  // but the conditioning of the updates does).
  Eigen::VectorXd scale = j_all.colwise().norm().transpose();
  for (Eigen::Index k = 0; k < n; ++k) scale(k) = scale(k) > 0 ? 1.0 / scale(k) : 1.0;
  const Eigen::MatrixXd js = j_all * scale.asDiagonal();
  std::array<std::vector<int>, 2> by_set;
  for (std::size_t i = 0; i < pool.readings.size(); ++i) {
    if (js.middleRows<2>(2 * static_cast<Eigen::Index>(i)).squaredNorm() > 0) {
      by_set[static_cast<std::size_t>(pool.readings[i].set - 1)].push_back(static_cast<int>(i));
    }
  }
  for (int s = 0; s < 2; ++s) {
    if (static_cast<int>(by_set[static_cast<std::size_t>(s)].size()) < per_set) {
      return InvalidArgument("selection: set " + std::to_string(s + 1) + " has " +
                             std::to_string(by_set[static_cast<std::size_t>(s)].size()) + " usable candidates, " +
                             std::to_string(per_set) + " wanted");
    }
  }
  SelectionResult out;
  {
    Eigen::MatrixXd info = Eigen::MatrixXd::Zero(n, n);
    for (int s = 0; s < 2; ++s) {
      for (int k = 0; k < per_set; ++k) {
        const auto b = js.middleRows<2>(2 * by_set[static_cast<std::size_t>(s)][static_cast<std::size_t>(k)]);
        info += b.transpose() * b;
      }
    }
    out.condition_number_first = ScaledConditionNumber(info);
  }
  // A-optimal weights in the scaled unknowns: w_i scale_i^2.
  Eigen::VectorXd wa = Eigen::VectorXd::Zero(n);
  for (Eigen::Index k = 0; k < static_cast<Eigen::Index>(a_weights.size()); ++k) wa(k) = a_weights[static_cast<std::size_t>(k)] * scale(k) * scale(k);
  const int d_picks = a_weights.empty() ? 2 * per_set : std::min(2 * per_set, 2 * static_cast<int>(n));
  // Lazy greedy: log det gains only shrink as the design grows (submodular), so a stale gain bounds the
  // fresh one and only the top of each queue needs re-evaluating; the A-optimal gains are treated the
  // same way (they shrink too, up to the occasional exception, which costs a slightly worse pick).
  const double eps = 1e-6;
  Eigen::MatrixXd m_inv = Eigen::MatrixXd::Identity(n, n) / eps;
  Eigen::MatrixXd info = eps * Eigen::MatrixXd::Identity(n, n);
  bool a_phase = false;
  auto gain = [&](int i) {
    const auto b = js.middleRows<2>(2 * static_cast<Eigen::Index>(i));
    const Eigen::Matrix<double, 2, Eigen::Dynamic> u = b * m_inv;
    const Eigen::Matrix2d s = Eigen::Matrix2d::Identity() + u * b.transpose();
    if (!a_phase) return std::log(s.determinant());
    return (s.inverse() * (u * wa.asDiagonal() * u.transpose())).trace();
  };
  using Entry = std::pair<double, int>;
  std::array<std::priority_queue<Entry>, 2> queues;
  std::vector<bool> taken(pool.readings.size(), false);
  auto fill = [&]() {
    for (int s = 0; s < 2; ++s) {
      queues[static_cast<std::size_t>(s)] = {};
      for (int i : by_set[static_cast<std::size_t>(s)]) {
        if (!taken[static_cast<std::size_t>(i)]) queues[static_cast<std::size_t>(s)].push({gain(i), i});
      }
    }
  };
  fill();
  for (int step = 0; step < 2 * per_set; ++step) {
    if (step == d_picks && !a_weights.empty()) {
      a_phase = true;
      fill();
    }
    auto& q = queues[static_cast<std::size_t>(step % 2)];
    int pick = -1;
    while (pick < 0) {
      const Entry top = q.top();
      q.pop();
      const double fresh = gain(top.second);
      if (q.empty() || fresh >= q.top().first) {
        pick = top.second;
      } else {
        q.push({fresh, top.second});
      }
    }
    const auto b = js.middleRows<2>(2 * static_cast<Eigen::Index>(pick));
    const Eigen::Matrix<double, Eigen::Dynamic, 2> mb = m_inv * b.transpose();
    const Eigen::Matrix2d s = Eigen::Matrix2d::Identity() + b * mb;
    m_inv -= mb * s.inverse() * mb.transpose();
    info += b.transpose() * b;
    taken[static_cast<std::size_t>(pick)] = true;
    out.chosen.push_back(pick);
  }
  out.condition_number = ScaledConditionNumber(info - eps * Eigen::MatrixXd::Identity(n, n));
  std::sort(out.chosen.begin(), out.chosen.end());
  return out;
}

std::optional<Vec2d> SpotOnPlane(const ParamSet& robot, const ParamSet& laser, const Rigid3d& base_from_plane,
                                 const Joints& q) {
  const Line3d line = LaserLineInBase(robot.data(), laser.data(), q.data());
  const Rigid3d plane_from_base = base_from_plane.Inverse();
  const Vec3d o = plane_from_base * line.origin;
  const Vec3d d = plane_from_base.RotateVector(line.direction);
  if (std::abs(d.z()) < 1e-9) return std::nullopt;
  const double s = -o.z() / d.z();
  if (!(s > 0)) return std::nullopt;
  return Vec2d(o.x() + s * d.x(), o.y() + s * d.y());
}

namespace {

// Of the 2^6 count combinations around `wanted` (each joint rounded down or up), the one whose spot
// shift from `current`, by the Jacobian, is nearest `error`.
Joints NearestCountsForSpot(const Joints& wanted, const Joints& current, const Eigen::Matrix<double, 2, 6>& j,
                            const Vec2d& error) {
  std::array<double, 6> lo{}, step{};
  for (std::size_t k = 0; k < 6; ++k) {
    step[k] = 1.0 / (kRx130CountsPerDeg[k] * kDegPerRad);
    lo[k] = std::floor(wanted[k] / step[k]) * step[k];
  }
  Joints best = wanted;
  double best_miss = std::numeric_limits<double>::infinity();
  for (unsigned mask = 0; mask < 64; ++mask) {
    Joints c;
    Eigen::Matrix<double, 6, 1> d;
    for (std::size_t k = 0; k < 6; ++k) {
      c[k] = lo[k] + (((mask >> k) & 1u) != 0 ? step[k] : 0.0);
      d(static_cast<Eigen::Index>(k)) = c[k] - current[k];
    }
    const double miss = (error - j * d).squaredNorm();
    if (miss < best_miss) {
      best_miss = miss;
      best = c;
    }
  }
  return best;
}

}  // namespace

Result<AimLoopResult> AimClosedLoop(const ParamSet& robot, const ParamSet& laser, const Rigid3d& base_from_plane,
                                    const Vec2d& target_on_plane, const Joints& start, const JointLimits& limits,
                                    const JointMover& move, const SpotObserver& observe, const AimLoopOptions& o) {
  IDI_RETURN_IF_ERROR(o.Check());
  AimLoopResult out;
  // A reading or a spot that is not finite is a device's fault, not a miss: it would turn into a NaN
  // joint command.
  auto move_checked = [&](const Joints& q) -> Result<Joints> {
    IDI_ASSIGN_OR_RETURN(const Joints reading, move(q));
    for (const double v : reading) {
      if (!std::isfinite(v)) return DeviceError("closed-loop aiming: the arm's joint reading is not finite");
    }
    return reading;
  };
  auto observe_checked = [&]() -> Result<Vec2d> {
    IDI_ASSIGN_OR_RETURN(const Vec2d spot, observe());
    if (!spot.allFinite()) return DeviceError("closed-loop aiming: the observed spot position is not finite");
    return spot;
  };
  IDI_ASSIGN_OR_RETURN(out.reading, move_checked(Clamp(start, limits, o.limit_margin_rad)));
  auto correct = [&](const Vec2d& error) -> Result<Joints> {
    const auto j = SpotJacobian(robot, laser, base_from_plane, out.reading);
    if (!j) {
      return OutOfRange("closed-loop aiming: the laser (nominal model) does not reach the observation plane");
    }
    // Minimum-norm correction dq = J^T (J J^T)^-1 e (lightly damped): the joints the spot does not see
    // stay where they are.
    Eigen::Matrix2d jjt = *j * j->transpose();
    jjt.diagonal().array() += 1e-12 * jjt.trace();
    Eigen::Matrix<double, 6, 1> dq = j->transpose() * jjt.ldlt().solve(error);
    const double step = dq.cwiseAbs().maxCoeff();
    if (step > o.max_step_rad) dq *= o.max_step_rad / step;
    Joints next = out.reading;
    for (std::size_t k = 0; k < 6; ++k) next[k] += dq(static_cast<Eigen::Index>(k));
    next = Clamp(next, limits, o.limit_margin_rad);
    if (o.round_to_encoder_counts) next = NearestCountsForSpot(next, out.reading, *j, error);
    return move_checked(next);
  };
  for (out.iterations = 0; out.iterations < o.max_iterations; ++out.iterations) {
    IDI_ASSIGN_OR_RETURN(const Vec2d spot, observe_checked());
    const Vec2d error = target_on_plane - spot;
    out.last_error_mm = error.norm();
    if (out.last_error_mm <= o.tolerance_mm) {
      Vec2d e = error;
      for (int c = 0; c < o.final_corrections; ++c) {
        if (c > 0) {
          IDI_ASSIGN_OR_RETURN(const Vec2d again, observe_checked());
          e = target_on_plane - again;
        }
        IDI_ASSIGN_OR_RETURN(out.reading, correct(e));
      }
      return out;
    }
    IDI_ASSIGN_OR_RETURN(out.reading, correct(error));
  }
  return NotConverged("closed-loop aiming: the spot is still " + FormatNumber(out.last_error_mm) +
                      " mm from the target after " + std::to_string(o.max_iterations) + " corrections");
}

}  // namespace idi::calib
