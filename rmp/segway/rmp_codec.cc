#include "rmp/segway/rmp_codec.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <string>

#include "shared/util/units.h"

namespace idi::rmp {
namespace {

// Plausibility limits for decoded status: an RMP never reports more, so a frame that does is
// garbage (device-protocols.md §1.1: one of the two channels was seen carrying garbage).
constexpr double kMaxTiltDeg = 90.0;
constexpr double kMaxRateDegps = 600.0;
constexpr double kMaxWheelSpeedMps = 10.0;
constexpr double kMaxBaseBatteryV = 100.0;
constexpr double kMaxUiBatteryV = 20.0;

std::string CodecHexId(uint32_t id) {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "0x%03X", id);
  return buf;
}

uint16_t GetU16(const std::array<uint8_t, 8>& d, int slot) {
  return static_cast<uint16_t>((d[2 * slot] << 8) | d[2 * slot + 1]);
}
int16_t GetI16(const std::array<uint8_t, 8>& d, int slot) { return static_cast<int16_t>(GetU16(d, slot)); }
void PutU16(std::array<uint8_t, 8>* d, int slot, uint16_t v) {
  (*d)[2 * slot] = static_cast<uint8_t>(v >> 8);
  (*d)[2 * slot + 1] = static_cast<uint8_t>(v & 0xFF);
}
void PutI16(std::array<uint8_t, 8>* d, int slot, int16_t v) { PutU16(d, slot, static_cast<uint16_t>(v)); }

int16_t SaturateToI16(double v) {
  if (!std::isfinite(v)) return 0;
  const double r = std::round(v);
  return static_cast<int16_t>(std::clamp(r, -32768.0, 32767.0));
}
uint16_t SaturateToU16(double v) {
  if (!std::isfinite(v)) return 0;
  return static_cast<uint16_t>(std::clamp(std::round(v), 0.0, 65535.0));
}

hal::CanFrame StatusFrame(uint32_t id) {
  hal::CanFrame f;
  f.id = id;
  f.dlc = 8;
  return f;
}

}  // namespace

const char* RmpModelName(RmpModel model) {
  switch (model) {
    case RmpModel::kRmp50: return "rmp50";
    case RmpModel::kRmp100: return "rmp100";
    case RmpModel::kRmp200: return "rmp200";
    case RmpModel::kRmp400: return "rmp400";
  }
  return "?";
}

Result<RmpModel> ParseRmpModel(std::string_view text) {
  std::string s;
  for (char c : text) {
    if (c != ' ' && c != '_' && c != '-') s.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(c))));
  }
  for (RmpModel m : {RmpModel::kRmp50, RmpModel::kRmp100, RmpModel::kRmp200, RmpModel::kRmp400}) {
    if (s == RmpModelName(m)) return m;
  }
  return InvalidArgument("RMP model '" + std::string(text) + "': expected rmp50, rmp100, rmp200 or rmp400");
}

RmpScaleFactors ScaleFactorsFor(RmpModel model) {
  RmpScaleFactors s;
  if (model == RmpModel::kRmp50 || model == RmpModel::kRmp100) {
    s.wheel_speed_counts_per_mps = 401.0;
    s.distance_counts_per_m = 40181.0;
    s.yaw_counts_per_rev = 117031.0;
    s.torque_counts_per_nm = 1463.0;
  } else {
    s.wheel_speed_counts_per_mps = 332.0;
    s.distance_counts_per_m = 33215.0;
    s.yaw_counts_per_rev = 112644.0;
    s.torque_counts_per_nm = 1094.0;
  }
  return s;
}

const char* RmpConfigIdName(RmpConfigId id) {
  switch (id) {
    case RmpConfigId::kNone: return "none";
    case RmpConfigId::kMaxVelocityScale: return "max velocity scale";
    case RmpConfigId::kMaxAccelScale: return "max acceleration scale";
    case RmpConfigId::kMaxTurnScale: return "max turn scale";
    case RmpConfigId::kGainSchedule: return "gain schedule";
    case RmpConfigId::kCurrentLimitScale: return "current limit scale";
    case RmpConfigId::kBalanceLockout: return "balance lockout";
    case RmpConfigId::kOperationalMode: return "operational mode";
    case RmpConfigId::kResetIntegrators: return "reset integrators";
  }
  return "unknown";
}

