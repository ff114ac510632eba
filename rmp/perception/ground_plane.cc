#include "rmp/perception/ground_plane.h"

#include <Eigen/Geometry>
#include <cmath>

namespace idi::rmp {

Status GroundPlaneOptions::Check() const {
  for (const double v : {prior_height_m, prior_slope, prior_roll, point_sigma_m, gate_m}) {
    if (!(std::isfinite(v) && v > 0)) return InvalidArgument("ground plane: prior, point sigma and gate must be positive");
  }
  for (const double v : {walk_height_m, walk_slope, walk_roll, point_sigma_per_range2}) {
    if (!(std::isfinite(v) && v >= 0)) return InvalidArgument("ground plane: random walk and range terms must be >= 0");
  }
  if (!(reversion >= 0 && reversion <= 1)) return InvalidArgument("ground plane: reversion must be in [0, 1]");
  return Status::Ok();
}

GroundPlaneEstimator::GroundPlaneEstimator(const GroundPlaneOptions& options) : options_(options) { Reset(); }

void GroundPlaneEstimator::Reset() {
  theta_.setZero();
  covariance_ = Eigen::Vector3d(options_.prior_height_m * options_.prior_height_m, options_.prior_slope * options_.prior_slope,
                                options_.prior_roll * options_.prior_roll)
                    .asDiagonal();
}

GroundPlaneUpdate GroundPlaneEstimator::Update(const std::vector<GroundSample>& samples) {
  GroundPlaneUpdate out;
  // Predict: a random walk pulled back towards the calibration.
  const Eigen::Vector3d prior_var(options_.prior_height_m * options_.prior_height_m, options_.prior_slope * options_.prior_slope,
                                  options_.prior_roll * options_.prior_roll);
  theta_ *= (1.0 - options_.reversion);
  covariance_ *= (1.0 - options_.reversion) * (1.0 - options_.reversion);
  covariance_ += Eigen::Vector3d(options_.walk_height_m * options_.walk_height_m, options_.walk_slope * options_.walk_slope,
                                 options_.walk_roll * options_.walk_roll)
                     .asDiagonal();
  for (int k = 0; k < 3; ++k) covariance_(k, k) = std::min(covariance_(k, k), prior_var[k]);
  // Update with each sample (sequential scalar Kalman updates), gating outliers on the innovation.
  for (const GroundSample& s : samples) {
    if (!s.xyz.allFinite() || !std::isfinite(s.range_m)) {
      ++out.rejected;
      continue;
    }
    const Eigen::Vector3d h(1.0, s.xyz.x(), s.xyz.y());
    const double sigma = options_.point_sigma_m + options_.point_sigma_per_range2 * s.range_m * s.range_m;
    const double r = sigma * sigma;
    const double innovation = s.xyz.z() - h.dot(theta_);
    const double var = h.dot(covariance_ * h) + r;
    if (std::abs(innovation) > options_.gate_m + 3.0 * std::sqrt(var)) {
      ++out.rejected;
      continue;
    }
    const Eigen::Vector3d gain = covariance_ * h / var;
    theta_ += gain * innovation;
    covariance_ = (Eigen::Matrix3d::Identity() - gain * h.transpose()) * covariance_;
    covariance_ = 0.5 * (covariance_ + covariance_.transpose());
    ++out.used;
  }
  return out;
}

Rigid3d GroundPlaneEstimator::GroundFromBody() const {
  // Plane: n . p = d with n = (-b, -c, 1) / |.|, d = a / |.|.
  Eigen::Vector3d n(-theta_[1], -theta_[2], 1.0);
  const double norm = n.norm();
  n /= norm;
  const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(n, Eigen::Vector3d::UnitZ());
  Rigid3d g;
  g.rotation = q.toRotationMatrix();
  // The point of the plane below the body origin maps to the ground frame's origin.
  g.translation = -(g.rotation * Vec3d(0, 0, theta_[0]));
  return g;
}

bool GroundPlaneEstimator::IntersectRay(const Vec3d& origin, const Vec3d& direction, Vec3d* hit) const {
  // origin.z + t d.z = a + b (o.x + t d.x) + c (o.y + t d.y)
  const double denom = direction.z() - theta_[1] * direction.x() - theta_[2] * direction.y();
  if (std::abs(denom) < 1e-9) return false;
  const double t = (theta_[0] + theta_[1] * origin.x() + theta_[2] * origin.y() - origin.z()) / denom;
  if (!(t > 0) || !std::isfinite(t)) return false;
  *hit = origin + t * direction;
  return true;
}

}  // namespace idi::rmp
