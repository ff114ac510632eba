// The Segway RMP's CAN protocol (classic RMP 50/100/200/400), a pure codec: CAN frames <-> structs
// in physical units. No I/O, no clock. Facts and their sources: ../shared/reference/
// device-protocols.md §1 (the RMP itself: dissertation §3.7; its use on the track: §8.12.4).
//
// Wire format: standard 11-bit ids, DLC 8, every 16-bit slot big-endian (slot k = bytes 2k, 2k+1);
// 32-bit integrators are word-swapped: value = (slot1 << 16) | slot0.
//
// Frame of reference: decoded values use x forward, y left, yaw counter-clockwise positive
// (REP-103). The RMP reports clockwise yaw rate as positive (Player negates it), so the yaw-rate and
// integrated-yaw signs are options; so is the turn command's sign (libsegwayrmp: positive turns left).
#pragma once

#include <array>
#include <cstdint>
#include <string_view>
#include <variant>

#include "shared/hal/can_bus.h"
#include "shared/util/status.h"

namespace idi::rmp {

enum class RmpModel { kRmp50, kRmp100, kRmp200, kRmp400 };
const char* RmpModelName(RmpModel model);  // "rmp200"
// Parses "rmp50", "rmp100", "rmp200", "rmp400" (case-insensitive, "RMP 200" too).
Result<RmpModel> ParseRmpModel(std::string_view text);

// Status scale factors (device-protocols.md §1.4). The RMP 400 is two RMP 200 bases.
struct RmpScaleFactors {
  double wheel_speed_counts_per_mps = 332.0;
  double distance_counts_per_m = 33215.0;
  double yaw_counts_per_rev = 112644.0;
  double torque_counts_per_nm = 1094.0;
  double tilt_counts_per_deg = 7.8;
  double rate_counts_per_degps = 7.8;
  double sec_per_servo_frame = 0.01;
};
RmpScaleFactors ScaleFactorsFor(RmpModel model);

// CAN ids (device-protocols.md §1.2).
inline constexpr uint32_t kRmpIdStatusFirst = 0x400;  // 0x400..0x407: one 100 Hz status cycle
inline constexpr uint32_t kRmpIdTilt = 0x401;
inline constexpr uint32_t kRmpIdSpeeds = 0x402;
inline constexpr uint32_t kRmpIdWheelIntegrators = 0x403;
inline constexpr uint32_t kRmpIdBodyIntegrators = 0x404;
inline constexpr uint32_t kRmpIdTorques = 0x405;
inline constexpr uint32_t kRmpIdMode = 0x406;
inline constexpr uint32_t kRmpIdStatusLast = 0x407;  // command echo, closes the cycle
inline constexpr uint32_t kRmpIdShutdown = 0x412;
inline constexpr uint32_t kRmpIdCommand = 0x413;
inline constexpr uint32_t kRmpIdCuStatus = 0x680;
inline constexpr uint32_t kRmpIdUiHeartbeat = 0x688;

inline constexpr int kRmpMaxVelocityCounts = 1176;  // ~8 mph at velocity scale 1.0
inline constexpr int kRmpMaxTurnCounts = 1024;

// Configuration command ids (bytes 4-5 of 0x413).
enum class RmpConfigId : uint16_t {
  kNone = 0,
  kMaxVelocityScale = 10,   // 0..16 (16 = 100 %)
  kMaxAccelScale = 11,      // 0..16
  kMaxTurnScale = 12,       // 0..16
  kGainSchedule = 13,       // GainSchedule
  kCurrentLimitScale = 14,  // 0..256
  kBalanceLockout = 15,     // 0 balance allowed, 1 locked out
  kOperationalMode = 16,    // OperationalMode
  kResetIntegrators = 50,   // bit mask kRmpReset*
};
const char* RmpConfigIdName(RmpConfigId id);

enum class OperationalMode : uint16_t { kDisabled = 0, kTractor = 1, kBalance = 2, kPowerDown = 3 };
const char* OperationalModeName(OperationalMode mode);
enum class GainSchedule : uint16_t { kLight = 0, kTall = 1, kHeavy = 2 };

inline constexpr uint16_t kRmpResetRightWheel = 0x01;
inline constexpr uint16_t kRmpResetLeftWheel = 0x02;
inline constexpr uint16_t kRmpResetYaw = 0x04;
inline constexpr uint16_t kRmpResetForeAft = 0x08;
inline constexpr uint16_t kRmpResetAll = 0x0F;

// Status word 1 of 0x680 (ORCA rmpdefs.h).
inline constexpr uint16_t kRmpStatus1SafetyShutdown1 = 0x0001;
inline constexpr uint16_t kRmpStatus1SafetyShutdown2 = 0x0004;
inline constexpr uint16_t kRmpStatus1DisableResponse = 0x0008;
inline constexpr uint16_t kRmpStatus1SpeedLimited4Mph = 0x0010;
inline constexpr uint16_t kRmpStatus1SpeedLimitedZero = 0x0020;
inline constexpr uint16_t kRmpStatus1IntegrityFault = 0x0040;
inline constexpr uint16_t kRmpStatus1MotorsEnabled = 0x0080;
inline constexpr uint16_t kRmpStatus1BalanceMode = 0x0100;
inline constexpr uint16_t kRmpStatus1YawTransient = 0x0200;
inline constexpr uint16_t kRmpStatus1EmptyBattery = 0x0400;
inline constexpr uint16_t kRmpStatus1WheelSlip = 0x1000;
inline constexpr uint16_t kRmpStatus1MotorFeedbackFault = 0x2000;
inline constexpr uint16_t kRmpStatus1LowBattery = 0x4000;
// Bits of word 1 that mean the platform must not be driven.
inline constexpr uint16_t kRmpStatus1FaultMask = kRmpStatus1SafetyShutdown1 | kRmpStatus1SafetyShutdown2 |
                                                 kRmpStatus1IntegrityFault | kRmpStatus1EmptyBattery |
                                                 kRmpStatus1MotorFeedbackFault;
// Status word 2: side A in the low byte, side B in the high byte (same bits << 8).
inline constexpr uint16_t kRmpStatus2PitchLimit = 0x01;
inline constexpr uint16_t kRmpStatus2EStopOpen = 0x02;
inline constexpr uint16_t kRmpStatus2PositionErrorLimit = 0x04;
inline constexpr uint16_t kRmpStatus2MaxVelocity = 0x08;
inline constexpr uint16_t kRmpStatus2BatteryEmpty = 0x10;
inline constexpr uint16_t kRmpStatus2BatteryTemperature = 0x20;
inline constexpr uint16_t kRmpStatus2RollLimit = 0x40;
inline constexpr uint16_t kRmpStatus2LowBusVoltage = 0x80;
inline constexpr uint16_t kRmpStatus2FaultMask = 0x77;  // all but max-velocity and low bus voltage
inline constexpr uint16_t kRmpStatus2LowBatteryMask = 0x90;

// ---- command frame 0x413 ----

struct RmpCommandFrame {
  int16_t velocity_counts = 0;
  int16_t turn_counts = 0;
  uint16_t config_id = 0;  // RmpConfigId; 0 = motion only
  uint16_t config_param = 0;
};
// Bytes 0-1 velocity, 2-3 turn, 4-5 config id, 6-7 parameter, all big-endian. The parameter is a
// full big-endian uint16 as ORCA sends it (libsegwayrmp writes byte 7 only, which is the same for
// values below 256; Player copies the byte into both, which we do not).
hal::CanFrame EncodeCommandFrame(const RmpCommandFrame& command);
// For the simulated RMP. ParseError for a wrong id, a truncated frame or counts beyond the limits.
Result<RmpCommandFrame> DecodeCommandFrame(const hal::CanFrame& frame);
hal::CanFrame EncodeShutdownFrame();

struct RmpConfigRequest {
  RmpConfigId id = RmpConfigId::kNone;
  uint16_t param = 0;
};
// Velocity, acceleration and turn scales take a fraction 0..1 sent as floor(16 * fraction);
// the current limit takes 0..1 sent as floor(256 * fraction) (1.0 -> 0x0100). OutOfRange otherwise.
Result<RmpConfigRequest> MakeScaleConfig(RmpConfigId id, double fraction);
RmpConfigRequest MakeGainScheduleConfig(GainSchedule schedule);
RmpConfigRequest MakeBalanceLockoutConfig(bool locked_out);
RmpConfigRequest MakeOperationalModeConfig(OperationalMode mode);
RmpConfigRequest MakeResetIntegratorsConfig(uint16_t mask = kRmpResetAll);

// How physical commands become counts. The velocity scale is the status scale (libsegwayrmp); the
// turn scale has no agreed value (device-protocols.md §1.6): the default is ORCA's 1024 counts ~
// pi rad/s; libsegwayrmp and Player use 7.8 counts per deg/s (446.9 per rad/s). The driver checks it
// against the measured yaw rate. Commands are divided by the configured scale fractions because
// the RMP multiplies them by those (ORCA's assumption).
struct RmpCommandScaling {
  double velocity_counts_per_mps = 332.0;
  double turn_counts_per_radps = 1024.0 / 3.14159265358979323846;
  int turn_sign = +1;  // +1: positive counts turn left (counter-clockwise)
  double velocity_scale_fraction = 1.0;
  double turn_scale_fraction = 1.0;