const char* OperationalModeName(OperationalMode mode) {
  switch (mode) {
    case OperationalMode::kDisabled: return "disabled";
    case OperationalMode::kTractor: return "tractor";
    case OperationalMode::kBalance: return "balance";
    case OperationalMode::kPowerDown: return "power down";
  }
  return "?";
}

// ---- command ----

hal::CanFrame EncodeCommandFrame(const RmpCommandFrame& command) {
  hal::CanFrame f = StatusFrame(kRmpIdCommand);
  PutI16(&f.data, 0, command.velocity_counts);
  PutI16(&f.data, 1, command.turn_counts);
  PutU16(&f.data, 2, command.config_id);
  PutU16(&f.data, 3, command.config_param);
  return f;
}

hal::CanFrame EncodeShutdownFrame() { return StatusFrame(kRmpIdShutdown); }

Result<RmpCommandFrame> DecodeCommandFrame(const hal::CanFrame& frame) {
  if (frame.error || frame.extended || frame.id != kRmpIdCommand) {
    return ParseError("RMP command: frame " + CodecHexId(frame.id) + " is not a command (0x413)");
  }
  if (frame.rtr || frame.dlc < 8) {
    return ParseError("RMP command: frame 0x413 is truncated (DLC " + std::to_string(frame.dlc) + ", expected 8)");
  }
  RmpCommandFrame c;
  c.velocity_counts = GetI16(frame.data, 0);
  c.turn_counts = GetI16(frame.data, 1);
  c.config_id = GetU16(frame.data, 2);
  c.config_param = GetU16(frame.data, 3);
  if (std::abs(c.velocity_counts) > kRmpMaxVelocityCounts || std::abs(c.turn_counts) > kRmpMaxTurnCounts) {
    return ParseError("RMP command: velocity " + std::to_string(c.velocity_counts) + " / turn " +
                      std::to_string(c.turn_counts) + " counts beyond +-1176 / +-1024");
  }
  return c;
}

Result<RmpConfigRequest> MakeScaleConfig(RmpConfigId id, double fraction) {
  double full = 0.0;
  switch (id) {
    case RmpConfigId::kMaxVelocityScale:
    case RmpConfigId::kMaxAccelScale:
    case RmpConfigId::kMaxTurnScale: full = 16.0; break;
    case RmpConfigId::kCurrentLimitScale: full = 256.0; break;
    default:
      return InvalidArgument(std::string("RMP config: ") + RmpConfigIdName(id) + " is not a scale command");
  }
  if (!(fraction >= 0.0 && fraction <= 1.0)) {
    return OutOfRange(std::string("RMP config: ") + RmpConfigIdName(id) + " fraction " + FormatNumber(fraction) +
                      " is outside [0, 1]");
  }
  // floor, as libsegwayrmp does: a limit is never set above what was asked.
  return RmpConfigRequest{id, static_cast<uint16_t>(std::floor(fraction * full + 1e-9))};
}

RmpConfigRequest MakeGainScheduleConfig(GainSchedule schedule) {
  return {RmpConfigId::kGainSchedule, static_cast<uint16_t>(schedule)};
}
RmpConfigRequest MakeBalanceLockoutConfig(bool locked_out) {
  return {RmpConfigId::kBalanceLockout, static_cast<uint16_t>(locked_out ? 1 : 0)};
}
RmpConfigRequest MakeOperationalModeConfig(OperationalMode mode) {
  return {RmpConfigId::kOperationalMode, static_cast<uint16_t>(mode)};
}
RmpConfigRequest MakeResetIntegratorsConfig(uint16_t mask) {
  return {RmpConfigId::kResetIntegrators, static_cast<uint16_t>(mask & kRmpResetAll)};
}

Status RmpCommandScaling::Check() const {
  if (!(std::isfinite(velocity_counts_per_mps) && velocity_counts_per_mps > 0.0)) {
    return InvalidArgument("RMP command scaling: velocity_counts_per_mps must be positive, got " +
                           FormatNumber(velocity_counts_per_mps));
  }
  if (!(std::isfinite(turn_counts_per_radps) && turn_counts_per_radps > 0.0)) {
    return InvalidArgument("RMP command scaling: turn_counts_per_radps must be positive, got " +
                           FormatNumber(turn_counts_per_radps));
  }
  if (turn_sign != 1 && turn_sign != -1) {
    return InvalidArgument("RMP command scaling: turn_sign must be +1 or -1, got " + std::to_string(turn_sign));
  }
  if (!(velocity_scale_fraction > 0.0 && velocity_scale_fraction <= 1.0) ||
      !(turn_scale_fraction > 0.0 && turn_scale_fraction <= 1.0)) {
    return InvalidArgument("RMP command scaling: scale fractions must be in (0, 1]");
  }
  return Status::Ok();
}

