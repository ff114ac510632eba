// The planner (§8.12.4): from the track ahead (odometry frame) and the vehicle's state, the speed and
// yaw rate to command now.
//
// 1. Path. The track's centre polyline is simplified and every corner becomes an arc. The arc cuts the
//    corner by `corner_cut_m`; where the cameras would then lose the coming track (the dissertation's
//    "if the RMP waits to make a turn ... it will no longer see the track") the arc grows - the
//    vehicle turns earlier - up to `max_corner_cut_m`, the least cut that keeps the track in view
//    along the whole turn (checked against the cameras' ground footprints).
// 2. Speed profile along the path: cruise speed, lowered on arcs so that yaw rate, yaw acceleration
//    and lateral acceleration stay within their limits, lowered where the track ahead was seen only
//    once (uncertain), and braking to a stop at the end of the known track (the track's end, or the
//    horizon of what has been seen - so the vehicle can always stop on track it has seen).
// 3. Tracking: the actuation delay of the RMP (command latency plus its response lag) is bridged by
//    predicting the pose the vehicle will have when a command takes effect, from the commands still in
//    flight; at that pose a path-following law (curvature feed-forward with preview, plus lateral and
//    heading feedback critically damped over a distance) gives the yaw rate.
// 4. Limits: speed, acceleration, yaw rate and yaw acceleration as configured; never reversing.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <string>
#include <vector>

#include "rmp/planning/path.h"
#include "rmp/track/pose2.h"
#include "rmp/track/track_model.h"
#include "shared/util/status.h"

namespace idi::rmp {

struct PlannerOptions {
  double cruise_speed_mps = 0.5;
  // Limits (the RMP enforces its own too; these are what the planner asks for at most).
  double max_speed_mps = 1.5;
  double max_accel_mps2 = 0.6;
  double max_decel_mps2 = 0.8;
  double max_yaw_rate_rps = 1.5;
  double max_yaw_accel_rps2 = 5.0;
  double max_lateral_accel_mps2 = 1.0;
  // Corners.
  double corner_cut_m = 0.02;
  double max_corner_cut_m = 0.20;
  double min_corner_turn_deg = 4.0;        // smaller bends are left to the tracking law
  double simplify_tolerance_m = 0.004;
  // Visibility: along each turn the coming `visibility_check_m` of track must show at least
  // `visibility_min_m` of tape inside every camera's footprint.
  bool keep_track_in_view = true;
  double visibility_check_m = 0.6;
  double visibility_min_m = 0.12;
  // RMP response model for the delay prediction.
  double command_latency_s = 0.05;
  double response_time_constant_s = 0.08;
  double control_period_s = 0.02;
  // Tracking law.
  double tracking_min_length_m = 0.12;  // lateral convergence distance at low speed
  double tracking_time_s = 0.45;        // ... and the time that scales it with speed
  double preview_time_s = 0.1;
  double pivot_heading_error_deg = 50;  // turn on the spot beyond this heading error
  double max_lateral_error_m = 0.3;     // farther off the path than this: stop (track lost)
  // Uncertainty: track ahead seen fewer than `min_support` times is driven at this fraction of cruise.
  int min_support = 2;
  double uncertain_speed_fraction = 0.5;
  double stop_margin_m = 0.0;  // stop this far before the end of the known track

  Status Check() const;
};

struct PlannerInput {
  int64_t now_ns = 0;
  Pose2 odom_from_vehicle;  // current estimate
  double speed_mps = 0.0;   // measured
  double yaw_rate_rps = 0.0;
  TrackAhead track;         // odometry frame
  std::vector<std::vector<Vec2d>> footprints_m;  // per camera, vehicle frame (empty: no visibility check)
};

enum class PlanState { kFollow, kCorner, kUncertain, kApproachEnd, kAtEnd, kPivot, kNoTrack, kOffTrack };
const char* PlanStateName(PlanState state);

struct PlanOutput {
  double speed_mps = 0.0;
  double yaw_rate_rps = 0.0;
  PlanState state = PlanState::kNoTrack;
  double lateral_error_m = 0.0;      // at the predicted pose
  double heading_error_rad = 0.0;
  double distance_to_stop_m = 0.0;   // along the path to where it will stop
  double corner_radius_m = 0.0;      // of the next corner (0 when none ahead)
  bool corner_in_view = true;        // the next corner's turn keeps the track in view
  bool stopped() const { return speed_mps == 0.0 && yaw_rate_rps == 0.0; }
};

class Planner {
 public:
  explicit Planner(const PlannerOptions& options = {});
  const PlannerOptions& options() const { return options_; }
  void set_cruise_speed(double speed_mps) { options_.cruise_speed_mps = speed_mps; }

  PlanOutput Plan(const PlannerInput& input);
  // Tell the planner what was actually commanded (zero when the safety layer overrode it), so the
  // delay prediction and the rate limits start from it.
  void CommandSent(int64_t t_ns, double speed_mps, double yaw_rate_rps);
  void Reset();

  // The path of the last Plan() (odometry frame), for logs and plots.
  const SmoothPath& path() const { return path_; }

 private:
  Pose2 PredictPose(const PlannerInput& input, double* speed, double* yaw_rate) const;
  std::vector<double> CornerRadii(const std::vector<Vec2d>& vertices, const Pose2& odom_from_vehicle,
                                  const std::vector<std::vector<Vec2d>>& footprints, std::vector<bool>* in_view);
  bool TurnKeepsTrackInView(const std::vector<Vec2d>& vertices, std::size_t corner, double radius,
                            const std::vector<std::vector<Vec2d>>& footprints) const;
  double SpeedLimitAt(double s, const TrackAhead& track, double s_stop) const;

  struct Sent {
    int64_t t_ns;
    double speed, yaw_rate;
  };
  PlannerOptions options_;
  std::deque<Sent> sent_;
  SmoothPath path_;
  std::map<std::pair<long, long>, std::pair<double, bool>> radius_cache_;  // corner vertex (cm grid) -> radius
};

}  // namespace idi::rmp
