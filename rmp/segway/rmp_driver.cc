#include "rmp/segway/rmp_driver.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

namespace idi::rmp {
namespace {

constexpr std::size_t kRecentSentCapacity = 256;
constexpr std::size_t kRecentEventsCapacity = 64;
constexpr std::size_t kTurnWindow = 500;
constexpr int kMaxDrainPerPoll = 10000;
// Inhibits that are faults (logged when they change), as opposed to "no command yet".
constexpr uint32_t kRmpFaultInhibits = kRmpInhibitStatusStale | kRmpInhibitBusOff | kRmpInhibitBusError |
                                       kRmpInhibitLowBattery | kRmpInhibitRmpFault | kRmpInhibitTurnSignMismatch;

Status CheckFraction(const char* name, double v, double min_exclusive) {
  if (!(std::isfinite(v) && v > min_exclusive && v <= 1.0)) {
    return InvalidArgument(std::string("RMP driver: ") + name + " = " + FormatNumber(v) + " must be in (" +
                           FormatNumber(min_exclusive) + ", 1]");
  }
  return Status::Ok();
}

Status CheckPositiveValue(const char* name, double v) {
  if (!(std::isfinite(v) && v > 0.0)) {
    return InvalidArgument(std::string("RMP driver: ") + name + " = " + FormatNumber(v) + " must be positive");
  }
  return Status::Ok();
}

std::string DriverSeconds(int64_t ns) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.3f s", static_cast<double>(ns) * 1e-9);
  return buf;
}

}  // namespace

const char* RmpDriverStateName(RmpDriverState state) {
  switch (state) {
    case RmpDriverState::kIdle: return "idle";
    case RmpDriverState::kConnecting: return "connecting";
    case RmpDriverState::kConfiguring: return "configuring";
    case RmpDriverState::kResettingOdometry: return "resetting odometry";
    case RmpDriverState::kRunning: return "running";
    case RmpDriverState::kShuttingDown: return "shutting down";
    case RmpDriverState::kStopped: return "stopped";
  }
  return "?";
}

const char* OdometryResetResultName(OdometryResetResult r) {
  switch (r) {
    case OdometryResetResult::kPending: return "pending";
    case OdometryResetResult::kConfirmed: return "confirmed";
    case OdometryResetResult::kSoftwareOffset: return "software offset";
    case OdometryResetResult::kNotRequested: return "not requested";
  }
  return "?";
}

std::string DescribeRmpInhibits(uint32_t mask) {
  static const std::pair<uint32_t, const char*> kNames[] = {
      {kRmpInhibitNotRunning, "not running"},         {kRmpInhibitNoCommand, "no command"},
      {kRmpInhibitStaleCommand, "stale command"},     {kRmpInhibitStopRequested, "stop requested"},
      {kRmpInhibitStatusStale, "status stale"},       {kRmpInhibitBusOff, "bus-off"},
      {kRmpInhibitBusError, "bus error"},             {kRmpInhibitLowBattery, "low battery"},
      {kRmpInhibitRmpFault, "RMP fault bit"},         {kRmpInhibitTurnSignMismatch, "turn direction wrong"},
  };
  std::string s;
  for (const auto& [bit, name] : kNames) {
    if (mask & bit) {
      if (!s.empty()) s += ", ";
      s += name;
    }
  }
  return s.empty() ? "none" : s;
}

