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
// 4. Limits: speed, acceleration, yaw rate and yaw acceleration as configured, never reversing; the
//    speed profile brakes at max_decel_mps2, and the command may brake at up to twice that when a stop
//    point appears closer than the profile allows (a margin the RMP's own limits then bound).
// 5. Blind acute corners. A corner turning by more than `pivot_corner_min_turn_deg` (an acute corner:
//    the next leg runs back at less than 90 deg to the one driven) cannot be driven as a curve that
//    keeps the track perceived: near the vertex the next leg lies beside or behind the vehicle,
//    outside the cameras' ground footprint, and the stubs of tape still in view at the image's lower
//    border are too short to be perceived as tape (no strip), so the track goes unseen for longer than
//    the control loop's track-lost limit while the vehicle crawls round the tight arc. (The footprint
//    check of 1. can pass such a corner: a few cm of each leg stay inside the footprint.) The
//    dissertation's RMP is a differential drive and can turn on the spot (§8.12.4), so:
//    a. the next leg is known from earlier sightings: during the approach, from further back, the
//       cameras see the far part of the next leg (the track model keeps it: a corner tip too short to
//       be perceived is no evidence against it, see TrackModelOptions::evidence_span_m);
//    b. within `pivot_commit_m` of the vertex the planner commits to the manoeuvre: it brakes to a
//       stop at the vertex, then turns on the spot towards the remembered leg's heading (updated
//       with every new observation) at up to `pivot_rate_rps`;
//    c. the leg is re-acquired when an observation newer than the start of the pivot has seen the
//       model beyond the vertex; the pivot ends when the vehicle faces the leg (within
//       `pivot_done_deg`) and it has been re-acquired, and following resumes;
//    d. bounds: the whole manoeuvre (approach from the commit point, pivot) lasts at most
//       `pivot_timeout_s`, the pivot turns at most the corner's turn plus `pivot_extra_deg`, and
//       facing the remembered leg without having seen it again is a failure, as is the corner
//       vanishing from the model (a view contradicted the leg): each stops the vehicle (kNoTrack) and
//       ends the manoeuvre, which is not retried at that vertex; from then on the control loop's
//       ordinary track-lost rule holds the vehicle until the track is seen again. Only while the
//       manoeuvre is committed and within these bounds may the control loop accept an association
//       older than its track-lost limit (corner_turn_active()); perception must stay fresh
//       throughout, and the pivot commands speed 0 (it begins within 3 cm of the vertex at under
//       0.05 m/s, or within 5 mm at whatever speed the approach's braking left, which the braking limit
//       then takes to 0 over a few ticks).
//    e. it is only attempted when the next leg is known for `pivot_min_leg_m` beyond the vertex from
//       repeated sightings (support >= min_support), so a spurious corner seen once is not turned.
//    In the twin (rmp/app/track_spec, the default rig) the far part of the next leg of the 120 and 135
//    deg corners is in view during the approach, so no exploratory (blind search) turn is needed; a
//    corner whose next leg was never seen is not turned - the vehicle stops at the end of the known
//    track as before.
#pragma once

#include <cstdint>
#include <deque>
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
  // Blind acute corners: stop at the vertex and turn on the spot (see 5. above).
  bool pivot_at_blind_corners = true;
  double pivot_corner_min_turn_deg = 100.0;
  double pivot_commit_m = 0.35;
  double pivot_min_leg_m = 0.3;  // the next leg must be known this far from repeated sightings
  double pivot_rate_rps = 1.0;
  double pivot_timeout_s = 6.0;
  double pivot_extra_deg = 20.0;
  double pivot_done_deg = 4.0;
  // A blind corner's legs run to the nearest vertices at least this far from its vertex (nearer ones are
  // blips of the track model there, such as the tape's outer corner seen while pivoting).
  double corner_leg_min_m = 0.1;

  Status Check() const;
};

struct PlannerInput {
  int64_t now_ns = 0;
  Pose2 odom_from_vehicle;  // current estimate
  double speed_mps = 0.0;   // measured
  double yaw_rate_rps = 0.0;
  TrackAhead track;         // odometry frame (TrackAhead::seen_ns tells when each point was last seen)
  std::vector<std::vector<Vec2d>> footprints_m;  // per camera, vehicle frame (empty: no visibility check)
};

enum class PlanState {
  kFollow,
  kCorner,
  kUncertain,
  kApproachEnd,
  kAtEnd,
  kPivot,
  kCornerApproach,  // committed to a blind acute corner: braking to a stop at its vertex
  kCornerPivot,     // turning on the spot at its vertex towards the remembered next leg
  kNoTrack,
  kOffTrack,
};
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
  // Committed to a blind acute corner (5. above) and within its bounds as of the last Plan(): the
  // track may go unseen for up to pivot_timeout_s from the commit.
  bool corner_turn_active() const { return corner_turn_.committed; }
  // Why the last blind-corner manoeuvre was abandoned (empty: none was).
  const std::string& corner_turn_failure() const { return corner_turn_failure_; }

 private:
  Pose2 PredictPose(const PlannerInput& input, double* speed, double* yaw_rate) const;
  std::vector<double> CornerRadii(const std::vector<Vec2d>& vertices, const Pose2& odom_from_vehicle,
                                  const std::vector<std::vector<Vec2d>>& footprints, std::vector<bool>* in_view);
  bool TurnKeepsTrackInView(const std::vector<Vec2d>& vertices, std::size_t corner, double radius,
                            const std::vector<std::vector<Vec2d>>& footprints) const;
  double SpeedLimitAt(double s, const TrackAhead& track, double s_stop) const;

  // The blind-corner manoeuvre (5. above). Returns true when it decided the output (`out` filled).
  bool BlindCorner(const PlannerInput& input, const Pose2& predicted, const PathProjection& proj, double v_pred,
                   double* s_stop, double* v_cmd, double* w_cmd, PlanOutput* out);
  void FailCornerTurn(const std::string& why);
  // Arc length before which the path is not searched: the far end of corners already turned on the
  // spot (the vehicle stands at their vertex, as close to the leg before as to the one after).
  double TurnedCornerEnd() const;

  struct CornerTurn {
    bool committed = false;
    bool pivoting = false;
    int64_t commit_ns = 0, pivot_ns = 0;
    Vec2d vertex = Vec2d::Zero();  // odometry frame
    double turn_rad = 0.0;         // the corner's turn (signed, left positive)
    double last_yaw = 0.0, turned_rad = 0.0;  // accumulated pivot angle
  };
  struct Sent {
    int64_t t_ns;
    double speed, yaw_rate;
  };
  PlannerOptions options_;
  std::deque<Sent> sent_;
  SmoothPath path_;
  // Radii decided for corners (odometry frame). A turn found to keep the track in view is reused while
  // the corner's vertex and turn stay within a few cm and degrees: fusion moves a vertex by millimetres
  // from frame to frame, and re-deciding as the vehicle reaches the corner would swap a tight turn for a
  // wide one too late to follow. A corner found not in view is decided again every time.
  struct CachedCorner {
    Vec2d vertex;
    double turn_rad;
    double radius_m;
    bool visible;
  };
  std::vector<CachedCorner> radius_cache_;
  CornerTurn corner_turn_;
  std::string corner_turn_failure_;
  std::vector<Vec2d> corners_failed_;  // vertices where the manoeuvre failed: not retried
  std::vector<Vec2d> corners_turned_;  // vertices already turned (odometry frame)
};

}  // namespace idi::rmp
