// The simulated Segway RMP: the twin's vehicle (shared/sim/vehicle) behind the RMP's CAN protocol,
// on the twin's virtual bus. It reads command frames (0x413) and configuration commands, drives the
// vehicle with them, and sends the status cycle 0x400..0x407 at 100 Hz plus the CU status 0x680,
// as the real RMP does (device-protocols.md §1). It sits beside the real driver and answers it the
// way an RMP 200 would, including the pitfalls: integrators that do not start at zero and roll over,
// a boot velocity scale of 3/4, and optionally an integrator reset that does not take.
//
// Faults: silence (no status, commands still taken), fault and low-battery bits, a battery drop,
// and bus-off through the virtual bus. It also counts command-timing violations (commands closer
// than 10 ms or further apart than 300 ms).
#pragma once

#include <cstdint>

#include "rmp/segway/rmp_codec.h"
#include "shared/sim/can/virtual_can_bus.h"
#include "shared/sim/vehicle/vehicle_twin.h"

namespace idi::rmp {

struct SimRmpOptions {
  RmpModel model = RmpModel::kRmp200;
  sim::VehicleTwinOptions vehicle;
  // The firmware's own command interpretation (the truth the driver's configuration must match).
  double turn_counts_per_radps = 1024.0 / 3.14159265358979323846;
  int turn_sign = +1;      // positive turn counts turn left
  int yaw_rate_sign = -1;  // reports clockwise as positive
  double status_period_s = 0.01;  // 100 Hz
  int cu_status_every_cycles = 10;
  uint16_t build_id = 0x0203;
  // Integrators at power-up (not zero, near rollover to exercise it).
  uint32_t initial_left_counts = 0xFFFF8000u;
  uint32_t initial_right_counts = 0x7FFFC000u;
  uint32_t initial_fore_aft_counts = 0xFFFFFF00u;
  uint32_t initial_yaw_counts = 0x00012345u;
  bool integrator_reset_works = true;  // false: the RMP 50 behaviour of ignoring it
  double boot_velocity_scale = 0.75;   // libsegwayrmp saw 3/4 at start-up
  double boot_accel_scale = 1.0;
  double boot_turn_scale = 1.0;
  OperationalMode boot_mode = OperationalMode::kTractor;
  GainSchedule boot_gain_schedule = GainSchedule::kLight;
  // Battery thresholds for the status bits.
  double low_battery_v = 68.0;
  double empty_battery_v = 62.0;

  Status Check() const;
};

struct SimRmpCounters {
  uint64_t commands = 0, config_commands = 0, bad_frames = 0, other_frames = 0;
  uint64_t commands_too_close = 0;  // < 10 ms after the previous one
  uint64_t command_gaps_too_long = 0;  // > 300 ms since the previous one
  uint64_t status_cycles = 0;
  uint64_t integrator_resets = 0;
  uint64_t shutdowns = 0;
};

class SimRmp final : public sim::SimProcess {
 public:
  // Adds an endpoint named "rmp" to `bus` and registers itself as a process. Aborts on options that
  // fail Check() (validate them first).
  SimRmp(sim::VirtualCanBus* bus, const SimRmpOptions& options);

  int64_t NextWakeNs() const override;
  void RunUntil(int64_t t_ns) override;

  sim::VehicleTwin& vehicle() { return vehicle_; }
  const sim::VehicleTwin& vehicle() const { return vehicle_; }
  sim::VirtualCanEndpoint* endpoint() const { return endpoint_; }
  const RmpCodec& codec() const { return codec_; }
  const SimRmpCounters& counters() const { return counters_; }
  OperationalMode mode() const { return mode_; }
  GainSchedule gain_schedule() const { return gain_; }
  double velocity_scale() const { return velocity_scale_; }
  double accel_scale() const { return accel_scale_; }
  double turn_scale() const { return turn_scale_; }
  double current_limit_scale() const { return current_limit_scale_; }
  bool balance_locked_out() const { return balance_locked_out_; }
  int last_velocity_counts() const { return echo_.velocity_counts; }
  int last_turn_counts() const { return echo_.turn_counts; }
  int64_t last_command_ns() const { return last_command_ns_; }

  // Faults.
  void SetSilent(bool silent) { silent_ = silent; }
  // Every status frame but the wheel integrators (0x403) is sent: a fault for the odometry's watchdog.
  void SetWheelIntegratorsMissing(bool missing) { integrators_missing_ = missing; }
  // Every status frame but the mode and battery frame (0x406).
  void SetModeFrameMissing(bool missing) { mode_missing_ = missing; }
  // Extra bits in status words 1 and 2 (e.g. kRmpStatus1MotorFeedbackFault). Fault bits also stop
  // the motors, as the firmware would.
  void SetInjectedStatusBits(uint16_t word1, uint16_t word2);
  // A power cycle (a brown-out, an e-stop reset): the boot scales, mode and gain schedule again, and
  // integrators counting from zero. Combine with SetSilent for the seconds it takes to boot.
  void Reboot();

 private:
  void HandleFrame(const hal::CanFrame& frame);
  void ApplyConfig(uint16_t id, uint16_t param);
  void SendStatusCycle();
  void UpdateMotorsEnabled();
  void ApplyScalesAndMode();  // the firmware's scaling and the twin's limits from the current settings

  SimRmpOptions options_;
  RmpCodec codec_;
  RmpCommandScaling firmware_scaling_;
  sim::VirtualCanBus* bus_;
  sim::VirtualCanEndpoint* endpoint_;
  sim::VehicleTwin vehicle_;
  int64_t next_status_ns_;
  uint64_t cycle_ = 0;
  SimRmpCounters counters_;
  RmpCommandEchoFrame echo_;
  int64_t last_command_ns_ = -1;
  OperationalMode mode_;
  GainSchedule gain_;
  bool balance_locked_out_ = false;
  double velocity_scale_, accel_scale_, turn_scale_;
  double current_limit_scale_ = 1.0;
  // Reported integrator = base + counts of the twin's measured value.
  uint32_t left_base_, right_base_, fore_aft_base_, yaw_base_;
  bool silent_ = false;
  bool mode_missing_ = false;
  bool integrators_missing_ = false;
  bool powered_down_ = false;
  uint16_t injected_word1_ = 0, injected_word2_ = 0;
};

}  // namespace idi::rmp
