// Planar poses on the ground (SE(2)): the vehicle in the odometry frame, the track in the vehicle
// frame. Frames follow the vehicle convention: x forward, y left, yaw counter-clockwise, metres.
#pragma once

#include <cmath>

#include "shared/geometry/rigid3.h"
#include "shared/util/units.h"

namespace idi::rmp {

// Wraps an angle to (-pi, pi].
inline double WrapAngle(double a) {
  a = std::remainder(a, 2.0 * kPi);
  return a <= -kPi ? a + 2.0 * kPi : a;
}

// `target_from_source` as x, y, yaw: p_target = R(yaw) p_source + (x, y).
struct Pose2 {
  double x = 0.0, y = 0.0, yaw = 0.0;

  static Pose2 Identity() { return {}; }
  Vec2d translation() const { return {x, y}; }
  Vec2d operator*(const Vec2d& p) const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    return {c * p.x() - s * p.y() + x, s * p.x() + c * p.y() + y};
  }
  Vec2d RotateVector(const Vec2d& v) const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    return {c * v.x() - s * v.y(), s * v.x() + c * v.y()};
  }
  Pose2 operator*(const Pose2& rhs) const {
    const Vec2d t = *this * rhs.translation();
    return {t.x(), t.y(), WrapAngle(yaw + rhs.yaw)};
  }
  Pose2 Inverse() const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    return {-(c * x + s * y), -(-s * x + c * y), WrapAngle(-yaw)};
  }
  bool IsFinite() const { return std::isfinite(x) && std::isfinite(y) && std::isfinite(yaw); }
};

// Unicycle motion over `dt_s` at constant speed and yaw rate (exact arc), applied in the body frame.
inline Pose2 IntegrateUnicycle(const Pose2& pose, double speed_mps, double yaw_rate_rps, double dt_s) {
  const double dyaw = yaw_rate_rps * dt_s;
  const double ds = speed_mps * dt_s;
  // Chord of the arc: length 2 r sin(dyaw/2) in direction dyaw/2 (straight line when dyaw -> 0).
  const double chord = std::abs(dyaw) < 1e-9 ? ds : ds * std::sin(0.5 * dyaw) / (0.5 * dyaw);
  const Pose2 step{chord * std::cos(0.5 * dyaw), chord * std::sin(0.5 * dyaw), dyaw};
  return pose * step;
}

}  // namespace idi::rmp