Status RmpDriverOptions::Check() const {
  IDI_RETURN_IF_ERROR(codec.Check());
  if (!(std::isfinite(velocity_counts_per_mps) && velocity_counts_per_mps >= 0.0)) {
    return InvalidArgument("RMP driver: velocity_counts_per_mps must be >= 0 (0 = the model's scale)");
  }
  IDI_RETURN_IF_ERROR(CheckPositiveValue("turn_counts_per_radps", turn_counts_per_radps));
  if (turn_sign != 1 && turn_sign != -1) return InvalidArgument("RMP driver: turn_sign must be +1 or -1");
  // The RMP wants a command at least every 300 ms and at most every 10 ms.
  if (!(std::isfinite(command_rate_hz) && command_rate_hz >= 1.0 / 0.3 && command_rate_hz <= 100.0)) {
    return InvalidArgument("RMP driver: command_rate_hz = " + FormatNumber(command_rate_hz) +
                           " is outside 3.4..100 Hz (the RMP needs a command every 10..300 ms)");
  }
  IDI_RETURN_IF_ERROR(CheckPositiveValue("max_input_age_s", max_input_age_s));
  if (!(std::isfinite(max_input_future_s) && max_input_future_s >= 0.0)) {
    return InvalidArgument("RMP driver: max_input_future_s must be >= 0");
  }
  IDI_RETURN_IF_ERROR(CheckPositiveValue("status_timeout_s", status_timeout_s));
  if (!(std::isfinite(reconfigure_after_silence_s) && reconfigure_after_silence_s > status_timeout_s)) {
    return InvalidArgument("RMP driver: reconfigure_after_silence_s must be finite and longer than status_timeout_s");
  }
  if (max_input_age_s > kMaxInputAgeLimitS || status_timeout_s > kStatusTimeoutLimitS) {
    return InvalidArgument("RMP driver: max_input_age_s = " + FormatNumber(max_input_age_s) + " (at most " +
                           FormatNumber(kMaxInputAgeLimitS) +
                           " s) and status_timeout_s = " + FormatNumber(status_timeout_s) + " (at most " +
                           FormatNumber(kStatusTimeoutLimitS) + " s): longer is driving on stale data");
  }
  IDI_RETURN_IF_ERROR(CheckFraction("velocity_scale", velocity_scale, 1.0 / 16.0 - 1e-9));
  IDI_RETURN_IF_ERROR(CheckFraction("accel_scale", accel_scale, 0.0));
  IDI_RETURN_IF_ERROR(CheckFraction("turn_scale", turn_scale, 1.0 / 16.0 - 1e-9));
  if (current_limit_scale >= 0.0) IDI_RETURN_IF_ERROR(CheckFraction("current_limit_scale", current_limit_scale, 0.0));
  if (static_cast<uint16_t>(gain_schedule) > 2) return InvalidArgument("RMP driver: gain_schedule must be light, tall or heavy");
  if (operational_mode != OperationalMode::kTractor && operational_mode != OperationalMode::kBalance) {
    return InvalidArgument(std::string("RMP driver: operational_mode must be tractor or balance, got ") +
                           OperationalModeName(operational_mode));
  }
  if (config_repeats < 1 || config_repeats > 10) return InvalidArgument("RMP driver: config_repeats must be 1..10");
  if (mode_retries < 0 || mode_retries > 20) return InvalidArgument("RMP driver: mode_retries must be 0..20");
  IDI_RETURN_IF_ERROR(CheckPositiveValue("config_verify_timeout_s", config_verify_timeout_s));
  IDI_RETURN_IF_ERROR(CheckPositiveValue("integrator_reset_timeout_s", integrator_reset_timeout_s));
  IDI_RETURN_IF_ERROR(CheckPositiveValue("integrator_reset_tolerance_m", integrator_reset_tolerance_m));
  if (!(min_base_battery_v >= 0.0 && min_ui_battery_v >= 0.0)) {
    return InvalidArgument("RMP driver: battery limits must be >= 0 V");
  }
  IDI_RETURN_IF_ERROR(CheckPositiveValue("turn_check_min_yaw_rate_rps", turn_check_min_yaw_rate_rps));
  IDI_RETURN_IF_ERROR(CheckPositiveValue("turn_check_max_speed_mps", turn_check_max_speed_mps));
  IDI_RETURN_IF_ERROR(CheckPositiveValue("turn_check_settle_s", turn_check_settle_s));
  if (turn_check_min_samples < 5) return InvalidArgument("RMP driver: turn_check_min_samples must be >= 5");
  IDI_RETURN_IF_ERROR(CheckPositiveValue("turn_check_tolerance", turn_check_tolerance));
  IDI_RETURN_IF_ERROR(CheckPositiveValue("bus_off_recovery_s", bus_off_recovery_s));
  if (shutdown_zero_frames < 1) return InvalidArgument("RMP driver: shutdown_zero_frames must be >= 1");
  return odometry.Check();
}

Result<std::unique_ptr<RmpDriver>> RmpDriver::Create(hal::CanBus* bus, hal::Clock* clock, const RmpDriverOptions& options) {
  if (bus == nullptr || clock == nullptr) return InvalidArgument("RMP driver: needs a CAN bus and a clock");
  IDI_RETURN_IF_ERROR(options.Check());
  return std::unique_ptr<RmpDriver>(new RmpDriver(bus, clock, options));
}

RmpDriver::RmpDriver(hal::CanBus* bus, hal::Clock* clock, const RmpDriverOptions& options)
    : bus_(bus),
      clock_(clock),
      options_(options),
      codec_(options.codec),
      odometry_(codec_, options.odometry),
      period_ns_(static_cast<int64_t>(std::llround(1e9 / options.command_rate_hz))) {
  scaling_.velocity_counts_per_mps =
      options_.velocity_counts_per_mps > 0.0 ? options_.velocity_counts_per_mps : codec_.scales().wheel_speed_counts_per_mps;
  scaling_.turn_counts_per_radps = options_.turn_counts_per_radps;
  scaling_.turn_sign = options_.turn_sign;
  // Commands are divided by the scales the RMP will multiply them with: the values actually sent.
  scaling_.velocity_scale_fraction = MakeScaleConfig(RmpConfigId::kMaxVelocityScale, options_.velocity_scale)->param / 16.0;
  scaling_.turn_scale_fraction = MakeScaleConfig(RmpConfigId::kMaxTurnScale, options_.turn_scale)->param / 16.0;
}

