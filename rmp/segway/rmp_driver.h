// The Segway RMP driver: a state machine on a hal::CanBus (SocketCAN on the vehicle, the twin's
// virtual bus in simulation, a log in replay) and a hal::Clock.
//
//   connecting   zero commands at the command rate until the RMP's status is heard
//   configuring  one configuration command per frame (scales, gain schedule, mode, ...), then the
//                operational mode and gain schedule are checked against status 0x406
//   resetting    integrator reset (command 50), confirmed from 0x403/0x404, else a software offset
//   running      motion commands from SetCommand(), zero whenever motion is inhibited
//   shutting down / stopped   zero commands for a while, then silence
//
// Safety (issue 8; device-protocols.md §1.5): a frame goes out every period (50 Hz by default,
// inside the RMP's 10-300 ms window) in every state but stopped. It carries zero unless the driver
// is running, a command was given, the data it came from is younger than max_input_age_s, status is
// fresh, the bus is not off, the battery is not low, no fault bit is set, no stop was requested and
// the turn direction checks out. Commands whose source data is already stale are refused outright.
//
// Single-threaded: call SetCommand(), Poll()/RunUntil() and Shutdown() from one thread.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rmp/segway/rmp_codec.h"
#include "rmp/segway/rmp_odometry.h"
#include "shared/hal/can_bus.h"
#include "shared/hal/can_error.h"
#include "shared/hal/clock.h"
#include "shared/replay/candump_log.h"
#include "shared/util/status.h"

namespace idi::rmp {

// The largest ages a configuration may set: data this old is no ground for motion (1 s at 1 m/s is a
// metre driven blind). The RMP sends status at 100 Hz and keeps a command about 0.4 s, so a longer
// silence is a lost machine. The control loop's perception age is the driver's input age.
inline constexpr double kMaxInputAgeLimitS = 1.0;
inline constexpr double kStatusTimeoutLimitS = 0.5;

struct RmpDriverOptions {
  RmpCodecOptions codec;  // model (default RMP 200) and yaw sign conventions
  // Command scaling; 0 = the model's wheel-speed scale (332 counts per m/s on an RMP 200).
  double velocity_counts_per_mps = 0.0;
  double turn_counts_per_radps = 1024.0 / 3.14159265358979323846;  // see rmp_codec.h
  int turn_sign = +1;

  double command_rate_hz = 50.0;  // the RMP wants a command every 10..300 ms
  double max_input_age_s = 0.2;   // perception older than this never moves the vehicle
  double max_input_future_s = 0.01;  // tolerated clock skew for input timestamps
  double status_timeout_s = 0.1;  // no status for this long: zero, and health says so

  // Configuration sent once the RMP is heard. Scales are fractions 0..1 (sent as 0..16);
  // a negative current limit leaves the RMP's own setting.
  double velocity_scale = 1.0;
  double accel_scale = 1.0;
  double turn_scale = 1.0;
  double current_limit_scale = -1.0;
  GainSchedule gain_schedule = GainSchedule::kLight;
  OperationalMode operational_mode = OperationalMode::kTractor;
  std::optional<bool> balance_lockout;  // unset: leave as is
  int config_repeats = 2;               // each configuration frame is sent this many times
  int mode_retries = 3;                 // mode/gain resent when 0x406 disagrees
  double config_verify_timeout_s = 0.3;
  // While running, no status for this long (longer than status_timeout_s): the RMP may have rebooted
  // with its boot scales and mode, so it is configured again when it answers before it may move.
  // A running RMP whose 0x406 shows another mode or gain schedule than the one it confirmed is too.
  double reconfigure_after_silence_s = 0.5;

  bool reset_integrators = true;
  double integrator_reset_timeout_s = 1.0;  // then fall back to a software offset
  double integrator_reset_tolerance_m = 0.02;

  // Battery limits (ORCA: base 66 V, UI 6 V); motion resumes 1 V above them.
  double min_base_battery_v = 66.0;
  double min_ui_battery_v = 6.0;

