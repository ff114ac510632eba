#include "shared/sim/vehicle/vehicle_twin.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace idi::sim {
namespace {

constexpr double kGravityMps2 = 9.81;
constexpr double kRollingResistance = 0.02;

// Moves `value` towards `goal` by at most `max_step`.
double StepTowards(double value, double goal, double max_step) {
  if (goal > value) return std::min(goal, value + max_step);
  return std::max(goal, value - max_step);
}

Status CheckPositive(const char* name, double v) {
  if (!(std::isfinite(v) && v > 0.0)) {
    return InvalidArgument(std::string("vehicle twin: ") + name + " = " + FormatNumber(v) +
                           " must be a positive number");
  }
  return Status::Ok();
}

Status CheckNonNegative(const char* name, double v) {
  if (!(std::isfinite(v) && v >= 0.0)) {
    return InvalidArgument(std::string("vehicle twin: ") + name + " = " + FormatNumber(v) +
                           " must be zero or positive");
  }
  return Status::Ok();
}

Status CheckFinite(const char* name, double v) {
  if (!std::isfinite(v)) return InvalidArgument(std::string("vehicle twin: ") + name + " is not a finite number");
  return Status::Ok();
}

}  // namespace

Status VehicleTwinOptions::Check() const {
  IDI_RETURN_IF_ERROR(CheckPositive("wheel_separation_m", wheel_separation_m));
  IDI_RETURN_IF_ERROR(CheckPositive("wheel_radius_m", wheel_radius_m));
  IDI_RETURN_IF_ERROR(CheckPositive("mass_kg", mass_kg));
  IDI_RETURN_IF_ERROR(CheckPositive("max_speed_mps", max_speed_mps));
  IDI_RETURN_IF_ERROR(CheckPositive("max_accel_mps2", max_accel_mps2));
  IDI_RETURN_IF_ERROR(CheckPositive("max_yaw_rate_rps", max_yaw_rate_rps));
  IDI_RETURN_IF_ERROR(CheckPositive("max_yaw_accel_rps2", max_yaw_accel_rps2));
  IDI_RETURN_IF_ERROR(CheckPositive("max_lateral_accel_mps2", max_lateral_accel_mps2));
  IDI_RETURN_IF_ERROR(CheckNonNegative("command_latency_s", command_latency_s));
  IDI_RETURN_IF_ERROR(CheckNonNegative("response_time_constant_s", response_time_constant_s));
  IDI_RETURN_IF_ERROR(CheckPositive("command_timeout_s", command_timeout_s));
  IDI_RETURN_IF_ERROR(CheckPositive("timeout_decel_mps2", timeout_decel_mps2));
  IDI_RETURN_IF_ERROR(CheckPositive("timeout_yaw_decel_rps2", timeout_yaw_decel_rps2));
  IDI_RETURN_IF_ERROR(CheckFinite("left_wheel_scale_error", left_wheel_scale_error));
  IDI_RETURN_IF_ERROR(CheckFinite("right_wheel_scale_error", right_wheel_scale_error));
  if (std::abs(left_wheel_scale_error) >= 0.5 || std::abs(right_wheel_scale_error) >= 0.5) {
    return InvalidArgument("vehicle twin: wheel scale errors must be within +-0.5 (got " +
                           FormatNumber(left_wheel_scale_error) + ", " + FormatNumber(right_wheel_scale_error) + ")");
  }
  IDI_RETURN_IF_ERROR(CheckNonNegative("slip_noise_m_per_sqrt_m", slip_noise_m_per_sqrt_m));
  IDI_RETURN_IF_ERROR(CheckNonNegative("wheel_speed_noise_mps", wheel_speed_noise_mps));
  IDI_RETURN_IF_ERROR(CheckNonNegative("gyro_noise_rps", gyro_noise_rps));
  IDI_RETURN_IF_ERROR(CheckFinite("gyro_bias_rps", gyro_bias_rps));
  IDI_RETURN_IF_ERROR(CheckNonNegative("tilt_noise_rad", tilt_noise_rad));
  IDI_RETURN_IF_ERROR(CheckPositive("base_battery_start_v", base_battery_start_v));
  IDI_RETURN_IF_ERROR(CheckNonNegative("base_battery_drain_v_per_h", base_battery_drain_v_per_h));
  IDI_RETURN_IF_ERROR(CheckNonNegative("base_battery_sag_v_per_nm", base_battery_sag_v_per_nm));
  IDI_RETURN_IF_ERROR(CheckPositive("ui_battery_start_v", ui_battery_start_v));
  IDI_RETURN_IF_ERROR(CheckNonNegative("ui_battery_drain_v_per_h", ui_battery_drain_v_per_h));
  IDI_RETURN_IF_ERROR(CheckFinite("start_x_m", start_x_m));
  IDI_RETURN_IF_ERROR(CheckFinite("start_y_m", start_y_m));
  IDI_RETURN_IF_ERROR(CheckFinite("start_yaw_rad", start_yaw_rad));
  IDI_RETURN_IF_ERROR(CheckPositive("step_s", step_s));
  if (step_s > 0.02) return InvalidArgument("vehicle twin: step_s = " + FormatNumber(step_s) + " is above 0.02 s");
  return Status::Ok();
}