RmpDriver::~RmpDriver() {
  // Last resort: never leave without a zero command on the bus.
  if (Sending()) {
    hal::CanFrame f = EncodeCommandFrame(RmpCommandFrame{});
    f.timestamp_ns = clock_->NowNs();
    if (bus_->Send(f).ok()) LogFrame(f, replay::CanDirection::kTransmitted);
  }
}

bool RmpDriver::Sending() const {
  return health_.state != RmpDriverState::kIdle && health_.state != RmpDriverState::kStopped;
}

void RmpDriver::Event(const std::string& what) {
  const int64_t now = clock_->NowNs();
  health_.last_event = what;
  recent_events_.push_back(DriverSeconds(now) + ": " + what);
  if (recent_events_.size() > kRecentEventsCapacity) recent_events_.pop_front();
  if (event_sink_) event_sink_(now, what);
}

void RmpDriver::SetState(RmpDriverState state, const std::string& why) {
  if (state == health_.state) return;
  Event(std::string("state ") + RmpDriverStateName(health_.state) + " -> " + RmpDriverStateName(state) +
        (why.empty() ? "" : " (" + why + ")"));
  health_.state = state;
}

Status RmpDriver::Start() {
  if (health_.state != RmpDriverState::kIdle) {
    return FailedPrecondition(std::string("RMP driver on ") + bus_->name() + ": already started (" +
                              RmpDriverStateName(health_.state) + ")");
  }
  SetState(RmpDriverState::kConnecting, "on " + bus_->name());
  next_send_ns_ = clock_->NowNs();
  MaybeTick(clock_->NowNs());
  return Status::Ok();
}

Status RmpDriver::SetCommand(const RmpMotionCommand& command) {
  if (!std::isfinite(command.speed_mps) || !std::isfinite(command.yaw_rate_rps)) {
    ++health_.counters.invalid_commands;
    command_.reset();
    return InvalidArgument("RMP driver: command speed " + FormatNumber(command.speed_mps) + " m/s, yaw rate " +
                           FormatNumber(command.yaw_rate_rps) + " rad/s is not finite; zero until the next command");
  }
  const int64_t now = clock_->NowNs();
  const int64_t age = now - command.source_timestamp_ns;
  if (static_cast<double>(age) * 1e-9 > options_.max_input_age_s) {
    ++health_.counters.stale_commands_refused;
    command_.reset();
    command_went_stale_ = true;
    return FailedPrecondition("RMP driver: command refused, its data is " + DriverSeconds(age) + " old (limit " +
                              FormatNumber(options_.max_input_age_s) + " s); zero until a fresh command");
  }
  if (static_cast<double>(-age) * 1e-9 > options_.max_input_future_s) {
    ++health_.counters.invalid_commands;
    command_.reset();
    return InvalidArgument("RMP driver: command refused, its data is stamped " + DriverSeconds(-age) +
                           " in the future (clock mismatch?)");
  }
  command_ = command;
  command_went_stale_ = false;
  return Status::Ok();
}

void RmpDriver::CommandZero() {
  command_.reset();
  command_went_stale_ = false;
}

void RmpDriver::RequestStop(const std::string& reason) {
  if (!stop_requested_) Event("stop requested: " + reason);
  stop_requested_ = true;
  stop_reason_ = reason;
}

void RmpDriver::ClearStop() {
  if (stop_requested_) Event("stop cleared");
  stop_requested_ = false;
}

void RmpDriver::LogFrame(const hal::CanFrame& frame, replay::CanDirection direction) {
  if (log_ == nullptr) return;
  if (!log_->Write(frame, direction).ok()) ++health_.counters.log_errors;
}

// ---- receiving ----

void RmpDriver::HandleFrame(const hal::CanFrame& frame) {
  LogFrame(frame, replay::CanDirection::kReceived);
  receive_failing_ = false;
  if (frame.error) {
    ++health_.counters.error_frames;
    HandleErrorFrame(frame);
    return;
  }
  ++health_.counters.frames_received;
  // A data frame got through, so the controller is on the bus again even if the restart
  // notification was lost.
  if (health_.bus_off) {
    health_.bus_off = false;
    health_.controller_state = hal::CanControllerState::kErrorActive;
    Event("CAN bus back (frames received)");
  }
  Result<RmpStatusMessage> decoded = codec_.Decode(frame);
  if (!decoded.ok()) {
    if (decoded.status().code() == StatusCode::kNotFound) {
      ++health_.counters.foreign_frames;
    } else {
      ++health_.counters.decode_errors;
    }
    return;
  }
  HandleStatus(*decoded, frame.timestamp_ns);
}