  // Turn-scale check: compares the commanded yaw rate with the measured one during steady turns.
  double turn_check_min_yaw_rate_rps = 0.15;
  double turn_check_max_speed_mps = 1.5;  // above ~518 counts the RMP treats turn as lateral accel
  double turn_check_settle_s = 0.6;
  int turn_check_min_samples = 50;
  double turn_check_tolerance = 0.2;  // |measured/commanded - 1| above this is a mismatch

  double bus_off_recovery_s = 0.5;  // wait this long before asking the bus to restart
  int shutdown_zero_frames = 10;

  RmpOdometryOptions odometry;

  Status Check() const;
};

// A motion request with the time of the data it was computed from (e.g. the camera exposure).
struct RmpMotionCommand {
  double speed_mps = 0.0;
  double yaw_rate_rps = 0.0;  // counter-clockwise positive
  int64_t source_timestamp_ns = 0;
};

enum class RmpDriverState { kIdle, kConnecting, kConfiguring, kResettingOdometry, kRunning, kShuttingDown, kStopped };
const char* RmpDriverStateName(RmpDriverState state);

// Reasons why the frame sent carries zero motion (bit mask).
inline constexpr uint32_t kRmpInhibitNotRunning = 1u << 0;
inline constexpr uint32_t kRmpInhibitNoCommand = 1u << 1;
inline constexpr uint32_t kRmpInhibitStaleCommand = 1u << 2;
inline constexpr uint32_t kRmpInhibitStopRequested = 1u << 3;
inline constexpr uint32_t kRmpInhibitStatusStale = 1u << 4;
inline constexpr uint32_t kRmpInhibitBusOff = 1u << 5;
inline constexpr uint32_t kRmpInhibitBusError = 1u << 6;
inline constexpr uint32_t kRmpInhibitLowBattery = 1u << 7;
inline constexpr uint32_t kRmpInhibitRmpFault = 1u << 8;
inline constexpr uint32_t kRmpInhibitTurnSignMismatch = 1u << 9;
// "status stale, low battery" ...
std::string DescribeRmpInhibits(uint32_t mask);

struct RmpDriverCounters {
  uint64_t frames_sent = 0, frames_received = 0;
  uint64_t send_errors = 0, receive_errors = 0;
  uint64_t decode_errors = 0;   // garbage or truncated RMP frames, counted and ignored
  uint64_t foreign_frames = 0;  // frames that are not RMP status (other nodes, other ids)
  uint64_t error_frames = 0;
  uint64_t status_cycles = 0, complete_cycles = 0;
  uint64_t motion_frames = 0, zero_frames = 0, config_frames = 0;
  uint64_t stale_commands_refused = 0, invalid_commands = 0, saturated_commands = 0;
  uint64_t status_timeouts = 0, bus_off_events = 0, bus_restart_requests = 0;
  uint64_t odometry_rejected = 0, log_errors = 0, late_ticks = 0;
  uint64_t reconfigurations = 0;  // configured again while running (a long silence, a changed mode)
};

enum class OdometryResetResult { kPending, kConfirmed, kSoftwareOffset, kNotRequested };
const char* OdometryResetResultName(OdometryResetResult r);

struct RmpTurnScaleCheck {
  int samples = 0;
  double ratio = 1.0;  // measured / commanded yaw rate (least squares over the window)
  bool valid = false;  // enough samples
  bool mismatch = false;
  bool sign_wrong = false;
  // What turn_counts_per_radps would make commanded and measured agree.
  double suggested_turn_counts_per_radps = 0.0;
};

struct RmpDriverHealth {
  RmpDriverState state = RmpDriverState::kIdle;
  uint32_t inhibit = kRmpInhibitNotRunning;
  bool status_fresh = false;
  int64_t last_status_ns = -1;  // receive time of the newest good status frame
  bool bus_off = false;
  hal::CanControllerState controller_state = hal::CanControllerState::kErrorActive;
  bool low_battery = false;
  bool rmp_fault = false;
  bool config_verified = false;
  OdometryResetResult odometry_reset = OdometryResetResult::kPending;
  RmpTurnScaleCheck turn_check;
  std::string last_event;  // the newest state change or fault, for logs
  RmpDriverCounters counters;

