// The ground plane in the vehicle's body frame: from the calibration (z = 0 when the vehicle stands
// level), refined from the data (§8.12.4: the triangulated IDI points of the track lie on the road
// plane). The plane z = a + b x + c y (height, pitch and roll slopes) is a small Kalman filter: the
// calibration is its prior, it drifts a little between frames (the platform pitches when it
// accelerates), and every triangulated ground point measures it.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "shared/geometry/rigid3.h"
#include "shared/util/status.h"

namespace idi::rmp {

struct GroundPlaneOptions {
  // Prior (the calibration) standard deviations.
  double prior_height_m = 0.02;
  double prior_slope = 0.05;  // pitch (rad)
  double prior_roll = 0.02;
  // Random walk per update, and the pull back to the calibration (fraction per update).
  double walk_height_m = 0.002;
  double walk_slope = 0.01;
  double walk_roll = 0.003;
  double reversion = 0.02;
  // A triangulated point's height noise: base + per_range2 * range^2 (stereo depth error grows with
  // the square of the distance).
  double point_sigma_m = 0.003;
  double point_sigma_per_range2 = 0.002;
  // Points further than this (plus 3 sigma) from the plane are not ground (rejected).
  double gate_m = 0.05;

  Status Check() const;
};

struct GroundSample {
  Vec3d xyz = Vec3d::Zero();  // body frame
  double range_m = 1.0;       // distance from the cameras (for its noise)
};

struct GroundPlaneUpdate {
  int used = 0, rejected = 0;
};

class GroundPlaneEstimator {
 public:
  explicit GroundPlaneEstimator(const GroundPlaneOptions& options = {});
  void Reset();
  // One frame's samples. Non-finite samples are rejected.
  GroundPlaneUpdate Update(const std::vector<GroundSample>& samples);

  // z = a + b x + c y in the body frame.
  const Eigen::Vector3d& plane() const { return theta_; }
  Eigen::Vector3d sigmas() const { return covariance_.diagonal().cwiseSqrt(); }
  double HeightAbove(const Vec3d& p_body) const { return p_body.z() - (theta_[0] + theta_[1] * p_body.x() + theta_[2] * p_body.y()); }
  // The ground frame: z along the plane's normal, the plane at z = 0, x along the body's forward
  // direction in the plane, origin below the body origin.
  Rigid3d GroundFromBody() const;
  // Where a ray (body frame) meets the plane; false when it runs parallel or away from it.
  bool IntersectRay(const Vec3d& origin, const Vec3d& direction, Vec3d* hit) const;

 private:
  GroundPlaneOptions options_;
  Eigen::Vector3d theta_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance_ = Eigen::Matrix3d::Zero();
};

}  // namespace idi::rmp
