#include "rmp/segway/sim_rmp.h"

#include <algorithm>
#include <cmath>

namespace idi::rmp {
namespace {

constexpr int64_t kMinCommandGapNs = 10'000'000;   // device-protocols.md §1.5
constexpr int64_t kMaxCommandGapNs = 300'000'000;

RmpCodecOptions SimCodecOptions(const SimRmpOptions& o) {
  RmpCodecOptions c;
  c.model = o.model;
  c.yaw_rate_sign = o.yaw_rate_sign;
  c.yaw_integrator_sign = o.yaw_rate_sign;
  return c;
}

}  // namespace

Status SimRmpOptions::Check() const {
  IDI_RETURN_IF_ERROR(vehicle.Check());
  if (!(std::isfinite(turn_counts_per_radps) && turn_counts_per_radps > 0.0)) {
    return InvalidArgument("simulated RMP: turn_counts_per_radps must be positive");
  }
  if ((turn_sign != 1 && turn_sign != -1) || (yaw_rate_sign != 1 && yaw_rate_sign != -1)) {
    return InvalidArgument("simulated RMP: turn_sign and yaw_rate_sign must be +1 or -1");
  }
  if (!(status_period_s >= 0.005 && status_period_s <= 0.1)) {
    return InvalidArgument("simulated RMP: status_period_s = " + FormatNumber(status_period_s) +
                           " is outside 5..100 ms");
  }
  if (cu_status_every_cycles < 1) return InvalidArgument("simulated RMP: cu_status_every_cycles must be >= 1");
  for (double s : {boot_velocity_scale, boot_accel_scale, boot_turn_scale}) {
    if (!(s >= 0.0 && s <= 1.0)) return InvalidArgument("simulated RMP: boot scales must be in [0, 1]");
  }
  if (boot_mode != OperationalMode::kTractor && boot_mode != OperationalMode::kBalance &&
      boot_mode != OperationalMode::kDisabled) {
    return InvalidArgument("simulated RMP: boot_mode must be disabled, tractor or balance");
  }
  return Status::Ok();
}

SimRmp::SimRmp(sim::VirtualCanBus* bus, const SimRmpOptions& options)
    : options_(options),
      codec_(SimCodecOptions(options)),
      bus_(bus),
      endpoint_(bus->AddEndpoint("rmp")),
      vehicle_(options.vehicle, bus->clock()->NowNs()),
      next_status_ns_(bus->clock()->NowNs() + static_cast<int64_t>(std::llround(options.status_period_s * 1e9))),
      mode_(options.boot_mode),
      gain_(options.boot_gain_schedule),
      velocity_scale_(options.boot_velocity_scale),
      accel_scale_(options.boot_accel_scale),
      turn_scale_(options.boot_turn_scale),
      left_base_(options.initial_left_counts),
      right_base_(options.initial_right_counts),
      fore_aft_base_(options.initial_fore_aft_counts),
      yaw_base_(options.initial_yaw_counts) {
  const Status st = options_.Check();
  IDI_CHECK(st.ok(), st.ToString());
  firmware_scaling_.velocity_counts_per_mps = codec_.scales().wheel_speed_counts_per_mps;
  firmware_scaling_.turn_counts_per_radps = options_.turn_counts_per_radps;
  firmware_scaling_.turn_sign = options_.turn_sign;
  ApplyScalesAndMode();
  bus_->AddProcess(this);
}

void SimRmp::ApplyScalesAndMode() {
  firmware_scaling_.velocity_scale_fraction = velocity_scale_;
  firmware_scaling_.turn_scale_fraction = turn_scale_;
  vehicle_.SetSpeedScale(velocity_scale_);
  vehicle_.SetAccelScale(accel_scale_);
  vehicle_.SetTurnScale(turn_scale_);
  vehicle_.SetBalanceMode(mode_ == OperationalMode::kBalance);
  UpdateMotorsEnabled();
}

void SimRmp::Reboot() {
  mode_ = options_.boot_mode;
  gain_ = options_.boot_gain_schedule;
  velocity_scale_ = options_.boot_velocity_scale;
  accel_scale_ = options_.boot_accel_scale;
  turn_scale_ = options_.boot_turn_scale;
  current_limit_scale_ = 1.0;
  balance_locked_out_ = false;
  vehicle_.ResetIntegrators(true, true, true, true);
  left_base_ = right_base_ = fore_aft_base_ = yaw_base_ = 0;
  ApplyScalesAndMode();
}

void SimRmp::SetInjectedStatusBits(uint16_t word1, uint16_t word2) {
  injected_word1_ = word1;
  injected_word2_ = word2;
  UpdateMotorsEnabled();
}

void SimRmp::UpdateMotorsEnabled() {
  const bool fault = (injected_word1_ & kRmpStatus1FaultMask) != 0 ||
                     (injected_word2_ & (kRmpStatus2FaultMask | (kRmpStatus2FaultMask << 8))) != 0;
  const bool mode_ok = mode_ == OperationalMode::kTractor || mode_ == OperationalMode::kBalance;
  vehicle_.SetMotorsEnabled(!powered_down_ && mode_ok && !fault);
}

int64_t SimRmp::NextWakeNs() const { return std::min(next_status_ns_, endpoint_->next_delivery_ns()); }

void SimRmp::RunUntil(int64_t t_ns) {
  const int64_t period = static_cast<int64_t>(std::llround(options_.status_period_s * 1e9));
  while (true) {
    const int64_t next_frame = endpoint_->next_delivery_ns();
    const int64_t next = std::min(next_frame, next_status_ns_);
    if (next > t_ns) break;
    vehicle_.AdvanceTo(next);
    if (next_frame <= next_status_ns_) {
      while (std::optional<hal::CanFrame> f = endpoint_->PopDelivered(next)) HandleFrame(*f);
    } else {
      SendStatusCycle();
      next_status_ns_ += period;
    }
  }
  vehicle_.AdvanceTo(t_ns);
}

void SimRmp::HandleFrame(const hal::CanFrame& frame) {
  if (frame.error || frame.extended) return;
  if (frame.id == kRmpIdShutdown) {
    ++counters_.shutdowns;
    powered_down_ = true;
    UpdateMotorsEnabled();
    return;
  }
  if (frame.id != kRmpIdCommand) {
    ++counters_.other_frames;
    return;
  }
  Result<RmpCommandFrame> cmd = DecodeCommandFrame(frame);
  if (!cmd.ok()) {
    ++counters_.bad_frames;
    return;
  }
  const int64_t t = frame.timestamp_ns;
  if (last_command_ns_ >= 0) {
    if (t - last_command_ns_ < kMinCommandGapNs) ++counters_.commands_too_close;
    if (t - last_command_ns_ > kMaxCommandGapNs) ++counters_.command_gaps_too_long;
  }
  last_command_ns_ = t;
  ++counters_.commands;
  if (cmd->config_id != 0) {
    ++counters_.config_commands;
    ApplyConfig(cmd->config_id, cmd->config_param);
  }
  echo_.velocity_counts = cmd->velocity_counts;
  echo_.turn_counts = cmd->turn_counts;
  if (powered_down_) return;
  // The firmware multiplies the command by its configured scales (ORCA's model, §1.6).
  const double v = VelocityCountsToMps(cmd->velocity_counts, firmware_scaling_);
  const double w = TurnCountsToRadps(cmd->turn_counts, firmware_scaling_);
  vehicle_.Command(t, {v, w});
}

void SimRmp::ApplyConfig(uint16_t id, uint16_t param) {
  switch (static_cast<RmpConfigId>(id)) {
    case RmpConfigId::kMaxVelocityScale:
      velocity_scale_ = std::min<uint16_t>(param, 16) / 16.0;
      firmware_scaling_.velocity_scale_fraction = velocity_scale_;
      vehicle_.SetSpeedScale(velocity_scale_);
      break;
    case RmpConfigId::kMaxAccelScale:
      accel_scale_ = std::min<uint16_t>(param, 16) / 16.0;
      vehicle_.SetAccelScale(accel_scale_);
      break;
    case RmpConfigId::kMaxTurnScale:
      turn_scale_ = std::min<uint16_t>(param, 16) / 16.0;
      firmware_scaling_.turn_scale_fraction = turn_scale_;
      vehicle_.SetTurnScale(turn_scale_);
      break;
    case RmpConfigId::kGainSchedule:
      if (param <= 2) gain_ = static_cast<GainSchedule>(param);
      break;
    case RmpConfigId::kCurrentLimitScale: current_limit_scale_ = std::min<uint16_t>(param, 256) / 256.0; break;
    case RmpConfigId::kBalanceLockout: balance_locked_out_ = param != 0; break;
    case RmpConfigId::kOperationalMode:
      if (param == static_cast<uint16_t>(OperationalMode::kTractor)) {
        mode_ = OperationalMode::kTractor;
      } else if (param == static_cast<uint16_t>(OperationalMode::kBalance) && !balance_locked_out_) {
        mode_ = OperationalMode::kBalance;
      } else if (param == static_cast<uint16_t>(OperationalMode::kPowerDown)) {
        mode_ = OperationalMode::kPowerDown;
        powered_down_ = true;
      }
      vehicle_.SetBalanceMode(mode_ == OperationalMode::kBalance);
      UpdateMotorsEnabled();
      break;
    case RmpConfigId::kResetIntegrators:
      if (options_.integrator_reset_works) {
        ++counters_.integrator_resets;
        const bool right = param & kRmpResetRightWheel, left = param & kRmpResetLeftWheel;
        const bool yaw = param & kRmpResetYaw, fore_aft = param & kRmpResetForeAft;
        vehicle_.ResetIntegrators(left, right, yaw, fore_aft);
        if (left) left_base_ = 0;
        if (right) right_base_ = 0;
        if (yaw) yaw_base_ = 0;
        if (fore_aft) fore_aft_base_ = 0;
      }
      break;
    case RmpConfigId::kNone: break;
  }
}

void SimRmp::SendStatusCycle() {
  ++cycle_;
  if (silent_ || powered_down_) return;
  ++counters_.status_cycles;
  const sim::VehicleSensors& s = vehicle_.sensors();
  auto send = [this](const hal::CanFrame& f) {
    // A bus-off controller cannot send: the frames are lost, as on the real RMP.
    (void)endpoint_->Send(f);
  };
  send(codec_.Encode(RmpBuildFrame{options_.build_id}));
  send(codec_.Encode(RmpTiltFrame{s.pitch_rad, s.pitch_rate_rps, s.roll_rad, s.roll_rate_rps}));
  send(codec_.Encode(RmpSpeedFrame{s.left_wheel_mps, s.right_wheel_mps, s.yaw_rate_rps, static_cast<uint16_t>(cycle_ & 0xFFFF)}));
  if (!integrators_missing_) {
    send(codec_.Encode(RmpWheelIntegratorFrame{left_base_ + codec_.DistanceCounts(s.left_wheel_m),
                                               right_base_ + codec_.DistanceCounts(s.right_wheel_m)}));
  }
  send(codec_.Encode(RmpBodyIntegratorFrame{fore_aft_base_ + codec_.DistanceCounts(s.fore_aft_m),
                                            yaw_base_ + codec_.YawCounts(s.yaw_rad)}));
  send(codec_.Encode(RmpTorqueFrame{s.left_torque_nm, s.right_torque_nm}));
  RmpModeFrame mode;
  mode.mode = mode_;
  mode.gain_schedule = gain_;
  mode.ui_battery_v = s.ui_battery_v;
  mode.base_battery_v = std::max(0.0, s.base_battery_v);
  if (!mode_missing_) send(codec_.Encode(mode));
  send(codec_.Encode(echo_));
  if (cycle_ % static_cast<uint64_t>(options_.cu_status_every_cycles) == 0) {
    RmpCuStatusFrame cu;
    if (vehicle_.motors_enabled()) cu.word1 |= kRmpStatus1MotorsEnabled;
    if (mode_ == OperationalMode::kBalance) cu.word1 |= kRmpStatus1BalanceMode;
    if (s.base_battery_v < options_.low_battery_v) {
      cu.word1 |= kRmpStatus1LowBattery;
      cu.word2 |= kRmpStatus2LowBusVoltage;
    }
    if (s.base_battery_v < options_.empty_battery_v) cu.word1 |= kRmpStatus1EmptyBattery;
    cu.word1 |= injected_word1_;
    cu.word2 |= injected_word2_;
    send(codec_.Encode(cu));
  }
}

}  // namespace idi::rmp