RmpMotionCounts MotionToCounts(double speed_mps, double yaw_rate_rps, const RmpCommandScaling& scaling) {
  RmpMotionCounts c;
  if (!std::isfinite(speed_mps) || !std::isfinite(yaw_rate_rps)) {
    c.invalid_input = true;
    return c;
  }
  const double v = std::round(speed_mps * scaling.velocity_counts_per_mps / scaling.velocity_scale_fraction);
  const double w = std::round(scaling.turn_sign * yaw_rate_rps * scaling.turn_counts_per_radps / scaling.turn_scale_fraction);
  c.velocity_saturated = std::abs(v) > kRmpMaxVelocityCounts;
  c.turn_saturated = std::abs(w) > kRmpMaxTurnCounts;
  c.velocity = static_cast<int16_t>(std::clamp(v, -double{kRmpMaxVelocityCounts}, double{kRmpMaxVelocityCounts}));
  c.turn = static_cast<int16_t>(std::clamp(w, -double{kRmpMaxTurnCounts}, double{kRmpMaxTurnCounts}));
  return c;
}

double VelocityCountsToMps(int counts, const RmpCommandScaling& scaling) {
  return counts * scaling.velocity_scale_fraction / scaling.velocity_counts_per_mps;
}

double TurnCountsToRadps(int counts, const RmpCommandScaling& scaling) {
  return scaling.turn_sign * counts * scaling.turn_scale_fraction / scaling.turn_counts_per_radps;
}

// ---- integrators ----

uint32_t GetWordSwappedU32(const std::array<uint8_t, 8>& data, int slot) {
  return (static_cast<uint32_t>(GetU16(data, slot + 1)) << 16) | GetU16(data, slot);
}

void PutWordSwappedU32(std::array<uint8_t, 8>* data, int slot, uint32_t value) {
  PutU16(data, slot, static_cast<uint16_t>(value & 0xFFFF));
  PutU16(data, slot + 1, static_cast<uint16_t>(value >> 16));
}

int32_t IntegratorDelta(uint32_t now, uint32_t before) {
  // Modulo-2^32 difference read as two's complement: the shortest signed way round.
  return static_cast<int32_t>(now - before);
}

// ---- status ----

Status RmpCodecOptions::Check() const {
  if ((yaw_rate_sign != 1 && yaw_rate_sign != -1) || (yaw_integrator_sign != 1 && yaw_integrator_sign != -1)) {
    return InvalidArgument("RMP codec: yaw_rate_sign and yaw_integrator_sign must be +1 or -1");
  }
  return Status::Ok();
}

RmpCodec::RmpCodec(const RmpCodecOptions& options) : options_(options), scales_(ScaleFactorsFor(options.model)) {
  const Status st = options_.Check();
  IDI_CHECK(st.ok(), st.ToString());
}

double RmpCodec::YawRadians(int64_t counts) const {
  return options_.yaw_integrator_sign * static_cast<double>(counts) * 2.0 * kPi / scales_.yaw_counts_per_rev;
}

uint32_t RmpCodec::DistanceCounts(double meters) const {
  return static_cast<uint32_t>(static_cast<int64_t>(std::llround(meters * scales_.distance_counts_per_m)));
}

uint32_t RmpCodec::YawCounts(double radians) const {
  const double counts = options_.yaw_integrator_sign * radians * scales_.yaw_counts_per_rev / (2.0 * kPi);
  return static_cast<uint32_t>(static_cast<int64_t>(std::llround(counts)));
}

