#include "rmp/segway/rmp_odometry.h"

#include <cmath>
#include <string>

namespace idi::rmp {

Status RmpOdometryOptions::Check() const {
  if (!(std::isfinite(wheel_separation_m) && wheel_separation_m > 0.1 && wheel_separation_m < 5.0)) {
    return InvalidArgument("RMP odometry: wheel_separation_m " + FormatNumber(wheel_separation_m) +
                           " is not in (0.1, 5) m");
  }
  if (!(std::isfinite(linear_scale) && linear_scale > 0.1 && linear_scale < 10.0) ||
      !(std::isfinite(angular_scale) && angular_scale > 0.1 && angular_scale < 10.0)) {
    return InvalidArgument("RMP odometry: linear_scale and angular_scale must be in (0.1, 10)");
  }
  if (!(std::isfinite(max_speed_mps) && max_speed_mps > 0.0)) {
    return InvalidArgument("RMP odometry: max_speed_mps must be positive");
  }
  return Status::Ok();
}

RmpOdometry::RmpOdometry(const RmpCodec& codec, const RmpOdometryOptions& options) : codec_(codec), options_(options) {
  const Status st = options_.Check();
  IDI_CHECK(st.ok(), st.ToString());
}

void RmpOdometry::Reset() {
  initialized_ = false;
  pose_ = {};
}

Status RmpOdometry::Update(int64_t t_ns, const RmpIntegratorCounts& counts) {
  if (!initialized_) {
    initialized_ = true;
    origin_ = counts;
    last_ = counts;
    last_ns_ = t_ns;
    pose_ = {};
    pose_.timestamp_ns = t_ns;
    return Status::Ok();
  }
  if (t_ns < last_ns_) {
    return InvalidArgument("RMP odometry: sample at " + std::to_string(t_ns) + " ns is older than the last one (" +
                           std::to_string(last_ns_) + " ns)");
  }
  const double dt = static_cast<double>(t_ns - last_ns_) * 1e-9;
  const double dl = options_.linear_scale * codec_.DistanceMeters(IntegratorDelta(counts.left, last_.left));
  const double dr = options_.linear_scale * codec_.DistanceMeters(IntegratorDelta(counts.right, last_.right));
  const double max_step = options_.max_speed_mps * dt + 0.1;
  if (std::abs(dl) > max_step || std::abs(dr) > max_step) {
    ++rejected_jumps_;
    last_ = counts;
    last_ns_ = t_ns;
    return OutOfRange("RMP odometry: wheel increments " + FormatNumber(dl) + " m, " + FormatNumber(dr) + " m in " +
                      FormatNumber(dt) + " s are impossible; sample taken as the new reference");
  }
  const double ds = 0.5 * (dl + dr);
  double dyaw = options_.angular_scale * (dr - dl) / options_.wheel_separation_m;
  if (options_.yaw_source == OdometryYawSource::kYawIntegrator) {
    dyaw = options_.angular_scale * codec_.YawRadians(IntegratorDelta(counts.yaw, last_.yaw));
  }
  // Constant-curvature arc over the increment (exact for a differential drive whose wheel speeds
  // are constant in between samples).
  const double yaw0 = pose_.yaw_rad;
  if (std::abs(dyaw) > 1e-9) {
    const double r = ds / dyaw;
    pose_.x_m += r * (std::sin(yaw0 + dyaw) - std::sin(yaw0));
    pose_.y_m -= r * (std::cos(yaw0 + dyaw) - std::cos(yaw0));
  } else {
    pose_.x_m += ds * std::cos(yaw0 + 0.5 * dyaw);
    pose_.y_m += ds * std::sin(yaw0 + 0.5 * dyaw);
  }
  pose_.yaw_rad += dyaw;
  pose_.distance_m += std::abs(ds);
  pose_.left_m += dl;
  pose_.right_m += dr;
  pose_.speed_mps = dt > 0.0 ? ds / dt : 0.0;
  pose_.yaw_rate_rps = dt > 0.0 ? dyaw / dt : 0.0;
  pose_.timestamp_ns = t_ns;
  last_ = counts;
  last_ns_ = t_ns;
  return Status::Ok();
}

}  // namespace idi::rmp