void RmpDriver::HandleErrorFrame(const hal::CanFrame& frame) {
  const hal::CanErrorInfo info = hal::DecodeCanError(frame);
  if (info.has_state) health_.controller_state = info.state;
  if (info.bus_off && !health_.bus_off) {
    health_.bus_off = true;
    bus_off_since_ns_ = frame.timestamp_ns;
    last_recovery_ns_ = -1;
    ++health_.counters.bus_off_events;
    Event("CAN bus-off on " + bus_->name());
  } else if (health_.bus_off && info.has_state && info.state != hal::CanControllerState::kBusOff) {
    health_.bus_off = false;
    Event("CAN controller restarted on " + bus_->name());
  }
}

void RmpDriver::HandleStatus(const RmpStatusMessage& message, int64_t t) {
  health_.last_status_ns = std::max(health_.last_status_ns, t);
  if (const auto* m = std::get_if<RmpBuildFrame>(&message)) {
    status_.build = *m;
    status_.build_ns = t;
    cycle_seen_ = 1u;
    wheel_integrators_in_cycle_ = false;
    body_integrators_in_cycle_ = false;
  } else if (const auto* m1 = std::get_if<RmpTiltFrame>(&message)) {
    status_.tilt = *m1;
    status_.tilt_ns = t;
    cycle_seen_ |= 1u << 1;
  } else if (const auto* m2 = std::get_if<RmpSpeedFrame>(&message)) {
    status_.speeds = *m2;
    status_.speeds_ns = t;
    cycle_seen_ |= 1u << 2;
    TurnCheckSample(t, m2->yaw_rate_rps);
  } else if (const auto* m3 = std::get_if<RmpWheelIntegratorFrame>(&message)) {
    status_.wheel_integrators = *m3;
    status_.wheel_integrators_ns = t;
    cycle_seen_ |= 1u << 3;
    wheel_integrators_in_cycle_ = true;
  } else if (const auto* m4 = std::get_if<RmpBodyIntegratorFrame>(&message)) {
    status_.body_integrators = *m4;
    status_.body_integrators_ns = t;
    cycle_seen_ |= 1u << 4;
    body_integrators_in_cycle_ = true;
  } else if (const auto* m5 = std::get_if<RmpTorqueFrame>(&message)) {
    status_.torques = *m5;
    status_.torques_ns = t;
    cycle_seen_ |= 1u << 5;
  } else if (const auto* m6 = std::get_if<RmpModeFrame>(&message)) {
    status_.mode = *m6;
    status_.mode_ns = t;
    cycle_seen_ |= 1u << 6;
  } else if (const auto* m7 = std::get_if<RmpCommandEchoFrame>(&message)) {
    status_.echo = *m7;
    status_.echo_ns = t;
    status_.echo_speed_mps = VelocityCountsToMps(m7->velocity_counts, scaling_);
    status_.echo_yaw_rate_rps = TurnCountsToRadps(m7->turn_counts, scaling_);
    cycle_seen_ |= 1u << 7;
    EndOfCycle(t);
  } else if (const auto* m8 = std::get_if<RmpCuStatusFrame>(&message)) {
    status_.cu_status = *m8;
    status_.cu_status_ns = t;
  }
}

void RmpDriver::EndOfCycle(int64_t t) {
  ++health_.counters.status_cycles;
  if (cycle_seen_ == 0xFFu) ++health_.counters.complete_cycles;
  status_.cycle_end_ns = t;
  const bool need_body = options_.odometry.yaw_source == OdometryYawSource::kYawIntegrator;
  if (health_.state == RmpDriverState::kRunning && wheel_integrators_in_cycle_ && (!need_body || body_integrators_in_cycle_)) {
    const RmpIntegratorCounts counts{status_.wheel_integrators.left_counts, status_.wheel_integrators.right_counts,
                                     status_.body_integrators.fore_aft_counts, status_.body_integrators.yaw_counts};
    const Status st = odometry_.Update(status_.wheel_integrators_ns, counts);
    if (!st.ok()) {
      ++health_.counters.odometry_rejected;
      Event(st.message());
    }
  }
  cycle_seen_ = 0;
  wheel_integrators_in_cycle_ = false;
  body_integrators_in_cycle_ = false;
}

