// The simulated PTU-D46 beside the real driver: same hal::PanTiltDevice, on a hal::Clock (a SimClock
// makes moves take simulated time). Angles are quantised to the unit's position resolution, limits
// are enforced in positions as the unit does, and moves take |distance| / speed. A fault can be
// injected so service-level tests see the errors the real driver reports.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include "shared/hal/clock.h"
#include "shared/hal/pan_tilt.h"

namespace idi::workcell {

struct SimPtuOptions {
  std::string name = "sim-ptu";
  double pan_arcsec = 185.1428, tilt_arcsec = 185.1428;  // PTU-46-17.5
  int32_t pan_min = -3090, pan_max = 3090, tilt_min = -907, tilt_max = 604;
  double speed_pos_per_s = 2000;
  Status Check() const;
};

class SimPanTilt final : public hal::PanTiltDevice {
 public:
  // `clock` must outlive the device.
  SimPanTilt(SimPtuOptions options, hal::Clock* clock);

  std::string name() const override { return options_.name; }
  Result<hal::PanTiltLimits> Limits() override;
  Status MoveTo(double pan_rad, double tilt_rad, std::chrono::milliseconds timeout) override;
  Result<hal::PanTiltState> Read() override;
  Status Halt() override;

  // The next call (other than Halt) fails with `status`; a failing move halts where it is.
  void InjectFault(Status status) { fault_ = std::move(status); }
  int32_t pan_position() const { return pan_; }
  int32_t tilt_position() const { return tilt_; }
  int halts() const { return halts_; }

 private:
  std::optional<Status> TakeFault();
  SimPtuOptions options_;
  hal::Clock* clock_;
  int32_t pan_ = 0, tilt_ = 0;
  int halts_ = 0;
  std::optional<Status> fault_;
};

}  // namespace idi::workcell
