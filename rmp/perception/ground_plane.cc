#include "rmp/perception/ground_plane.h"

#include <Eigen/Geometry>
#include <cmath>
#include <vector>

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
  // Which samples are ground: the largest set that one plane explains. A frame's samples come from
  // a few triangulated lines, and a wrong stereo match puts all of its line's samples off the ground
  // together. Updated one at a time, the first sample of such a line could pull the plane (still
  // uncertain) to itself, and then the frame's true ground samples failed the gate - and the next
  // frames' too, since the plane also decides which line matches are kept (seen in the closed loop:
  // a 9 deg pitch from the first frame on, and tape beyond 1.4 m never seen). So the candidate planes
  // are the predicted one and, for each sample the prediction admits, the prediction updated with that
  // sample alone; the candidate that the most samples lie on (gate_m + 3 sigma of the point) picks the
  // samples that update the filter.
  auto point_sigma = [&](const GroundSample& s) {
    return options_.point_sigma_m + options_.point_sigma_per_range2 * s.range_m * s.range_m;
  };
  std::vector<std::size_t> valid;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    if (samples[i].xyz.allFinite() && std::isfinite(samples[i].range_m)) {
      valid.push_back(i);
    } else {
      ++out.rejected;
    }
  }
  auto row = [&](const GroundSample& s) { return Eigen::Vector3d(1.0, s.xyz.x(), s.xyz.y()); };
  std::vector<Eigen::Vector3d> candidates = {theta_};
  for (const std::size_t i : valid) {
    const GroundSample& s = samples[i];
    const Eigen::Vector3d h = row(s);
    const double r = point_sigma(s) * point_sigma(s);
    const double innovation = s.xyz.z() - h.dot(theta_);
    const double var = h.dot(covariance_ * h) + r;
    if (std::abs(innovation) <= options_.gate_m + 3.0 * std::sqrt(var))
      candidates.push_back(theta_ + covariance_ * h / var * innovation);
  }
  std::vector<char> inlier(samples.size(), 0), best(samples.size(), 0);
  int best_count = -1;
  double best_cost = 0.0;
  for (const Eigen::Vector3d& plane : candidates) {
    int count = 0;
    double cost = 0.0;
    for (const std::size_t i : valid) {
      const double d = std::abs(samples[i].xyz.z() - row(samples[i]).dot(plane));
      inlier[i] = d <= options_.gate_m + 3.0 * point_sigma(samples[i]);
      if (inlier[i]) {
        ++count;
        cost += d;
      }
    }
    if (count > best_count || (count == best_count && cost < best_cost)) {
      best_count = count;
      best_cost = cost;
      best = inlier;
    }
  }
  // Update with those samples (sequential scalar Kalman updates), still gating on the innovation.
  for (const std::size_t i : valid) {
    const GroundSample& s = samples[i];
    if (!best[i]) {
      ++out.rejected;
      continue;
    }
    const Eigen::Vector3d h = row(s);
    const double sigma = point_sigma(s);
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
