// `idi-rmp replay DIR`: the pipeline re-run on a drive log on a desktop. The log's CAN frames arrive
// at their receive times and its images at their delivery times, on a simulated clock that starts
// where the log starts; the control loop runs the same ticks, and its commands are compared with the
// ones the log recorded (tick by tick, and frame by frame on the CAN bus).
#pragma once

#include <atomic>
#include <functional>
#include <string>

#include "rmp/app/sim_run.h"
#include "shared/replay/drive_log.h"

namespace idi::rmp {

struct ReplayOptions {
  std::string dir;
  std::string can_log;  // the frames the replayed driver sends (candump -l); empty: none
  // Set by a signal (the service's stop): the replay ends at the next tick, the driver sends its zero
  // commands and the report's end is "stopped", as in RunSimulation.
  std::atomic<bool>* stop = nullptr;
  std::function<void(const TickRecord&)> on_tick = {};  // tests
};

struct ReplayResult {
  RunReport report;
  uint64_t ticks_compared = 0, ticks_matching = 0;
  uint64_t ticks_resynced = 0;  // ticks whose time the driver's schedule did not give (a late tick on the vehicle)
  uint64_t can_frames_compared = 0, can_frames_matching = 0;
  double max_speed_difference_mps = 0.0, max_yaw_rate_difference_rps = 0.0;
  // The first tick whose command differs from the recorded one: its time from the first tick (the "t="
  // of the loop's messages) and its line in events.jsonl (-1 and 0: none).
  double first_tick_difference_s = -1.0;
  int first_tick_difference_line = 0;

  // Every compared tick and CAN frame as recorded.
  bool commands_reproduced() const {
    return ticks_matching == ticks_compared && can_frames_matching == can_frames_compared;
  }
};

// Reads the drive log options.dir and replays it.
Result<ReplayResult> RunReplay(const ReplayOptions& options);
// Replays a drive log already read from options.dir.
Result<ReplayResult> RunReplay(const ReplayOptions& options, const replay::DriveLog& log);

// The text summary of the comparison: "commands reproduced: yes (...)" or "commands reproduced: no (N of
// M ticks differ, first at t=... s, events.jsonl line L; ...)".
std::string ReplayComparisonSummary(const ReplayResult& result);

}  // namespace idi::rmp