Result<RmpStatusMessage> RmpCodec::Decode(const hal::CanFrame& frame) const {
  const uint32_t id = frame.id;
  const bool status_id = (id >= kRmpIdStatusFirst && id <= kRmpIdStatusLast) || id == kRmpIdCuStatus;
  if (frame.error || frame.extended || !status_id) {
    return NotFound("CAN frame " + CodecHexId(id) + (frame.extended ? " (extended)" : "") + " is no RMP status frame");
  }
  if (frame.rtr) return ParseError("RMP status " + CodecHexId(id) + ": a remote frame, not data");
  if (frame.dlc < 8) {
    return ParseError("RMP status " + CodecHexId(id) + ": truncated, DLC " + std::to_string(frame.dlc) + " (expected 8)");
  }
  const std::array<uint8_t, 8>& d = frame.data;
  const RmpScaleFactors& s = scales_;
  auto garbage = [&](const std::string& what) { return ParseError("RMP status " + CodecHexId(id) + ": " + what); };
  switch (id) {
    case 0x400: return RmpStatusMessage(RmpBuildFrame{GetU16(d, 0)});
    case kRmpIdTilt: {
      const double pitch_deg = GetI16(d, 0) / s.tilt_counts_per_deg;
      const double pitch_rate = GetI16(d, 1) / s.rate_counts_per_degps;
      const double roll_deg = GetI16(d, 2) / s.tilt_counts_per_deg;
      const double roll_rate = GetI16(d, 3) / s.rate_counts_per_degps;
      if (std::abs(pitch_deg) > kMaxTiltDeg || std::abs(roll_deg) > kMaxTiltDeg) {
        return garbage("pitch " + FormatNumber(pitch_deg) + " deg / roll " + FormatNumber(roll_deg) +
                       " deg beyond 90 deg");
      }
      if (std::abs(pitch_rate) > kMaxRateDegps || std::abs(roll_rate) > kMaxRateDegps) {
        return garbage("tilt rates beyond 600 deg/s");
      }
      return RmpStatusMessage(RmpTiltFrame{DegToRad(pitch_deg), DegToRad(pitch_rate), DegToRad(roll_deg), DegToRad(roll_rate)});
    }
    case kRmpIdSpeeds: {
      RmpSpeedFrame m;
      m.left_wheel_mps = GetI16(d, 0) / s.wheel_speed_counts_per_mps;
      m.right_wheel_mps = GetI16(d, 1) / s.wheel_speed_counts_per_mps;
      const double yaw_degps = options_.yaw_rate_sign * GetI16(d, 2) / s.rate_counts_per_degps;
      m.yaw_rate_rps = DegToRad(yaw_degps);
      m.servo_frames = GetU16(d, 3);
      if (std::abs(m.left_wheel_mps) > kMaxWheelSpeedMps || std::abs(m.right_wheel_mps) > kMaxWheelSpeedMps) {
        return garbage("wheel speeds " + FormatNumber(m.left_wheel_mps) + ", " + FormatNumber(m.right_wheel_mps) +
                       " m/s beyond 10 m/s");
      }
      if (std::abs(yaw_degps) > kMaxRateDegps) return garbage("yaw rate beyond 600 deg/s");
      return RmpStatusMessage(m);
    }
    case kRmpIdWheelIntegrators:
      return RmpStatusMessage(RmpWheelIntegratorFrame{GetWordSwappedU32(d, 0), GetWordSwappedU32(d, 2)});
    case kRmpIdBodyIntegrators:
      return RmpStatusMessage(RmpBodyIntegratorFrame{GetWordSwappedU32(d, 0), GetWordSwappedU32(d, 2)});
    case kRmpIdTorques:
      return RmpStatusMessage(RmpTorqueFrame{GetI16(d, 0) / s.torque_counts_per_nm, GetI16(d, 1) / s.torque_counts_per_nm});
    case kRmpIdMode: {
      const uint16_t mode = GetU16(d, 0), gain = GetU16(d, 1);
      if (mode > 3) return garbage("operational mode " + std::to_string(mode) + " (expected 0..3)");
      if (gain > 2) return garbage("gain schedule " + std::to_string(gain) + " (expected 0..2)");
      RmpModeFrame m;
      m.mode = static_cast<OperationalMode>(mode);
      m.gain_schedule = static_cast<GainSchedule>(gain);
      m.ui_battery_v = 1.4 + 0.0125 * GetU16(d, 2);
      m.base_battery_v = GetU16(d, 3) / 4.0;
      if (m.ui_battery_v > kMaxUiBatteryV || m.base_battery_v > kMaxBaseBatteryV) {
        return garbage("battery voltages " + FormatNumber(m.ui_battery_v) + " V / " + FormatNumber(m.base_battery_v) +
                       " V beyond 20 V / 100 V");
      }
      return RmpStatusMessage(m);
    }
    case kRmpIdStatusLast: {
      RmpCommandEchoFrame m{GetI16(d, 0), GetI16(d, 1)};
      if (std::abs(m.velocity_counts) > kRmpMaxVelocityCounts || std::abs(m.turn_counts) > kRmpMaxTurnCounts) {
        return garbage("command echo " + std::to_string(m.velocity_counts) + " / " + std::to_string(m.turn_counts) +
                       " counts beyond +-1176 / +-1024");
      }
      return RmpStatusMessage(m);
    }
    case kRmpIdCuStatus: return RmpStatusMessage(RmpCuStatusFrame{GetU16(d, 1), GetU16(d, 2)});
    default: break;
  }
  return NotFound("CAN frame " + CodecHexId(id) + " is no RMP status frame");
}

