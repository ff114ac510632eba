#include "shared/kinematics/aiming.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>

#include "shared/util/units.h"

namespace idi {
namespace {

using Jacobian = Eigen::Matrix<double, Eigen::Dynamic, kRx130Joints>;
using Residual = Eigen::VectorXd;
using ResidualFn = std::function<std::optional<Residual>(const Joints&)>;

Joints ClampToLimits(Joints q, const JointLimits& limits, double margin) {
  for (std::size_t i = 0; i < q.size(); ++i) {
    q[i] = std::clamp(q[i], limits.min[i] + margin, limits.max[i] - margin);
  }
  return q;
}

// Levenberg-Marquardt on a residual of the joints: steps are accepted only if they lower the cost,
// the damping adapts (smaller after success, larger after failure), and joints are clamped inside
// their limits. Central-difference Jacobian: the residuals are smooth trigonometric functions, so
// h = 1e-6 rad gives ~1e-10 relative accuracy, plenty for fast convergence.
// `accept_solution` is a last check of a configuration whose residual is below the tolerance.
Result<IkSummary> SolveLm(const ResidualFn& residual_of,
                          const Joints& start,
                          const JointLimits& limits,
                          const IkOptions& options,
                          const char* what,
                          const std::function<bool(const Joints&)>& accept_solution) {
  if (!options.Check()) {
    return InvalidArgument(std::string(what) + ": invalid IK options");
  }
  for (std::size_t i = 0; i < start.size(); ++i) {
    if (!std::isfinite(start[i])) {
      return InvalidArgument(std::string(what) + ": start joint " + std::to_string(i + 1) + " is not finite");
    }
    // std::clamp needs lo <= hi: a margin wider than half a joint's range has no configuration inside it.
    if (!(limits.min[i] + options.limit_margin_rad <= limits.max[i] - options.limit_margin_rad)) {
      return InvalidArgument(std::string(what) + ": joint " + std::to_string(i + 1) +
                             "'s limits leave no room inside the margin of " + FormatNumber(options.limit_margin_rad) +
                             " rad");
    }
  }
  Joints q = ClampToLimits(start, limits, options.limit_margin_rad);
  std::optional<Residual> r = residual_of(q);
  if (!r) {
    return OutOfRange(std::string(what) + ": the target is closer than min_laser_length_mm to the laser origin");
  }
  double cost = r->squaredNorm();
  double lambda = 1e-3;
  IkSummary summary;
  for (int iter = 0; iter < options.max_iterations; ++iter) {
    summary.iterations = iter;
    if (std::sqrt(cost) < options.tolerance_mm) {
      break;
    }
    Jacobian j(r->size(), kRx130Joints);
    const double h = 1e-6;
    for (std::size_t k = 0; k < kRx130Joints; ++k) {
      Joints qp = q, qm = q;
      qp[k] += h;
      qm[k] -= h;
      const auto rp = residual_of(qp);
      const auto rm = residual_of(qm);
      if (!rp || !rm) {
        return OutOfRange(std::string(what) + ": the target came too close to the laser origin");
      }
      j.col(static_cast<Eigen::Index>(k)) = (*rp - *rm) / (2 * h);
    }
    // Minimum-norm damped step dq = -J^T (J J^T + lambda mu I)^-1 r: joints the residual barely sees
    // (the roll about the beam) get no motion, instead of the large, useless moves a damped normal-
    // equation step would give them.
    const Eigen::MatrixXd jjt = j * j.transpose();
    const double mu = std::max(1e-12, jjt.diagonal().maxCoeff());
    bool accepted = false;
    for (int attempt = 0; attempt < 30 && !accepted; ++attempt) {
      Eigen::MatrixXd a = jjt;
      a.diagonal().array() += lambda * mu;
      Eigen::Matrix<double, kRx130Joints, 1> dq = -j.transpose() * a.ldlt().solve(*r);
      const double step = dq.cwiseAbs().maxCoeff();
      if (step > options.max_step_rad) {
        dq *= options.max_step_rad / step;
      }
      Joints next = q;
      for (std::size_t k = 0; k < kRx130Joints; ++k) {
        next[k] += dq(static_cast<Eigen::Index>(k));
      }
      next = ClampToLimits(next, limits, options.limit_margin_rad);
      const auto rn = residual_of(next);
      if (rn && rn->squaredNorm() < cost) {
        q = next;
        r = rn;
        cost = rn->squaredNorm();
        lambda = std::max(lambda / 3.0, 1e-12);
        accepted = true;
      } else {
        lambda *= 4.0;
      }
    }
    if (!accepted) {
      break;  // at a local minimum (or on a joint limit): report below
    }
  }
  summary.q = q;
  summary.residual_mm = std::sqrt(cost);
  if (summary.residual_mm < options.tolerance_mm && accept_solution(q)) {
    summary.message = "converged";
    return summary;
  }
  if (summary.residual_mm < options.tolerance_mm) {
    return NotConverged(std::string(what) +
                        ": the solution found is not acceptable (the target lies behind the laser)");
  }
  return NotConverged(std::string(what) + ": residual " + FormatNumber(summary.residual_mm) + " mm after " +
                      std::to_string(summary.iterations) +
                      " iterations (target out of reach from this start, or joints at their limits)");
}

}  // namespace

AimAngles AimDirection(const Vec3d& end_effector, const Vec3d& target) {
  const Vec3d d = target - end_effector;
  return {std::atan2(d.y(), d.x()), std::atan2(std::hypot(d.x(), d.y()), d.z())};
}

Vec3d DirectionFromAim(const AimAngles& aim) {
  return {std::sin(aim.pitch_rad) * std::cos(aim.yaw_rad), std::sin(aim.pitch_rad) * std::sin(aim.yaw_rad),
          std::cos(aim.pitch_rad)};
}

Result<IkSummary> AimLaserAt(const ParamSet& robot, const ParamSet& laser, const Joints& start, const Vec3d& target,
                             const JointLimits& limits, const IkOptions& options) {
  if (robot.size() != kRx130ParamCount || laser.size() != kLaserParamCount) {
    return InvalidArgument("AimLaserAt: expected 18 robot and 4 laser parameters");
  }
  if (!target.allFinite()) {
    return InvalidArgument("AimLaserAt: target is not finite");
  }
  // Residual in the laser frame (frame 7, the beam its z axis): with the target at p = (x, y, z),
  // r = |p| theta (x, y) / hypot(x, y), theta = atan2(hypot(x, y), z) the angle between the beam and
  // the direction to the target (the geometry eqs. 3.6-3.8 express as yaw and pitch). It is the arc
  // the beam must sweep at the target's distance: zero exactly when the beam hits the target in front
  // of the laser, equal to the target's offset from the beam near the solution, and, unlike (x, y)
  // alone, largest (not zero) when the beam points straight away, so a start that faces away is
  // turned round. Two components: the roll about the beam is left free.
  auto residual = [&](const Joints& q) -> std::optional<Residual> {
    const Rigid3d base_from_laser = Rx130BaseFromFlange(robot.data(), q.data()) * FlangeFromLaser(laser.data());
    const Vec3d p = base_from_laser.Inverse() * target;
    const double dist = p.norm();
    if (dist < options.min_laser_length_mm) {
      return std::nullopt;
    }
    const double rho = std::hypot(p.x(), p.y());
    Residual r(2);
    r << p.x(), p.y();
    if (rho > 1e-12) {
      r *= dist * std::atan2(rho, p.z()) / rho;
    } else if (p.z() < 0) {
      // Straight behind the laser: the offset (x, y) is rounding noise, but the beam must sweep half a turn.
      r << dist * kPi, 0.0;
    }
    return r;
  };
  // Converged means on the beam and in front of the laser (never the backward half of its line).
  auto in_front = [&](const Joints& q) {
    const Rigid3d base_from_laser = Rx130BaseFromFlange(robot.data(), q.data()) * FlangeFromLaser(laser.data());
    return (base_from_laser.Inverse() * target).z() > 0;
  };
  return SolveLm(residual, start, limits, options, "aiming the laser", in_front);
}

Result<IkSummary> SolveFlangePose(const ParamSet& robot, const Joints& start, const Rigid3d& base_from_flange,
                                  const JointLimits& limits, const IkOptions& options,
                                  double orientation_weight_mm) {
  if (robot.size() != kRx130ParamCount) {
    return InvalidArgument("SolveFlangePose: expected 18 robot parameters");
  }
  if (!base_from_flange.rotation.allFinite() || !base_from_flange.translation.allFinite() ||
      !std::isfinite(orientation_weight_mm)) {
    return InvalidArgument("SolveFlangePose: the target pose is not finite");
  }
  auto residual = [&](const Joints& q) -> std::optional<Residual> {
    const Rigid3d t = Rx130BaseFromFlange(robot.data(), q.data());
    const Eigen::AngleAxisd dr(Mat3d(base_from_flange.rotation.transpose() * t.rotation));
    Residual r(6);
    r.head<3>() = t.translation - base_from_flange.translation;
    r.tail<3>() = orientation_weight_mm * dr.angle() * dr.axis();  // rotation error, mm per radian
    return r;
  };
  return SolveLm(residual, start, limits, options, "flange pose IK", [](const Joints&) { return true; });
}

}  // namespace idi
