// The control loop of idi-rmp (§8.12.4; issue 8): at every command tick of the RMP driver (50 Hz by
// default, inside the RMP's 10-300 ms window) it
//   1. lets the driver read the RMP's status up to the tick (odometry, health);
//   2. takes the camera frames delivered since the last tick, pairs left and right, skips frozen
//      (repeated) frames, perceives the track on the newest pair and fuses it into the track model
//      with the odometry pose at the pair's exposure time;
//   3. decides: zero when the perception is older than max_perception_age_s, the wheel odometry is
//      older than max_odometry_age_s, the track is lost, the RMP's status is stale, the bus is off, the battery is low,
//      a fault bit is set, a stop was requested (shutdown, a signal) or the RMP driver is not running yet - otherwise
//      the planner's speed and yaw rate;
//   4. hands the command to the driver, which sends it on the tick (and zeroes it by itself when its
//      source data is stale);
//   5. logs every change of decision (and every tick into the drive log, when recording), and pings
//      the systemd watchdog.
// Everything runs on the driver's clock: real time on the vehicle, simulated time in the twin and in
// replay, so the same code drives all three.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rmp/perception/track_perception.h"
#include "rmp/planning/planner.h"
#include "rmp/segway/rmp_driver.h"
#include "rmp/track/track_model.h"
#include "shared/hal/camera.h"
#include "shared/replay/drive_log.h"
#include "shared/util/sample_reservoir.h"
#include "shared/util/status.h"

namespace idi::rmp {

// Where the loop's camera frames come from: V4L2 devices, the twin's rendered cameras, a log.
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // Frames delivered since the last call up to `now_ns` (any camera, in delivery order).
  virtual Result<std::vector<hal::Image>> Collect(int64_t now_ns) = 0;
};

// Upper bounds of the ages below that a configuration may set (the perception's is the driver's input
// age, kMaxInputAgeLimitS): a larger value in a file is a typo, not a choice.
inline constexpr double kMaxOdometryAgeLimitS = 0.5;
inline constexpr double kTrackLostLimitS = 5.0;

struct ControlLoopOptions {
  double max_perception_age_s = 0.2;  // older perception never moves the vehicle
  // Wheel odometry (the RMP's integrator frames, 100 Hz) older than this never moves the vehicle: the
  // status may stay fresh while the integrators alone stop or arrive malformed.
  double max_odometry_age_s = 0.1;
  double track_lost_s = 0.6;          // no perceived track matched the model for this long: lost
  double stereo_max_skew_s = 0.02;    // left and right frames further apart are not a pair
  double finish_hold_s = 1.0;         // stopped at the track's known end this long: done
  double start_timeout_s = 5.0;       // the RMP driver must be running by then
  double max_run_s = 0.0;             // the run stops (zero, then shutdown) after this long; 0: no limit

  Status Check() const;
};

// Why the tick commanded what it did.
enum class Decision {
  kDrive,          // the planner's command (possibly zero, see the plan state)
  kStopRequested,  // shutdown or a signal
  kRmpNotRunning,  // connecting, configuring, resetting odometry, or stopped
  kRmpStatusStale,
  kOdometryStale,  // no wheel integrators for max_odometry_age_s (or none yet)
  kBusOff,
  kLowBattery,
  kRmpFault,
  kNoPerception,  // no stereo pair perceived yet
  kPerceptionStale,
  kTrackLost,
  kAtEnd,  // stopped at the track's end
};
const char* DecisionName(Decision d);

struct TickRecord {
  int64_t t_ns = 0;
  Decision decision = Decision::kRmpNotRunning;
  PlanOutput plan;
  double speed_mps = 0.0, yaw_rate_rps = 0.0;  // what was given to the driver
  bool perceived = false;                      // a new stereo pair was perceived at this tick
  int64_t left_seq = -1, right_seq = -1;
  int64_t perception_exposure_ns = -1;         // of the newest perceived pair
  double perception_ms = 0.0;                  // CPU time of that perception
  Pose2 odom;                                  // odometry pose used
};