void RmpDriver::TurnCheckSample(int64_t t, double measured_yaw_rate_rps) {
  if (health_.state != RmpDriverState::kRunning || turn_steady_since_ns_ < 0) return;
  if (static_cast<double>(t - turn_steady_since_ns_) * 1e-9 < options_.turn_check_settle_s) return;
  if (std::abs(steady_turn_counts_) >= kRmpMaxTurnCounts) return;  // saturated: the ratio means nothing
  const double commanded = TurnCountsToRadps(steady_turn_counts_, scaling_);
  const double speed = VelocityCountsToMps(steady_velocity_counts_, scaling_);
  if (std::abs(commanded) < options_.turn_check_min_yaw_rate_rps || std::abs(speed) > options_.turn_check_max_speed_mps) return;
  turn_pairs_.emplace_back(commanded, measured_yaw_rate_rps);
  turn_sum_cm_ += commanded * measured_yaw_rate_rps;
  turn_sum_cc_ += commanded * commanded;
  if (turn_pairs_.size() > kTurnWindow) {
    const auto [c, m] = turn_pairs_.front();
    turn_sum_cm_ -= c * m;
    turn_sum_cc_ -= c * c;
    turn_pairs_.pop_front();
  }
  RmpTurnScaleCheck& check = health_.turn_check;
  check.samples = static_cast<int>(turn_pairs_.size());
  if (check.samples < options_.turn_check_min_samples || turn_sum_cc_ <= 0.0) return;
  const bool was_mismatch = check.mismatch;
  check.valid = true;
  check.ratio = turn_sum_cm_ / turn_sum_cc_;  // least squares: measured = ratio * commanded
  check.sign_wrong = check.ratio < 0.0;
  check.mismatch = std::abs(check.ratio - 1.0) > options_.turn_check_tolerance;
  // We send c = k * w_cmd; the RMP turns at c / k_true = ratio * w_cmd, so k_true = k / ratio.
  check.suggested_turn_counts_per_radps = std::abs(check.ratio) > 1e-6 ? scaling_.turn_counts_per_radps / std::abs(check.ratio) : 0.0;
  if (check.mismatch && !was_mismatch) {
    char buf[200];
    std::snprintf(buf, sizeof(buf),
                  "turn scale check: measured yaw rate is %.3f x the commanded one over %d samples%s; "
                  "turn_counts_per_radps %.1f would match",
                  check.ratio, check.samples, check.sign_wrong ? " (wrong direction)" : "", check.suggested_turn_counts_per_radps);
    Event(buf);
  }
}

// ---- health ----

void RmpDriver::UpdateInhibits(int64_t now) {
  uint32_t m = 0;
  if (health_.state != RmpDriverState::kRunning) m |= kRmpInhibitNotRunning;
  if (stop_requested_) m |= kRmpInhibitStopRequested;
  if (command_ && static_cast<double>(now - command_->source_timestamp_ns) * 1e-9 > options_.max_input_age_s) {
    ++health_.counters.stale_commands_refused;
    command_.reset();
    command_went_stale_ = true;
  }
  if (!command_) m |= command_went_stale_ ? kRmpInhibitStaleCommand : kRmpInhibitNoCommand;

  const bool fresh = health_.last_status_ns >= 0 &&
                     static_cast<double>(now - health_.last_status_ns) * 1e-9 <= options_.status_timeout_s;
  if (status_was_fresh_ && !fresh) {
    ++health_.counters.status_timeouts;
    Event("no RMP status for " + DriverSeconds(now - health_.last_status_ns));
  } else if (!status_was_fresh_ && fresh && health_.counters.status_timeouts > 0) {
    Event("RMP status back");
  }
  status_was_fresh_ = fresh;
  health_.status_fresh = fresh;
  // The battery voltages and the mode come in 0x406, one frame of the 100 Hz cycle: while running,
  // a cycle without it for status_timeout_s is stale status too (the battery check would hold its
  // last reading for good).
  const bool mode_fresh =
      status_.mode_ns >= 0 && static_cast<double>(now - status_.mode_ns) * 1e-9 <= options_.status_timeout_s;
  if (!fresh || (health_.state == RmpDriverState::kRunning && !mode_fresh)) m |= kRmpInhibitStatusStale;
  if (health_.bus_off) m |= kRmpInhibitBusOff;
  if (receive_failing_) m |= kRmpInhibitBusError;

  // Battery: from the voltages in 0x406 and the low-battery bits of 0x680, with 1 V hysteresis.
  bool low = health_.low_battery;
  const bool cu_low = status_.cu_status_ns >= 0 && status_.cu_status.low_battery();
  if (status_.mode_ns >= 0) {
    const double base = status_.mode.base_battery_v, ui = status_.mode.ui_battery_v;
    if (!low) {
      low = base < options_.min_base_battery_v || ui < options_.min_ui_battery_v || cu_low;
    } else {
      low = !(base > options_.min_base_battery_v + 1.0 && ui > options_.min_ui_battery_v + 1.0 && !cu_low);
    }
  } else {
    low = cu_low;
  }
  if (low != health_.low_battery) {
    char buf[120];
    std::snprintf(buf, sizeof(buf), "battery %s: base %.1f V, UI %.1f V", low ? "low" : "recovered",
                  status_.mode.base_battery_v, status_.mode.ui_battery_v);
    Event(buf);
  }
  health_.low_battery = low;
  if (low) m |= kRmpInhibitLowBattery;
  health_.rmp_fault = status_.cu_status_ns >= 0 && status_.cu_status.fault();
  if (health_.rmp_fault) m |= kRmpInhibitRmpFault;
  if (health_.turn_check.valid && health_.turn_check.sign_wrong) m |= kRmpInhibitTurnSignMismatch;

  const uint32_t faults = m & kRmpFaultInhibits;
  if (faults != last_fault_inhibits_) {
    Event("motion inhibited by: " + DescribeRmpInhibits(faults));
    last_fault_inhibits_ = faults;
  }
  health_.inhibit = m;

  // Bus-off: ask for a restart after a while, and again while it stays off.
  if (health_.bus_off && recover_ && static_cast<double>(now - bus_off_since_ns_) * 1e-9 >= options_.bus_off_recovery_s &&
      (last_recovery_ns_ < 0 || static_cast<double>(now - last_recovery_ns_) * 1e-9 >= options_.bus_off_recovery_s)) {
    last_recovery_ns_ = now;
    ++health_.counters.bus_restart_requests;
    const Status st = recover_();
    Event(st.ok() ? "CAN restart requested" : "CAN restart failed: " + st.message());
  }
}