  Status Check() const;
};

struct RmpMotionCounts {
  int16_t velocity = 0;
  int16_t turn = 0;
  bool velocity_saturated = false;  // clipped at +-1176
  bool turn_saturated = false;      // clipped at +-1024
  bool invalid_input = false;       // NaN or infinite input: sent as zero
};
RmpMotionCounts MotionToCounts(double speed_mps, double yaw_rate_rps, const RmpCommandScaling& scaling);
// The inverse (what a command in counts asks for), for echoes and the simulated RMP.
double VelocityCountsToMps(int counts, const RmpCommandScaling& scaling);
double TurnCountsToRadps(int counts, const RmpCommandScaling& scaling);

// ---- status frames ----

struct RmpBuildFrame {  // 0x400
  uint16_t build_id = 0;
};
struct RmpTiltFrame {  // 0x401
  double pitch_rad = 0, pitch_rate_rps = 0, roll_rad = 0, roll_rate_rps = 0;
};
struct RmpSpeedFrame {  // 0x402
  double left_wheel_mps = 0, right_wheel_mps = 0;
  double yaw_rate_rps = 0;  // counter-clockwise positive
  uint16_t servo_frames = 0;
};
struct RmpWheelIntegratorFrame {  // 0x403, raw counts (they roll over)
  uint32_t left_counts = 0, right_counts = 0;
};
struct RmpBodyIntegratorFrame {  // 0x404, raw counts
  uint32_t fore_aft_counts = 0, yaw_counts = 0;
};
struct RmpTorqueFrame {  // 0x405
  double left_nm = 0, right_nm = 0;
};
struct RmpModeFrame {  // 0x406
  OperationalMode mode = OperationalMode::kDisabled;
  GainSchedule gain_schedule = GainSchedule::kLight;
  double ui_battery_v = 0, base_battery_v = 0;
};
struct RmpCommandEchoFrame {  // 0x407
  int16_t velocity_counts = 0, turn_counts = 0;
};
struct RmpCuStatusFrame {  // 0x680
  uint16_t word1 = 0, word2 = 0;
  bool motors_enabled() const { return (word1 & kRmpStatus1MotorsEnabled) != 0; }
  bool fault() const { return (word1 & kRmpStatus1FaultMask) != 0 || (word2 & (kRmpStatus2FaultMask | (kRmpStatus2FaultMask << 8))) != 0; }
  bool low_battery() const {
    return (word1 & kRmpStatus1LowBattery) != 0 || (word2 & (kRmpStatus2LowBatteryMask | (kRmpStatus2LowBatteryMask << 8))) != 0;
  }
};

using RmpStatusMessage = std::variant<RmpBuildFrame, RmpTiltFrame, RmpSpeedFrame, RmpWheelIntegratorFrame,
                                      RmpBodyIntegratorFrame, RmpTorqueFrame, RmpModeFrame, RmpCommandEchoFrame,
                                      RmpCuStatusFrame>;

struct RmpCodecOptions {
  RmpModel model = RmpModel::kRmp200;
  int yaw_rate_sign = -1;  // the RMP reports clockwise as positive (Player negates it)
  int yaw_integrator_sign = -1;