hal::CanFrame RmpCodec::Encode(const RmpBuildFrame& m) const {
  hal::CanFrame f = StatusFrame(0x400);
  PutU16(&f.data, 0, m.build_id);
  return f;
}

hal::CanFrame RmpCodec::Encode(const RmpTiltFrame& m) const {
  hal::CanFrame f = StatusFrame(kRmpIdTilt);
  PutI16(&f.data, 0, SaturateToI16(RadToDeg(m.pitch_rad) * scales_.tilt_counts_per_deg));
  PutI16(&f.data, 1, SaturateToI16(RadToDeg(m.pitch_rate_rps) * scales_.rate_counts_per_degps));
  PutI16(&f.data, 2, SaturateToI16(RadToDeg(m.roll_rad) * scales_.tilt_counts_per_deg));
  PutI16(&f.data, 3, SaturateToI16(RadToDeg(m.roll_rate_rps) * scales_.rate_counts_per_degps));
  return f;
}

hal::CanFrame RmpCodec::Encode(const RmpSpeedFrame& m) const {
  hal::CanFrame f = StatusFrame(kRmpIdSpeeds);
  PutI16(&f.data, 0, SaturateToI16(m.left_wheel_mps * scales_.wheel_speed_counts_per_mps));
  PutI16(&f.data, 1, SaturateToI16(m.right_wheel_mps * scales_.wheel_speed_counts_per_mps));
  PutI16(&f.data, 2, SaturateToI16(options_.yaw_rate_sign * RadToDeg(m.yaw_rate_rps) * scales_.rate_counts_per_degps));
  PutU16(&f.data, 3, m.servo_frames);
  return f;
}

hal::CanFrame RmpCodec::Encode(const RmpWheelIntegratorFrame& m) const {
  hal::CanFrame f = StatusFrame(kRmpIdWheelIntegrators);
  PutWordSwappedU32(&f.data, 0, m.left_counts);
  PutWordSwappedU32(&f.data, 2, m.right_counts);
  return f;
}

hal::CanFrame RmpCodec::Encode(const RmpBodyIntegratorFrame& m) const {
  hal::CanFrame f = StatusFrame(kRmpIdBodyIntegrators);
  PutWordSwappedU32(&f.data, 0, m.fore_aft_counts);
  PutWordSwappedU32(&f.data, 2, m.yaw_counts);
  return f;
}

hal::CanFrame RmpCodec::Encode(const RmpTorqueFrame& m) const {
  hal::CanFrame f = StatusFrame(kRmpIdTorques);
  PutI16(&f.data, 0, SaturateToI16(m.left_nm * scales_.torque_counts_per_nm));
  PutI16(&f.data, 1, SaturateToI16(m.right_nm * scales_.torque_counts_per_nm));
  return f;
}

hal::CanFrame RmpCodec::Encode(const RmpModeFrame& m) const {
  hal::CanFrame f = StatusFrame(kRmpIdMode);
  PutU16(&f.data, 0, static_cast<uint16_t>(m.mode));
  PutU16(&f.data, 1, static_cast<uint16_t>(m.gain_schedule));
  PutU16(&f.data, 2, SaturateToU16((m.ui_battery_v - 1.4) / 0.0125));
  PutU16(&f.data, 3, SaturateToU16(m.base_battery_v * 4.0));
  return f;
}

hal::CanFrame RmpCodec::Encode(const RmpCommandEchoFrame& m) const {
  hal::CanFrame f = StatusFrame(kRmpIdStatusLast);
  PutI16(&f.data, 0, m.velocity_counts);
  PutI16(&f.data, 1, m.turn_counts);
  return f;
}

hal::CanFrame RmpCodec::Encode(const RmpCuStatusFrame& m) const {
  hal::CanFrame f = StatusFrame(kRmpIdCuStatus);
  PutU16(&f.data, 1, m.word1);
  PutU16(&f.data, 2, m.word2);
  // libsegwayrmp reads byte 3 == 0x80 as "motors enabled": the low byte of word 1 carries 0x80.
  return f;
}

}  // namespace idi::rmp
