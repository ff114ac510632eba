// The simulated BH8-262 beside the real driver: hal::GripperDevice on a hal::Clock. Motions take
// simulated time at the hand's speed, positions are quantised to encoder counts (the driver's
// factors), the hand must be initialised first, and a closing finger stalls where it meets an object
// (the inner link stops, §3.5). A fault can be injected for service-level tests.
#pragma once

#include <array>
#include <optional>
#include <string>

#include "shared/hal/arm.h"
#include "shared/hal/clock.h"

namespace idi::workcell {

struct SimGripperOptions {
  std::string name = "sim-barrett";
  double finger_closed_rad = 140.0 * 3.14159265358979323846 / 180.0;
  double spread_max_rad = 3.14159265358979323846;
  double finger_speed_rad_per_s = 2.0;
  double spread_speed_rad_per_s = 3.0;
  double init_duration_s = 3.0;
  double finger_counts_per_rad = 17800.0 / (140.0 * 3.14159265358979323846 / 180.0);
  double spread_counts_per_rad = 3150.0 / 3.14159265358979323846;
  Status Check() const;
};

class SimGripper final : public hal::GripperDevice {
 public:
  SimGripper(SimGripperOptions options, hal::Clock* clock);

  Status Initialize() override;
  Status Open() override;
  Status Close() override;
  Status SetSpread(double spread_rad) override;
  Result<hal::GripperState> Read() override;
  Status Stop() override;

  // An object between the fingers: finger i's inner link stops at `contact_rad` when closing.
  void SetObject(std::array<std::optional<double>, 3> contact_rad) { contact_rad_ = contact_rad; }
  void InjectFault(Status status) { fault_ = std::move(status); }
  int stops() const { return stops_; }

 private:
  Status MoveFingers(const std::array<double, 3>& goal);
  double Quantise(double rad, double counts_per_rad) const;
  SimGripperOptions options_;
  hal::Clock* clock_;
  bool initialized_ = false;
  std::array<double, 3> finger_rad_{};
  double spread_rad_ = 0;
  std::array<std::optional<double>, 3> contact_rad_{};
  std::optional<Status> fault_;
  int stops_ = 0;
};

}  // namespace idi::workcell
