// The vehicle of the digital twin: a Segway RMP (dissertation §3.7, §8.12.4) moving as a
// differential drive on flat ground, with what its firmware and sensors add between a command and
// the numbers it reports:
//
// - commands act after a latency and are limited in speed, acceleration, yaw rate, yaw
//   acceleration and lateral acceleration; the platform follows them with a first-order lag;
// - the firmware keeps the last command for `command_timeout_s` (0.4 s on the RMP) after commands
//   stop, then ramps speed and turn rate to zero (device-protocols.md §1.5);
// - wheel odometry has a scale error per wheel and slip noise (a random walk whose variance grows
//   with the distance each wheel rolls); wheel speeds and the yaw-rate gyro are noisy;
// - pitch follows acceleration in balance mode; motor torques follow the wheels' accelerations;
// - the powerbase battery drains with time and load.
//
// Everything runs on simulated time (nanoseconds, the SimClock's time line) with seeded noise, so the
// same options give the same run. Ground truth (truth()) is for tests and reports; what a real
// device would report is in sensors().
#pragma once

#include <cstdint>
#include <deque>
#include <random>

#include "shared/util/status.h"

namespace idi::sim {

struct VehicleTwinOptions {
  double wheel_separation_m = 0.54;  // device-protocols.md §1.4
  double wheel_radius_m = 0.24;      // RMP 200 tyre
  double mass_kg = 80.0;             // platform plus payload (for torques)
  // Limits at 100 % configuration scales. 3.576 m/s is 8 mph, the RMP's full-scale velocity command.
  double max_speed_mps = 3.576;
  double max_accel_mps2 = 1.5;
  double max_yaw_rate_rps = 3.14159265358979;  // ORCA's "1024 counts ~ pi rad/s"
  double max_yaw_accel_rps2 = 6.0;
  double max_lateral_accel_mps2 = 0.5 * 9.81;  // ORCA models 0.5 g at speed
  // Response: the command takes effect after the latency, then the platform follows it with a
  // first-order lag of this time constant, within the acceleration limits.
  double command_latency_s = 0.05;
  double response_time_constant_s = 0.08;
  // Communication-loss protection in the firmware.
  double command_timeout_s = 0.4;
  double timeout_decel_mps2 = 1.0;
  double timeout_yaw_decel_rps2 = 2.0;
  // Odometry: measured wheel distance = true * (1 + scale error) + slip; slip is a random walk
  // with standard deviation slip_noise * sqrt(distance rolled) per wheel.
  double left_wheel_scale_error = 0.0;
  double right_wheel_scale_error = 0.0;
  double slip_noise_m_per_sqrt_m = 0.0;
  double wheel_speed_noise_mps = 0.0;
  double gyro_noise_rps = 0.0;  // white noise on the reported yaw rate
  double gyro_bias_rps = 0.0;
  double tilt_noise_rad = 0.0;  // on pitch and roll
  // Battery: powerbase (72 V nominal) and UI (12 V nominal).
  double base_battery_start_v = 76.0;
  double base_battery_drain_v_per_h = 3.0;
  double base_battery_sag_v_per_nm = 0.02;  // under motor torque
  double ui_battery_start_v = 12.6;
  double ui_battery_drain_v_per_h = 0.3;
  // Start pose in the world (truth).
  double start_x_m = 0.0, start_y_m = 0.0, start_yaw_rad = 0.0;
  double step_s = 0.001;  // integration step
  uint64_t seed = 1;