  bool motion_allowed() const { return inhibit == 0; }
};

// The newest value of every status field with the receive time of the frame it came from
// (-1: never received).
struct RmpStatusSnapshot {
  RmpBuildFrame build;
  int64_t build_ns = -1;
  RmpTiltFrame tilt;
  int64_t tilt_ns = -1;
  RmpSpeedFrame speeds;
  int64_t speeds_ns = -1;
  RmpWheelIntegratorFrame wheel_integrators;
  int64_t wheel_integrators_ns = -1;
  RmpBodyIntegratorFrame body_integrators;
  int64_t body_integrators_ns = -1;
  RmpTorqueFrame torques;
  int64_t torques_ns = -1;
  RmpModeFrame mode;
  int64_t mode_ns = -1;
  RmpCommandEchoFrame echo;
  double echo_speed_mps = 0.0, echo_yaw_rate_rps = 0.0;  // the echo through our command scaling
  int64_t echo_ns = -1;
  RmpCuStatusFrame cu_status;
  int64_t cu_status_ns = -1;
  int64_t cycle_end_ns = -1;  // receive time of the last 0x407
};

// The frame sent on one tick, for tests and decision logs.
struct RmpSentCommand {
  int64_t timestamp_ns = 0;
  RmpCommandFrame frame;
  uint32_t inhibit = 0;
  int64_t source_timestamp_ns = -1;  // of the command it carries (-1: none)
};

class RmpDriver {
 public:
  // `bus` and `clock` must outlive the driver.
  static Result<std::unique_ptr<RmpDriver>> Create(hal::CanBus* bus, hal::Clock* clock, const RmpDriverOptions& options);
  ~RmpDriver();
  RmpDriver(const RmpDriver&) = delete;
  RmpDriver& operator=(const RmpDriver&) = delete;

  // Begins: connecting, then configuring and resetting as the RMP answers. The first frame goes
  // out now.
  Status Start();
  // Reads every frame available now and sends the tick's frame if it is due. Never blocks.
  Status Poll();
  // Runs until the clock reaches `t_ns`: waits for frames with timeouts (real time on hardware,
  // simulated time on the virtual bus) and sends on schedule.
  Status RunUntil(int64_t t_ns);

  // The motion to send from now on. InvalidArgument for NaN/inf; FailedPrecondition (and zero from
  // now on) when its source data is already older than max_input_age_s or from the future.
  Status SetCommand(const RmpMotionCommand& command);
  // Zero from now on, until the next SetCommand().
  void CommandZero();
  // Latched stop (an operator, a signal, the control loop): zero until ClearStop().
  void RequestStop(const std::string& reason);
  void ClearStop();
  // Zero for shutdown_zero_frames periods, then stops sending (the RMP's own timeout then holds
  // it). Runs the loop on the driver's clock until done.
  Status Shutdown();

  // Every frame sent and received is written here (nullptr: no log). Not owned.
  void SetFrameLog(replay::CandumpWriter* log) { log_ = log; }
  // Called when the bus has been off for bus_off_recovery_s (e.g. SocketCanBus::Restart, or the
  // virtual bus's RestartEndpoint), and again every bus_off_recovery_s while it stays off.
  void SetBusRecovery(std::function<Status()> recover) { recover_ = std::move(recover); }
  // Called with every state change and fault (time, text); the binary logs them.
  void SetEventSink(std::function<void(int64_t, const std::string&)> sink) { event_sink_ = std::move(sink); }

