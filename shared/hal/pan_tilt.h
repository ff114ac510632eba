// Pan-tilt units (Directed Perception PTU-D46) carrying the Biclops cameras or the RMP's cameras.
// Angles in radians in the unit's own convention (pan about frame 0's z, tilt the DH joint of eq. 3.13).
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

#include "shared/util/status.h"

namespace idi::hal {

struct PanTiltState {
  int64_t timestamp_ns = 0;
  double pan_rad = 0;
  double tilt_rad = 0;
};

struct PanTiltLimits {
  double pan_min_rad = 0, pan_max_rad = 0;
  double tilt_min_rad = 0, tilt_max_rad = 0;
  double pan_resolution_rad = 0, tilt_resolution_rad = 0;  // one position step (read with PR/TR)
  bool Contains(double pan, double tilt) const {
    return pan >= pan_min_rad && pan <= pan_max_rad && tilt >= tilt_min_rad && tilt <= tilt_max_rad;
  }
};

class PanTiltDevice {
 public:
  virtual ~PanTiltDevice() = default;
  virtual std::string name() const = 0;
  virtual Result<PanTiltLimits> Limits() = 0;
  // Moves to the nearest positions and blocks until reached. OutOfRange outside the limits.
  virtual Status MoveTo(double pan_rad, double tilt_rad, std::chrono::milliseconds timeout) = 0;
  virtual Result<PanTiltState> Read() = 0;
  virtual Status Halt() = 0;
};

}  // namespace idi::hal
