// Wheel odometry from the RMP's 32-bit integrators (0x403 wheels, 0x404 fore/aft and yaw).
//
// The integrators are not zero at start and roll over (device-protocols.md §1.7), so the pose is
// built from increments: each sample's shortest signed difference to the previous one, in metres
// through the model's scale, integrated as a differential drive (wheel separation 0.54 m) along
// constant-curvature arcs. The first sample is the origin of the odometry frame (x forward, y
// left, yaw counter-clockwise), so a reset that does not take still gives a zeroed pose (the
// software offset). A jump no vehicle can make between two samples (garbage, or a reset taking
// effect mid-run) is refused and the sample becomes the new reference.
#pragma once

#include <cstdint>

#include "rmp/segway/rmp_codec.h"
#include "shared/util/status.h"

namespace idi::rmp {

struct RmpIntegratorCounts {
  uint32_t left = 0, right = 0, fore_aft = 0, yaw = 0;
};

enum class OdometryYawSource { kWheels, kYawIntegrator };

struct RmpOdometryOptions {
  double wheel_separation_m = 0.54;
  // Calibration factors (the integrators' scale is known to be off on some units, §1.7).
  double linear_scale = 1.0;
  double angular_scale = 1.0;
  OdometryYawSource yaw_source = OdometryYawSource::kWheels;
  // Refuse increments faster than this (plus a 10 cm margin) between two samples.
  double max_speed_mps = 10.0;

  Status Check() const;
};

struct RmpOdometryPose {
  int64_t timestamp_ns = 0;
  double x_m = 0.0, y_m = 0.0, yaw_rad = 0.0;  // odometry frame; yaw unwrapped
  double distance_m = 0.0;                     // path length
  double left_m = 0.0, right_m = 0.0;          // each wheel since the origin
  double speed_mps = 0.0, yaw_rate_rps = 0.0;  // over the last increment
};

class RmpOdometry {
 public:
  RmpOdometry(const RmpCodec& codec, const RmpOdometryOptions& options = {});

  // The next sample becomes the origin.
  void Reset();
  // One sample at `t_ns`. OutOfRange when the increment is implausible (the pose does not move and
  // the sample becomes the reference); InvalidArgument when time goes backwards.
  Status Update(int64_t t_ns, const RmpIntegratorCounts& counts);

  bool initialized() const { return initialized_; }
  const RmpOdometryPose& pose() const { return pose_; }
  // The raw counts of the origin sample (the software offset).
  const RmpIntegratorCounts& origin_counts() const { return origin_; }
  uint64_t rejected_jumps() const { return rejected_jumps_; }
  const RmpOdometryOptions& options() const { return options_; }

 private:
  RmpCodec codec_;
  RmpOdometryOptions options_;
  bool initialized_ = false;
  RmpIntegratorCounts origin_, last_;
  int64_t last_ns_ = 0;
  RmpOdometryPose pose_;
  uint64_t rejected_jumps_ = 0;
};

}  // namespace idi::rmp
