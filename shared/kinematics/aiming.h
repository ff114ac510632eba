// Aiming the laser tool (§3.3.2, eqs. 3.6-3.8) and numeric inverse kinematics for the RX-130.
#pragma once

#include <cmath>
#include <optional>

#include "shared/geometry/rigid3.h"
#include "shared/kinematics/rx130.h"
#include "shared/util/param_set.h"
#include "shared/util/status.h"

namespace idi {

// Eqs. 3.7-3.8: yaw and pitch (radians) of the direction from the end effector E to the target P.
// (Eq. 3.6 writes d = E - P; the pointing direction is its negative, P - E, which is what we use.)
struct AimAngles {
  double yaw_rad = 0;    // atan2(dy, dx)
  double pitch_rad = 0;  // atan2(sqrt(dx^2 + dy^2), dz): angle from the +z axis
};
AimAngles AimDirection(const Vec3d& end_effector, const Vec3d& target);
// The unit direction for given yaw and pitch (inverse of AimDirection).
Vec3d DirectionFromAim(const AimAngles& aim);

struct IkOptions {
  int max_iterations = 100;
  double tolerance_mm = 1e-7;        // stop when the residual is below this
  double max_step_rad = 0.2;         // largest joint change per iteration
  double limit_margin_rad = 1e-4;    // stay this far inside the joint limits
  double min_laser_length_mm = 50;   // the target must lie this far in front of the laser origin
  // Finite and positive (the margin and the laser length may be 0); a NaN margin turned the joint limits off.
  bool Check() const {
    return max_iterations > 0 && tolerance_mm > 0 && std::isfinite(tolerance_mm) && max_step_rad > 0 &&
           std::isfinite(max_step_rad) && limit_margin_rad >= 0 && std::isfinite(limit_margin_rad) &&
           min_laser_length_mm >= 0 && std::isfinite(min_laser_length_mm);
  }
};

struct IkSummary {
  Joints q{};
  int iterations = 0;
  double residual_mm = 0;  // distance of the target from the laser line (aim) or pose error
  std::string message;
};

// Turns a starting joint configuration into a nearby one whose laser line passes through `target`
// (base frame, mm), in front of the laser: Levenberg-Marquardt (minimum-norm damped steps) on the arc
// the beam must sweep to reach the target (see aiming.cc), joints kept inside their limits. Fails
// (NotConverged / OutOfRange) rather than returning a configuration that misses.
Result<IkSummary> AimLaserAt(const ParamSet& robot, const ParamSet& laser, const Joints& start, const Vec3d& target,
                             const JointLimits& limits, const IkOptions& options = {});

// Joint configuration whose flange frame equals `base_from_flange` (position in mm, orientation
// weighted by `orientation_weight_mm` per radian), from a start configuration.
Result<IkSummary> SolveFlangePose(const ParamSet& robot, const Joints& start, const Rigid3d& base_from_flange,
                                  const JointLimits& limits, const IkOptions& options = {},
                                  double orientation_weight_mm = 1000.0);

}  // namespace idi