  const RmpDriverHealth& health() const { return health_; }
  const RmpStatusSnapshot& status() const { return status_; }
  const RmpOdometry& odometry() const { return odometry_; }
  const RmpCodec& codec() const { return codec_; }
  const RmpCommandScaling& scaling() const { return scaling_; }
  const RmpDriverOptions& options() const { return options_; }
  int64_t next_send_ns() const { return next_send_ns_; }
  // Replay: the next tick at t_ns (not before now), as a recording's schedule had it. On the vehicle the
  // schedule starts at one clock reading and moves after a late tick, which a replay's clock cannot
  // reproduce by itself. InvalidArgument for a time already past.
  Status ResyncSchedule(int64_t t_ns);
  int64_t period_ns() const { return period_ns_; }
  // The last `n` frames sent (kept for tests and decision logs).
  const std::deque<RmpSentCommand>& recent_sent() const { return recent_sent_; }
  // The newest events (state changes, faults), oldest first.
  const std::deque<std::string>& recent_events() const { return recent_events_; }

 private:
  RmpDriver(hal::CanBus* bus, hal::Clock* clock, const RmpDriverOptions& options);
  void HandleFrame(const hal::CanFrame& frame);
  void HandleStatus(const RmpStatusMessage& message, int64_t t_ns);
  void HandleErrorFrame(const hal::CanFrame& frame);
  void EndOfCycle(int64_t t_ns);
  void UpdateInhibits(int64_t now_ns);
  void Tick(int64_t now_ns);
  void SendFrame(int64_t now_ns, const RmpCommandFrame& frame, uint32_t inhibit, int64_t source_ns);
  void SetState(RmpDriverState state, const std::string& why);
  void Event(const std::string& what);
  void QueueConfiguration();
  void TurnCheckSample(int64_t t_ns, double measured_yaw_rate_rps);
  void LogFrame(const hal::CanFrame& frame, replay::CanDirection direction);
  void MaybeTick(int64_t now_ns);
  bool Sending() const;

  hal::CanBus* bus_;
  hal::Clock* clock_;
  RmpDriverOptions options_;
  RmpCodec codec_;
  RmpCommandScaling scaling_;
  RmpOdometry odometry_;
  int64_t period_ns_;
  int64_t next_send_ns_ = 0;

  RmpDriverHealth health_;
  RmpStatusSnapshot status_;
  std::optional<RmpMotionCommand> command_;
  bool command_went_stale_ = false;
  bool stop_requested_ = false;
  std::string stop_reason_;

  // Configuration and reset.
  std::deque<RmpConfigRequest> config_queue_;
  int mode_attempts_ = 0;
  bool reconfiguring_ = false;     // configuring again after running: the odometry keeps its pose
  int64_t running_since_ns_ = -1;  // when the driver last reached running
  int64_t config_sent_ns_ = -1;
  int64_t reset_started_ns_ = -1;
  int64_t reset_sent_ns_ = -1;
  int reset_frames_left_ = 0;
  int shutdown_frames_left_ = 0;

  // Status cycle bookkeeping.
  uint32_t cycle_seen_ = 0;  // bit (id - 0x400)
  bool wheel_integrators_in_cycle_ = false;
  bool body_integrators_in_cycle_ = false;
  bool status_was_fresh_ = false;

  // Bus state.
  int64_t bus_off_since_ns_ = -1;
  int64_t last_recovery_ns_ = -1;
  bool receive_failing_ = false;

  // Turn-scale check: the command in effect (sent counts), steady since when, and the pairs.
  int16_t steady_turn_counts_ = 0;
  int16_t steady_velocity_counts_ = 0;
  int64_t turn_steady_since_ns_ = -1;
  std::deque<std::pair<double, double>> turn_pairs_;  // (commanded, measured) rad/s
  double turn_sum_cm_ = 0.0, turn_sum_cc_ = 0.0;

  replay::CandumpWriter* log_ = nullptr;
  std::function<Status()> recover_;
  std::function<void(int64_t, const std::string&)> event_sink_;
  std::deque<RmpSentCommand> recent_sent_;
  std::deque<std::string> recent_events_;
  uint32_t last_fault_inhibits_ = 0;
};

}  // namespace idi::rmp
