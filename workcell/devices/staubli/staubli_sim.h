// The simulated RX-130 on its CS8 and rail carriage, beside the real driver: hal::ArmDevice and
// hal::RailDevice on a hal::Clock. Joint readings are quantised to the encoders (Table 4.2 counts
// per degree, in the controller's convention via staubli_joints.h), limits are the RX-130's, moves
// take |largest joint change| / (nominal speed x speed fraction), and the rail reads to 0.01 mm
// (§4.3 quotes the RTU position to within 0.1 mm). Faults can be injected for service-level tests.
#pragma once

#include <optional>
#include <string>

#include "shared/hal/arm.h"
#include "shared/hal/clock.h"

namespace idi::workcell {

struct SimStaubliOptions {
  std::string name = "sim-arm";
  double joint_speed_deg_per_s = 180;  // at 100 % (one nominal speed for all joints)
  double rail_speed_mm_per_s = 500;
  double rail_min_mm = 0, rail_max_mm = 6000;
  double rail_resolution_mm = 0.01;
  bool has_rail = true;
  Joints initial_q_rad{};
  Status Check() const;
};

class SimStaubli final : public hal::ArmDevice, public hal::RailDevice {
 public:
  SimStaubli(SimStaubliOptions options, hal::Clock* clock);

  std::string name() const override { return options_.name; }
  Status MoveJoints(const Joints& q_rad, const hal::MoveOptions& options) override;
  Result<hal::JointState> ReadJoints() override;
  Status Stop() override;
  Status MoveTo(double position_mm, const hal::MoveOptions& options) override;
  Result<hal::RailState> Read() override;

  void InjectFault(Status status) { fault_ = std::move(status); }
  int stops() const { return stops_; }

 private:
  Joints Quantised(const Joints& q) const;
  SimStaubliOptions options_;
  hal::Clock* clock_;
  Joints q_rad_{};
  double rail_mm_ = 0;
  std::optional<Status> fault_;
  int stops_ = 0;
};

}  // namespace idi::workcell