VehicleTwin::VehicleTwin(const VehicleTwinOptions& options, int64_t start_ns)
    : options_(options), now_ns_(start_ns), rng_(options.seed), last_command_received_ns_(start_ns) {
  const Status st = options_.Check();
  IDI_CHECK(st.ok(), st.ToString());
  truth_.timestamp_ns = start_ns;
  truth_.x_m = options_.start_x_m;
  truth_.y_m = options_.start_y_m;
  truth_.yaw_rad = options_.start_yaw_rad;
  sensors_.base_battery_v = options_.base_battery_start_v;
  sensors_.ui_battery_v = options_.ui_battery_start_v;
}

void VehicleTwin::Command(int64_t t_ns, const VehicleCommand& in) {
  // The firmware receives integer counts: a value that is not a number cannot reach it (it would
  // otherwise turn the whole state into NaN).
  VehicleCommand command = in;
  if (!std::isfinite(command.speed_mps)) command.speed_mps = 0.0;
  if (!std::isfinite(command.yaw_rate_rps)) command.yaw_rate_rps = 0.0;
  const int64_t received = std::max(t_ns, now_ns_);
  last_command_received_ns_ = std::max(last_command_received_ns_, received);
  have_command_ = true;
  // With the motors off the firmware ignores commands: none of them acts once they are on again.
  if (!motors_enabled_) return;
  const int64_t effective = received + static_cast<int64_t>(std::llround(options_.command_latency_s * 1e9));
  // Commands arrive in order; a late one with an earlier time still queues behind the others.
  const int64_t after = pending_.empty() ? effective : std::max(effective, pending_.back().effective_ns);
  pending_.push_back({after, received, command});
}

void VehicleTwin::SetMotorsEnabled(bool enabled) {
  if (!enabled) {
    pending_.clear();
    commanded_ = VehicleCommand{};
  }
  motors_enabled_ = enabled;
}

namespace {
// A scale fraction in [0, 1]; NaN is 0 (std::clamp passes NaN through, and a NaN limit is no limit).
double Fraction(double f) { return std::isnan(f) ? 0.0 : std::clamp(f, 0.0, 1.0); }
}  // namespace

void VehicleTwin::SetSpeedScale(double fraction) { speed_scale_ = Fraction(fraction); }
void VehicleTwin::SetAccelScale(double fraction) { accel_scale_ = Fraction(fraction); }
void VehicleTwin::SetTurnScale(double fraction) { turn_scale_ = Fraction(fraction); }

void VehicleTwin::ResetIntegrators(bool left, bool right, bool yaw, bool fore_aft) {
  if (left) sensors_.left_wheel_m = 0.0;
  if (right) sensors_.right_wheel_m = 0.0;
  if (yaw) sensors_.yaw_rad = 0.0;
  if (fore_aft) sensors_.fore_aft_m = 0.0;
}