// ---- sending ----

void RmpDriver::QueueConfiguration() {
  config_queue_.clear();
  auto add = [this](const RmpConfigRequest& r) {
    for (int i = 0; i < options_.config_repeats; ++i) config_queue_.push_back(r);
  };
  add(*MakeScaleConfig(RmpConfigId::kMaxVelocityScale, options_.velocity_scale));
  add(*MakeScaleConfig(RmpConfigId::kMaxAccelScale, options_.accel_scale));
  add(*MakeScaleConfig(RmpConfigId::kMaxTurnScale, options_.turn_scale));
  if (options_.current_limit_scale >= 0.0) add(*MakeScaleConfig(RmpConfigId::kCurrentLimitScale, options_.current_limit_scale));
  if (options_.balance_lockout) add(MakeBalanceLockoutConfig(*options_.balance_lockout));
  add(MakeGainScheduleConfig(options_.gain_schedule));
  add(MakeOperationalModeConfig(options_.operational_mode));
}

void RmpDriver::SendFrame(int64_t now, const RmpCommandFrame& command, uint32_t inhibit, int64_t source_ns) {
  hal::CanFrame frame = EncodeCommandFrame(command);
  frame.timestamp_ns = now;
  const Status st = bus_->Send(frame);
  if (!st.ok()) {
    if (health_.counters.send_errors == 0 || !health_.bus_off) Event("send failed: " + st.message());
    ++health_.counters.send_errors;
  } else {
    ++health_.counters.frames_sent;
    LogFrame(frame, replay::CanDirection::kTransmitted);
  }
  if (command.config_id != 0) ++health_.counters.config_frames;
  if (command.velocity_counts != 0 || command.turn_counts != 0) {
    ++health_.counters.motion_frames;
  } else {
    ++health_.counters.zero_frames;
  }
  // The command the RMP now follows, for the turn-scale check: steady while it stays within 5 %.
  auto near = [](int a, int b) { return std::abs(a - b) <= std::max(3, std::abs(b) / 20); };
  if (turn_steady_since_ns_ < 0 || !near(command.turn_counts, steady_turn_counts_) ||
      !near(command.velocity_counts, steady_velocity_counts_)) {
    steady_turn_counts_ = command.turn_counts;
    steady_velocity_counts_ = command.velocity_counts;
    turn_steady_since_ns_ = now;
  }
  recent_sent_.push_back({now, command, inhibit, source_ns});
  if (recent_sent_.size() > kRecentSentCapacity) recent_sent_.pop_front();
}