  Status Check() const;
};

// Word-swapped 32-bit value at slots (slot, slot + 1): (slot+1 word << 16) | slot word.
uint32_t GetWordSwappedU32(const std::array<uint8_t, 8>& data, int slot);
void PutWordSwappedU32(std::array<uint8_t, 8>* data, int slot, uint32_t value);
// The shortest signed difference now - before of two rolling 32-bit counters.
int32_t IntegratorDelta(uint32_t now, uint32_t before);

class RmpCodec {
 public:
  explicit RmpCodec(const RmpCodecOptions& options = {});
  const RmpCodecOptions& options() const { return options_; }
  const RmpScaleFactors& scales() const { return scales_; }

  // NotFound for a frame that is no RMP status (another id, an extended id, an error frame);
  // ParseError for a truncated frame (DLC < 8), a remote frame with an RMP id, or contents no RMP
  // sends (out-of-range mode, impossible angles or speeds, commands beyond the limits).
  Result<RmpStatusMessage> Decode(const hal::CanFrame& frame) const;

  // Encoders for the simulated RMP: values are rounded to counts and saturated to their slots.
  hal::CanFrame Encode(const RmpBuildFrame& m) const;
  hal::CanFrame Encode(const RmpTiltFrame& m) const;
  hal::CanFrame Encode(const RmpSpeedFrame& m) const;
  hal::CanFrame Encode(const RmpWheelIntegratorFrame& m) const;
  hal::CanFrame Encode(const RmpBodyIntegratorFrame& m) const;
  hal::CanFrame Encode(const RmpTorqueFrame& m) const;
  hal::CanFrame Encode(const RmpModeFrame& m) const;
  hal::CanFrame Encode(const RmpCommandEchoFrame& m) const;
  hal::CanFrame Encode(const RmpCuStatusFrame& m) const;

  // Integrator counts (as a signed difference) in metres and radians (counter-clockwise).
  double DistanceMeters(int64_t counts) const { return static_cast<double>(counts) / scales_.distance_counts_per_m; }
  double YawRadians(int64_t counts) const;
  // Metres / radians to integrator counts (for the simulated RMP); wraps modulo 2^32.
  uint32_t DistanceCounts(double meters) const;
  uint32_t YawCounts(double radians) const;

 private:
  RmpCodecOptions options_;
  RmpScaleFactors scales_;
};

}  // namespace idi::rmp
