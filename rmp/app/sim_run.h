// `idi-rmp sim`: the closed loop in the twin (DESIGN.md §6), and the report it shares with `replay`.
#pragma once

#include <atomic>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "rmp/app/control_loop.h"
#include "rmp/app/rmp_config.h"
#include "rmp/app/sim_world.h"
#include "rmp/app/track_spec.h"

namespace idi::rmp {

// The report of a run (DESIGN.md §6 fields first; the rest are extras).
struct RunReport {
  bool completed = false;
  double distance_m = 0.0, time_s = 0.0;
  double lateral_error_rms_m = 0.0, lateral_error_max_m = 0.0;
  double track_visible_fraction = 0.0;
  uint64_t frames = 0;  // stereo pairs perceived
  double perception_ms_median = 0.0, perception_ms_p99 = 0.0;
  uint64_t commands = 0;  // command frames sent to the RMP
  // Extras.
  uint64_t commands_nonzero = 0;
  double end_distance_m = -1.0;  // truth (sim only)
  std::string end;               // "finished", "time-limit" (sim), "max_run_s" (hardware), "stopped", "error: ..."
  double cruise_speed_mps = 0.0, max_speed_mps = 0.0;
  double frame_to_command_ms_median = 0.0, frame_to_command_ms_p99 = 0.0;
  uint64_t frozen_frames = 0, dropped_frames = 0, unpaired_frames = 0, perception_errors = 0;
  uint64_t pairs_without_pose = 0, pairs_from_the_future = 0;  // pairs not perceived (ControlLoopStats)
  std::map<std::string, uint64_t> decisions;
  nlohmann::json extra = nlohmann::json::object();  // replay: command comparison; files written

  nlohmann::json ToJson() const;
};

struct SimRunOptions {
  RmpConfig config = DefaultRmpConfig();
  std::string config_text;  // the configuration file's text (saved in the drive log for replay)
  TrackSpec track;
  std::string record_dir;             // drive log; empty: none
  std::string can_log;                // candump log of the driver's bus; empty: none
  std::string png;                    // track, driven path and lateral error; empty: none
  double max_time_s = 0.0;            // 0: 2.5 x the track's length at cruise speed + 30 s
  bool real_time = false;             // pace the twin with the wall clock (the `run` command)
  std::atomic<bool>* stop = nullptr;  // set by a signal: stop (zero) and end
  std::function<void(const TickRecord&, SimWorld&, const ControlLoop&)> on_tick;  // tests
};

struct SimRunResult {
  RunReport report;
  SimTruth truth;
  ControlLoopStats stats;
  double render_wall_s = 0.0;  // SimWorld::render_wall_s at the end
  // An output (the drive log's end, the CAN log, the PNG) that could not be written after the run; the
  // report is whole all the same, so that the caller can show it before failing.
  Status output_status;
};

// Fails when the run could not start or a tick failed; a failure to write an output after the run is
// in SimRunResult::output_status instead (check it).
Result<SimRunResult> RunSimulation(const SimRunOptions& options);

// The PNG: the track (tape and gaps), the driven path coloured by lateral error, and the lateral
// error along the track below it.
Status WriteRunPng(const std::string& path,
                   const TrackSpec& track,
                   const SimTruth& truth,
                   const std::vector<std::pair<double, double>>& covered_m,
                   const std::string& title);

}  // namespace idi::rmp