void RmpDriver::Tick(int64_t now) {
  UpdateInhibits(now);
  RmpCommandFrame f;
  int64_t source_ns = -1;
  switch (health_.state) {
    case RmpDriverState::kIdle:
    case RmpDriverState::kStopped: return;
    case RmpDriverState::kConnecting:
      if (health_.status_fresh) {
        SetState(RmpDriverState::kConfiguring, "RMP heard, build " + std::to_string(status_.build.build_id));
        QueueConfiguration();
        mode_attempts_ = 0;
      }
      break;
    case RmpDriverState::kConfiguring: {
      if (!config_queue_.empty()) {
        const RmpConfigRequest r = config_queue_.front();
        config_queue_.pop_front();
        f.config_id = static_cast<uint16_t>(r.id);
        f.config_param = r.param;
        config_sent_ns_ = now;
        break;
      }
      const bool answered = status_.mode_ns > config_sent_ns_;
      const bool matches = answered && status_.mode.mode == options_.operational_mode &&
                           status_.mode.gain_schedule == options_.gain_schedule;
      const bool timed_out = static_cast<double>(now - config_sent_ns_) * 1e-9 >= options_.config_verify_timeout_s;
      if (!matches && !timed_out) break;  // wait for 0x406 to show the new mode
      if (!matches && mode_attempts_ < options_.mode_retries) {
        ++mode_attempts_;
        Event(std::string("RMP reports mode ") + OperationalModeName(status_.mode.mode) + ", gain schedule " +
              std::to_string(static_cast<int>(status_.mode.gain_schedule)) + "; sending mode and gain schedule again");
        for (int i = 0; i < options_.config_repeats; ++i) {
          config_queue_.push_back(MakeGainScheduleConfig(options_.gain_schedule));
          config_queue_.push_back(MakeOperationalModeConfig(options_.operational_mode));
        }
        break;
      }
      health_.config_verified = matches;
      if (!matches) Event("RMP did not confirm the operational mode and gain schedule; continuing");
      if (reconfiguring_) {
        // Integrators that start again from zero are a jump the odometry takes as a new reference.
        reconfiguring_ = false;
        running_since_ns_ = now;
        SetState(RmpDriverState::kRunning, "configured again");
      } else if (options_.reset_integrators) {
        SetState(RmpDriverState::kResettingOdometry, "integrator reset");
        reset_started_ns_ = now;
        reset_frames_left_ = options_.config_repeats;
      } else {
        odometry_.Reset();
        health_.odometry_reset = OdometryResetResult::kNotRequested;
        running_since_ns_ = now;
        SetState(RmpDriverState::kRunning, "configured");
      }
      break;
    }
    case RmpDriverState::kResettingOdometry: {
      if (reset_frames_left_ > 0) {
        --reset_frames_left_;
        const RmpConfigRequest r = MakeResetIntegratorsConfig(kRmpResetAll);
        f.config_id = static_cast<uint16_t>(r.id);
        f.config_param = r.param;
        reset_sent_ns_ = now;
        break;
      }
      const int64_t tol = static_cast<int64_t>(options_.integrator_reset_tolerance_m * codec_.scales().distance_counts_per_m);
      auto small = [tol](uint32_t c) { return std::abs(static_cast<int64_t>(static_cast<int32_t>(c))) <= tol; };
      const bool fresh_counts = status_.wheel_integrators_ns > reset_sent_ns_ && status_.body_integrators_ns > reset_sent_ns_;
      const bool zeroed = fresh_counts && small(status_.wheel_integrators.left_counts) &&
                          small(status_.wheel_integrators.right_counts) && small(status_.body_integrators.fore_aft_counts);
      const bool timed_out = static_cast<double>(now - reset_started_ns_) * 1e-9 >= options_.integrator_reset_timeout_s;
      if (!zeroed && !timed_out) break;
      health_.odometry_reset = zeroed ? OdometryResetResult::kConfirmed : OdometryResetResult::kSoftwareOffset;
      if (!zeroed) Event("integrator reset not confirmed; odometry uses a software offset");
      odometry_.Reset();
      running_since_ns_ = now;
      SetState(RmpDriverState::kRunning, std::string("odometry ") + OdometryResetResultName(health_.odometry_reset));
      UpdateInhibits(now);
      break;
    }
    case RmpDriverState::kRunning: {
      const bool long_silence =
          health_.last_status_ns >= 0 &&
          static_cast<double>(now - health_.last_status_ns) * 1e-9 > options_.reconfigure_after_silence_s;
      const bool mode_changed =
          health_.config_verified && status_.mode_ns > running_since_ns_ &&
          (status_.mode.mode != options_.operational_mode || status_.mode.gain_schedule != options_.gain_schedule);
      if (long_silence || mode_changed) {
        // A zero this tick; motion again once the RMP has its configuration back.
        ++health_.counters.reconfigurations;
        reconfiguring_ = true;
        if (long_silence) {
          SetState(RmpDriverState::kConnecting,
                   "no status for " + DriverSeconds(now - health_.last_status_ns) +
                       ": the RMP may have rebooted; configuring it again when it answers");
        } else {
          SetState(
              RmpDriverState::kConfiguring,
              std::string("the RMP reports mode ") + OperationalModeName(status_.mode.mode) + ": configuring it again");
          QueueConfiguration();
          mode_attempts_ = 0;
        }
        UpdateInhibits(now);
        break;
      }
      if (health_.inhibit == 0 && command_) {
        const RmpMotionCounts c = MotionToCounts(command_->speed_mps, command_->yaw_rate_rps, scaling_);
        if (c.velocity_saturated || c.turn_saturated) ++health_.counters.saturated_commands;
        f.velocity_counts = c.velocity;
        f.turn_counts = c.turn;
        source_ns = command_->source_timestamp_ns;
      }
      break;
    }
    case RmpDriverState::kShuttingDown:
      --shutdown_frames_left_;
      break;
  }
  SendFrame(now, f, health_.inhibit, source_ns);
  if (health_.state == RmpDriverState::kShuttingDown && shutdown_frames_left_ <= 0) {
    SetState(RmpDriverState::kStopped, "zero sent");
  }
}