void VehicleTwin::AdvanceTo(int64_t t_ns) {
  const int64_t step_ns = std::max<int64_t>(1, static_cast<int64_t>(std::llround(options_.step_s * 1e9)));
  while (now_ns_ < t_ns) {
    const int64_t dt_ns = std::min(step_ns, t_ns - now_ns_);
    Step(static_cast<double>(dt_ns) * 1e-9);
    now_ns_ += dt_ns;
    truth_.timestamp_ns = now_ns_;
  }
}

void VehicleTwin::Step(double dt) {
  const VehicleTwinOptions& o = options_;
  while (!pending_.empty() && pending_.front().effective_ns <= now_ns_) {
    commanded_ = pending_.front().command;
    pending_.pop_front();
  }
  timed_out_ = have_command_ && static_cast<double>(now_ns_ - last_command_received_ns_) * 1e-9 > o.command_timeout_s;
  // A timeout or disabled motors drop the last command: the firmware does not bring it back when
  // commands resume (until the new one takes effect, the target is zero).
  if (timed_out_ || !motors_enabled_) commanded_ = VehicleCommand{};

  // What the platform is asked to follow. On a timeout or with the motors off the firmware ramps
  // its target to zero; otherwise the last command, within the configured limits.
  const double v_max = o.max_speed_mps * speed_scale_;
  const double w_max = o.max_yaw_rate_rps * turn_scale_;
  if (!motors_enabled_ || timed_out_ || !have_command_) {
    target_.speed_mps = StepTowards(target_.speed_mps, 0.0, o.timeout_decel_mps2 * dt);
    target_.yaw_rate_rps = StepTowards(target_.yaw_rate_rps, 0.0, o.timeout_yaw_decel_rps2 * dt);
  } else {
    target_.speed_mps = std::clamp(commanded_.speed_mps, -v_max, v_max);
    target_.yaw_rate_rps = std::clamp(commanded_.yaw_rate_rps, -w_max, w_max);
  }
  const double v_abs = std::abs(truth_.speed_mps);
  if (v_abs > 1e-3) {
    const double w_lat = o.max_lateral_accel_mps2 / v_abs;
    target_.yaw_rate_rps = std::clamp(target_.yaw_rate_rps, -w_lat, w_lat);
  }

  // First-order lag within the acceleration limits.
  const double a_max = (motors_enabled_ && !timed_out_) ? o.max_accel_mps2 * std::max(accel_scale_, 0.05)
                                                        : std::max(o.timeout_decel_mps2, o.max_accel_mps2);
  const double wdot_max = o.max_yaw_accel_rps2;
  const double tau = o.response_time_constant_s;
  const double v_old = truth_.speed_mps, w_old = truth_.yaw_rate_rps;
  const double dv_want = tau > 0.0 ? (target_.speed_mps - v_old) * std::min(1.0, dt / tau) : target_.speed_mps - v_old;
  const double dw_want = tau > 0.0 ? (target_.yaw_rate_rps - w_old) * std::min(1.0, dt / tau) : target_.yaw_rate_rps - w_old;
  const double v_new = v_old + std::clamp(dv_want, -a_max * dt, a_max * dt);
  double w_new = w_old + std::clamp(dw_want, -wdot_max * dt, wdot_max * dt);
  // Traction: the lateral acceleration of the actual motion stays within its limit.
  if (std::abs(v_new) > 1e-3) {
    const double w_lat = o.max_lateral_accel_mps2 / std::abs(v_new);
    w_new = std::clamp(w_new, -w_lat, w_lat);
  }

  // Pose: trapezoidal speed and yaw rate over the step, heading at the step's middle.
  const double ds = 0.5 * (v_old + v_new) * dt;
  const double dyaw = 0.5 * (w_old + w_new) * dt;
  const double mid = truth_.yaw_rad + 0.5 * dyaw;
  truth_.x_m += ds * std::cos(mid);
  truth_.y_m += ds * std::sin(mid);
  truth_.yaw_rad += dyaw;
  truth_.accel_mps2 = (v_new - v_old) / dt;
  truth_.speed_mps = v_new;
  truth_.yaw_rate_rps = w_new;
  truth_.distance_m += std::abs(ds);
  const double half_b = 0.5 * o.wheel_separation_m;
  const double dl = ds - dyaw * half_b;
  const double dr = ds + dyaw * half_b;
  truth_.left_wheel_m += dl;
  truth_.right_wheel_m += dr;
  truth_.left_wheel_mps = v_new - w_new * half_b;
  truth_.right_wheel_mps = v_new + w_new * half_b;

  // Encoders: scale error and slip (variance proportional to the distance rolled).
  const double dl_meas = dl * (1.0 + o.left_wheel_scale_error) + o.slip_noise_m_per_sqrt_m * std::sqrt(std::abs(dl)) * gauss_(rng_);
  const double dr_meas = dr * (1.0 + o.right_wheel_scale_error) + o.slip_noise_m_per_sqrt_m * std::sqrt(std::abs(dr)) * gauss_(rng_);
  sensors_.left_wheel_m += dl_meas;
  sensors_.right_wheel_m += dr_meas;
  sensors_.fore_aft_m += 0.5 * (dl_meas + dr_meas);
  sensors_.left_wheel_mps = truth_.left_wheel_mps * (1.0 + o.left_wheel_scale_error) + o.wheel_speed_noise_mps * gauss_(rng_);
  sensors_.right_wheel_mps = truth_.right_wheel_mps * (1.0 + o.right_wheel_scale_error) + o.wheel_speed_noise_mps * gauss_(rng_);
  const double gyro = w_new + o.gyro_bias_rps + o.gyro_noise_rps * gauss_(rng_);
  sensors_.yaw_rate_rps = gyro;
  sensors_.yaw_rad += gyro * dt;

  // Balance mode leans into the acceleration (an inverted pendulum keeps its centre of mass over
  // the wheels' contact point while accelerating, §3.7).
  // The platform's pitch follows that lean with a first-order lag of kPitchLagS (its balance loop): the
  // lean is a step wherever the acceleration is, and the difference of steps over a step of a few us
  // (AdvanceTo to a frame's time) gave pitch rates of 1e5 rad/s.
  constexpr double kPitchLagS = 0.1;
  const double lean = balance_mode_ ? std::atan2(truth_.accel_mps2, kGravityMps2) : 0.0;
  const double pitch_clean = pitch_clean_rad_ + (lean - pitch_clean_rad_) * std::min(1.0, dt / kPitchLagS);
  const double pitch_rate_clean = (pitch_clean - pitch_clean_rad_) / dt;
  pitch_clean_rad_ = pitch_clean;
  sensors_.pitch_rad = pitch_clean + o.tilt_noise_rad * gauss_(rng_);
  sensors_.pitch_rate_rps = pitch_rate_clean + o.tilt_noise_rad * gauss_(rng_);
  sensors_.roll_rad = o.tilt_noise_rad * gauss_(rng_);
  sensors_.roll_rate_rps = o.tilt_noise_rad * gauss_(rng_);

  // Torques: half the mass per wheel, plus rolling resistance.
  auto wheel_torque = [&](double v_wheel_new, double v_wheel_old) {
    const double a = (v_wheel_new - v_wheel_old) / dt;
    const double roll = std::abs(v_wheel_new) > 1e-3 ? std::copysign(kRollingResistance * 0.5 * o.mass_kg * kGravityMps2, v_wheel_new) : 0.0;
    return (0.5 * o.mass_kg * a + roll) * o.wheel_radius_m;
  };
  sensors_.left_torque_nm = wheel_torque(truth_.left_wheel_mps, prev_left_mps_);
  sensors_.right_torque_nm = wheel_torque(truth_.right_wheel_mps, prev_right_mps_);
  prev_left_mps_ = truth_.left_wheel_mps;
  prev_right_mps_ = truth_.right_wheel_mps;

  elapsed_s_ += dt;
  const double hours = elapsed_s_ / 3600.0;
  sensors_.base_battery_v = o.base_battery_start_v - o.base_battery_drain_v_per_h * hours -
                            o.base_battery_sag_v_per_nm * (std::abs(sensors_.left_torque_nm) + std::abs(sensors_.right_torque_nm)) -
                            battery_drop_v_;
  sensors_.ui_battery_v = o.ui_battery_start_v - o.ui_battery_drain_v_per_h * hours;
}

}  // namespace idi::sim
