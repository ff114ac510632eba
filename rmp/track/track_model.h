// The track in the odometry frame, fused over time from the stereo observations with the RMP's wheel
// odometry (§8.12.4: the cameras look ahead, so the vehicle drives on track it saw earlier and the
// model carries it, through odometry, to where the vehicle is).
//
// The model is the centre line as dense samples in travel order. Each observation is placed in the
// odometry frame with the odometry pose at its exposure time, then
//  - associated: every perceived piece is matched to the model where it lies within a gate of it;
//  - fused: the observed stretch replaces the model where they overlap (its vertices kept, so corners
//    stay sharp), pulled back towards the old model by (1 - blend) - a running average in which the
//    newest, nearest view dominates; the support of what was seen again grows; samples the cameras
//    should have seen but did not lose support, and an unconfirmed far end is dropped;
//  - extended: a piece continuing the model's far end is appended; a piece beyond a visible tape end,
//    in line with it and no further than `max_gap_m`, is appended behind a straight "gap" link;
//  - ended: when a tape end has been seen with `end_confirm_m` of clear ground beyond it (no
//    continuation possible), the end is the track's end.
// The vehicle's progress along the model is tracked so that other tape in view (the loop coming back
// by) is never mistaken for the track ahead.
#pragma once

#include <cstdint>
#include <vector>

#include "rmp/track/pose2.h"
#include "rmp/track/track_observation.h"
#include "shared/util/status.h"

namespace idi::rmp {

struct TrackModelOptions {
  double sample_spacing_m = 0.01;
  double association_gate_m = 0.08;  // a perceived point this close to the model is the same tape
  double blend = 0.7;                // weight of a new observation where it overlaps the model
  double join_distance_m = 0.12;     // a piece starting this close to the model's end continues it
  double max_gap_m = 1.3;            // longest stretch without tape bridged between two pieces
  double max_gap_angle_deg = 20.0;   // the far piece lies within this cone of the near piece's end
  double end_confirm_m = 1.3;        // clear ground seen beyond a tape end that makes it the track's end
  double start_search_m = 1.2;       // the first observation's track starts this close to the vehicle
  double keep_behind_m = 0.5;        // model kept behind the vehicle
  int max_support = 8;               // support saturates here
  double footprint_margin_m = 0.05;  // a sample counts as "in view" this far inside a footprint
  // Tape is only perceived as a strip of some length (tape_geometry's min_piece_length_m, and both
  // edges inside the images): a sample counts as contradicted (in view, no tape seen) only when the
  // model this far on either side of it is in view as well. The tip of a corner whose next leg runs
  // out of the view (an acute corner under the vehicle) is no evidence against that leg.
  double evidence_span_m = 0.08;

  Status Check() const;
};

struct TrackSample {
  Vec2d xy = Vec2d::Zero();  // odometry frame
  int support = 1;           // observations that saw tape here (capped)
  bool gap = false;          // a bridged stretch without tape (its ends were seen)
  int64_t seen_ns = 0;       // exposure time of the newest observation that saw it
};

// The track ahead of the vehicle, as the planner sees it.
struct TrackAhead {
  std::vector<Vec2d> points;   // odometry frame, from `behind_m` behind the progress point forward
  std::vector<int> support;    // per point
  std::vector<bool> gap;       // per point: the stretch after it is a bridged gap
  std::vector<int64_t> seen_ns;  // per point: exposure time of the newest observation that saw it
  double length_m = 0.0;
  double progress_offset_m = 0.0;  // arc length from points.front() to the progress point
  bool end_known = false;      // the last point is the track's end
  bool valid() const { return points.size() >= 2; }
};

struct TrackUpdateStats {
  int pieces = 0;
  int pieces_associated = 0;  // overlapping the model
  int pieces_appended = 0;    // continuing it (incl. across a gap)
  int pieces_ignored = 0;     // other tape, or not connected to the track
  int samples_dropped = 0;    // unconfirmed model samples removed
  bool initialised = false;   // this update started the model
};

class TrackModel {
 public:
  explicit TrackModel(const TrackModelOptions& options = {});

  // Fuses one observation taken with the vehicle at `odom_from_vehicle`. Non-finite inputs are
  // rejected (InvalidArgument) and leave the model unchanged.
  Result<TrackUpdateStats> Update(const TrackObservation& observation, const Pose2& odom_from_vehicle);
  // Moves the vehicle's progress point to the model point closest to the vehicle (searching a window
  // around the previous progress). Call with every new odometry pose.
  void UpdateProgress(const Pose2& odom_from_vehicle);

  // The model from `behind_m` behind the progress point (so a corner being driven stays in the path)
  // to at most `max_length_m` ahead of it.
  TrackAhead Ahead(double max_length_m = 1e9, double behind_m = 0.3) const;

  bool initialised() const { return !samples_.empty(); }
  bool end_known() const { return end_known_; }
  // Arc length of the vehicle's progress point from the model's first sample (the model's start moves
  // as samples behind the vehicle are pruned; distance_along_m() does not).
  double progress_index_s() const;
  double distance_along_m() const { return distance_along_m_; }
  int64_t last_associated_ns() const { return last_associated_ns_; }
  const std::vector<TrackSample>& samples() const { return samples_; }
  std::size_t progress_index() const { return progress_; }
  // Lateral distance of the vehicle from the model at the last UpdateProgress (signed, left positive).
  double vehicle_offset_m() const { return vehicle_offset_m_; }
  void Reset();

 private:
  void Initialise(const std::vector<Vec2d>& piece, int64_t seen_ns);
  std::vector<Vec2d> Densify(const std::vector<Vec2d>& pts) const;
  bool InView(const std::vector<std::vector<Vec2d>>& footprints_odom, const Vec2d& p) const;
  // Per sample: it and the model within evidence_span_m either side of it are in view.
  std::vector<char> StretchInView(const std::vector<std::vector<Vec2d>>& footprints_odom) const;

  TrackModelOptions options_;
  std::vector<TrackSample> samples_;
  std::size_t progress_ = 0;
  double vehicle_offset_m_ = 0.0;
  double distance_along_m_ = 0.0;
  bool end_known_ = false;
  bool end_seen_ = false;           // the last sample is a visible tape end
  double clear_beyond_end_m_ = 0.0;  // clear ground seen beyond it
  int64_t last_associated_ns_ = 0;
};

}  // namespace idi::rmp