Status RmpDriver::ResyncSchedule(int64_t t_ns) {
  if (t_ns < clock_->NowNs()) {
    return InvalidArgument("RMP driver: a tick at " + std::to_string(t_ns) + " ns is before now (" +
                           std::to_string(clock_->NowNs()) + " ns)");
  }
  next_send_ns_ = t_ns;
  return Status::Ok();
}

void RmpDriver::MaybeTick(int64_t now) {
  if (!Sending() || now < next_send_ns_) return;
  if (now - next_send_ns_ >= period_ns_) ++health_.counters.late_ticks;
  Tick(now);
  next_send_ns_ += period_ns_;
  if (next_send_ns_ <= now) next_send_ns_ = now + period_ns_;
}

Status RmpDriver::Poll() {
  if (health_.state == RmpDriverState::kIdle) return FailedPrecondition("RMP driver: Poll() before Start()");
  for (int i = 0; i < kMaxDrainPerPoll; ++i) {
    Result<std::optional<hal::CanFrame>> r = bus_->Receive(std::chrono::milliseconds(0));
    if (!r.ok()) {
      if (!receive_failing_) Event("receive failed: " + r.status().message());
      ++health_.counters.receive_errors;
      receive_failing_ = true;
      break;
    }
    if (!r->has_value()) break;
    HandleFrame(**r);
  }
  const int64_t now = clock_->NowNs();
  MaybeTick(now);
  UpdateInhibits(now);
  return Status::Ok();
}

Status RmpDriver::RunUntil(int64_t t_ns) {
  if (health_.state == RmpDriverState::kIdle) return FailedPrecondition("RMP driver: RunUntil() before Start()");
  while (true) {
    int64_t now = clock_->NowNs();
    MaybeTick(now);
    if (now >= t_ns) break;
    const int64_t wake = Sending() ? std::min(t_ns, next_send_ns_) : t_ns;
    // Millisecond timeouts, rounded up so simulated time always moves.
    const int64_t timeout_ms = std::max<int64_t>(1, (wake - now + hal::kNsPerMs - 1) / hal::kNsPerMs);
    Result<std::optional<hal::CanFrame>> r = bus_->Receive(std::chrono::milliseconds(timeout_ms));
    if (!r.ok()) {
      if (!receive_failing_) Event("receive failed: " + r.status().message());
      ++health_.counters.receive_errors;
      receive_failing_ = true;
      clock_->SleepUntilNs(wake);  // do not spin on a dead interface
      continue;
    }
    if (r->has_value()) HandleFrame(**r);
  }
  UpdateInhibits(clock_->NowNs());
  return Status::Ok();
}

Status RmpDriver::Shutdown() {
  if (!Sending()) return Status::Ok();
  command_.reset();
  shutdown_frames_left_ = options_.shutdown_zero_frames;
  SetState(RmpDriverState::kShuttingDown, "shutdown");
  for (int i = 0; i < options_.shutdown_zero_frames + 2 && health_.state != RmpDriverState::kStopped; ++i) {
    IDI_RETURN_IF_ERROR(RunUntil(next_send_ns_));
  }
  if (health_.state != RmpDriverState::kStopped) {
    return Internal("RMP driver: shutdown did not finish sending zero commands");
  }
  return Status::Ok();
}

}  // namespace idi::rmp