struct ControlLoopStats {
  uint64_t ticks = 0, frames = 0, pairs = 0, perceptions = 0, perception_errors = 0;
  uint64_t frozen_frames = 0, unpaired_frames = 0, dropped_frames = 0;
  // Pairs not perceived: exposed when the odometry gives no pose (none yet, older than its history, or
  // after its last update by more than max_odometry_age_s), or stamped ahead of the clock.
  uint64_t pairs_without_pose = 0, pairs_from_the_future = 0;
  uint64_t zero_ticks = 0, drive_ticks = 0;
  std::map<std::string, uint64_t> decisions;  // ticks per decision
  // Per perceived pair, bounded in memory for a service that runs for hours (exact percentiles for
  // runs of up to 16384 pairs, about 9 min at 30 Hz; a uniform sample of the run after that).
  SampleReservoir perception_ms;              // CPU time of the perception
  SampleReservoir track_update_ms;            // the track model's update (wall)
  SampleReservoir frame_to_command_ms;        // exposure to the tick that first used it
  int64_t running_since_ns = -1;              // the RMP driver reached running
  int64_t finished_ns = -1;                   // stopped at the end
};

class ControlLoop {
 public:
  // None of the pointers are owned; `log` may be null (no recording).
  ControlLoop(const ControlLoopOptions& options, hal::Clock* clock, RmpDriver* driver, FrameSource* frames,
              TrackPerception* perception, const PlannerOptions& planner, const TrackModelOptions& track,
              replay::DriveLogWriter* log);

  // Starts the driver (zero commands until the RMP answers and is configured).
  Status Start();
  // One tick at the driver's next command time. Returns the tick's record.
  Result<TickRecord> Step();
  // Latches a stop (zero from now on) - signals and shutdown.
  void RequestStop(const std::string& why);
  // Zero commands for the driver's shutdown period, then silence. Always call before exiting.
  Status Shutdown();

  // Called with each decision change (time, text) - the binary logs them.
  void SetDecisionSink(std::function<void(int64_t, const std::string&)> sink) { sink_ = std::move(sink); }

  bool finished() const { return stats_.finished_ns >= 0; }
  bool stop_requested() const { return stop_requested_; }
  const ControlLoopStats& stats() const { return stats_; }
  const TrackModel& track() const { return track_; }
  const Planner& planner() const { return planner_; }
  const PerceptionResult* last_perception() const { return last_result_ ? &*last_result_ : nullptr; }
  RmpDriver* driver() const { return driver_; }

 private:
  // The odometry pose at t_ns, interpolated in its history; none when the history does not cover t_ns
  // (empty, older than its first entry, or later than its last by more than max_odometry_age_s).
  std::optional<Pose2> OdometryAt(int64_t t_ns) const;
  void PerceivePair(const hal::Image& left, const hal::Image& right, TickRecord* rec);
  Decision Decide(int64_t now_ns, PlanOutput* plan, const Pose2& odom);

  ControlLoopOptions options_;
  hal::Clock* clock_;
  RmpDriver* driver_;
  FrameSource* frames_;
  TrackPerception* perception_;
  Planner planner_;
  TrackModel track_;
  replay::DriveLogWriter* log_;

  std::optional<hal::Image> latest_[2];      // newest frame per camera, not yet perceived
  std::map<std::string, uint64_t> last_hash_;  // per camera: content hash of the previous frame
  std::map<std::string, uint64_t> last_seq_;
  std::deque<std::pair<int64_t, Pose2>> odom_history_;
  int64_t last_perception_ns_ = -1;
  int64_t last_pair_exposure_ns_ = -1;
  int64_t start_ns_ = 0;
  int64_t at_end_since_ns_ = -1;
  bool stop_requested_ = false;
  std::string stop_reason_;
  Decision last_decision_ = Decision::kRmpNotRunning;
  bool first_tick_ = true;
  std::optional<PerceptionResult> last_result_;
  std::function<void(int64_t, const std::string&)> sink_;
  ControlLoopStats stats_;
};

}  // namespace idi::rmp