  // InvalidArgument naming the field for a non-positive limit, a negative noise level, a NaN, ...
  Status Check() const;
};

// Speed along the heading and yaw rate (counter-clockwise positive), as the firmware receives them.
struct VehicleCommand {
  double speed_mps = 0.0;
  double yaw_rate_rps = 0.0;
};

// Ground truth (world frame, x forward at start, y left, yaw counter-clockwise).
struct VehicleTruth {
  int64_t timestamp_ns = 0;
  double x_m = 0.0, y_m = 0.0, yaw_rad = 0.0;  // yaw unwrapped
  double speed_mps = 0.0, yaw_rate_rps = 0.0, accel_mps2 = 0.0;
  double left_wheel_mps = 0.0, right_wheel_mps = 0.0;
  double left_wheel_m = 0.0, right_wheel_m = 0.0;  // signed distance each wheel rolled
  double distance_m = 0.0;                          // path length of the centre
};

// What the firmware measures and would report.
struct VehicleSensors {
  double left_wheel_m = 0.0, right_wheel_m = 0.0;  // encoder-integrated, with scale error and slip
  double fore_aft_m = 0.0;                         // mean of the two wheels
  double yaw_rad = 0.0;                            // integrated gyro, counter-clockwise
  double left_wheel_mps = 0.0, right_wheel_mps = 0.0;
  double yaw_rate_rps = 0.0;
  double pitch_rad = 0.0, pitch_rate_rps = 0.0, roll_rad = 0.0, roll_rate_rps = 0.0;
  double left_torque_nm = 0.0, right_torque_nm = 0.0;
  double base_battery_v = 0.0, ui_battery_v = 0.0;
};

class VehicleTwin {
 public:
  // Aborts on options that fail Check(): validate them first (they come from configuration).
  explicit VehicleTwin(const VehicleTwinOptions& options, int64_t start_ns = 0);

  // A command as the firmware received it at `t_ns` (>= the current time). It takes effect
  // command_latency_s later.
  void Command(int64_t t_ns, const VehicleCommand& command);
  // Integrates to `t_ns` (no-op if not later than now).
  void AdvanceTo(int64_t t_ns);
  int64_t now_ns() const { return now_ns_; }

  const VehicleTruth& truth() const { return truth_; }
  const VehicleSensors& sensors() const { return sensors_; }
  const VehicleTwinOptions& options() const { return options_; }

  // The RMP's configuration scales (fractions of the full limits, 0..1).
  void SetSpeedScale(double fraction);
  void SetAccelScale(double fraction);
  void SetTurnScale(double fraction);
  double speed_scale() const { return speed_scale_; }
  double accel_scale() const { return accel_scale_; }
  double turn_scale() const { return turn_scale_; }
  // Balance mode leans into accelerations; tractor mode does not.
  void SetBalanceMode(bool balance) { balance_mode_ = balance; }
  // Motors disabled (disabled mode, power down, a motor fault, an E-stop): the platform brakes to a
  // stop at the timeout deceleration and ignores commands until enabled.
  void SetMotorsEnabled(bool enabled);
  bool motors_enabled() const { return motors_enabled_; }
  // Zeroes the encoder and gyro integrators (the RMP's "reset integrators" command).
  void ResetIntegrators(bool left, bool right, bool yaw, bool fore_aft);
  // Fault injection: the powerbase battery voltage drops by this much (a low or failing battery).
  void SetBatteryDrop(double volts) { battery_drop_v_ = volts; }

  // True while the firmware's communication-loss ramp is active.
  bool command_timed_out() const { return timed_out_; }
  // The command the platform is currently following (after latency and timeout handling).
  VehicleCommand active_target() const { return target_; }

 private:
  struct PendingCommand {
    int64_t effective_ns;
    int64_t received_ns;
    VehicleCommand command;
  };
  void Step(double dt_s);

  VehicleTwinOptions options_;
  int64_t now_ns_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> gauss_{0.0, 1.0};
  std::deque<PendingCommand> pending_;
  VehicleCommand commanded_;  // last command in effect (before limits)
  VehicleCommand target_;     // what the platform follows now
  int64_t last_command_received_ns_;
  bool have_command_ = false;
  bool timed_out_ = false;
  bool balance_mode_ = true;
  bool motors_enabled_ = true;
  double speed_scale_ = 1.0, accel_scale_ = 1.0, turn_scale_ = 1.0;
  double battery_drop_v_ = 0.0;
  double elapsed_s_ = 0.0;
  double prev_left_mps_ = 0.0, prev_right_mps_ = 0.0;
  double pitch_clean_rad_ = 0.0;  // pitch before sensor noise
  VehicleTruth truth_;
  VehicleSensors sensors_;
};

}  // namespace idi::sim
