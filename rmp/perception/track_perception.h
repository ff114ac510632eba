// Perception of the taped track from the two fixed cameras (§8.12.4):
//
//   1. EMPL lines and IDI points of the tape edges in both images (chapter 7; shared/features), in
//      undistorted pixels;
//   2. stereo correspondence with the fixed pan-tilt calibration: the bundle correspondence of IDI
//      points and lines with the epipolar constraint and topology (§8.8; shared/reconstruction, the
//      same code the workcell uses), completed for lines that carry no IDI point (a straight tape) by
//      the plane-induced transfer of each line through the current ground plane;
//   3. triangulation of the matched points (§8.4) and lines (§8.5) in the vehicle's body frame;
//   4. the ground plane: the calibration's z = 0, refined from the triangulated points
//      (GroundPlaneEstimator) - it moves when the platform pitches or the calibration is off;
//   5. every tape edge placed on the refined ground, the two views merged, edges paired into strips of
//      the tape's width and strips joined at corners: the track's centre line as polylines in the
//      vehicle frame (tape_geometry.h).
//
// The output is a TrackObservation for the track model. One instance per camera pair; not thread safe.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

#include "rmp/perception/ground_plane.h"
#include "rmp/perception/tape_geometry.h"
#include "rmp/track/track_observation.h"
#include "rmp/vehicle/camera_rig.h"
#include "shared/features/features.h"
#include "shared/reconstruction/correspondence.h"
#include "shared/util/status.h"

namespace idi::rmp {

// The calibrated stereo pair: intrinsics and pose of each camera on the vehicle.
struct StereoRig {
  RigCamera left, right;
  Status Check() const;
};

struct PerceptionOptions {
  TapeGeometryOptions tape;
  bool tape_brighter = true;  // tape brighter than the floor (false: darker)
  FeatureOptions features = DefaultFeatureOptions();
  CorrespondenceOptions correspondence;
  GroundPlaneOptions ground;
  double max_range_m = 3.5;           // tape further than this (along the ground) is not used
  double border_margin_px = 4.0;      // a segment end this close to the border is cut by it
  double line_transfer_tolerance_px = 4.0;  // plane-induced line matching
  double line_transfer_angle_deg = 4.0;
  double min_line_triangulation_deg = 2.0;  // back-projected planes closer than this: no 3D line
  double max_point_reprojection_px = 1.5;
  double polarity_min_contrast = 6.0;  // grey levels; weaker edges get an unknown tape side
  // The two images' features on two threads (the left here, the right on a helper): the same result,
  // in about half the time on a machine with two free cores. Off: one thread.
  bool parallel_views = true;

  // Features for tape on a floor: straight edges only (no active contours); the photometric
  // refinement is left out for speed (the ground geometry is limited by the plane, not by it).
  static FeatureOptions DefaultFeatureOptions();
  Status Check() const;
};

struct PerceptionStats {
  std::array<int, 2> lines{0, 0}, points{0, 0};
  int point_matches = 0, line_matches_topology = 0, line_matches_transfer = 0;
  int line_matches_rejected_by_plane = 0;  // topology matches the ground plane contradicts
  int points_triangulated = 0, lines_triangulated = 0;
  int ground_samples_used = 0, ground_samples_rejected = 0;
  int edges = 0, strips = 0, pieces = 0;
  Eigen::Vector3d plane = Eigen::Vector3d::Zero();  // z = a + b x + c y, body frame
  std::array<double, 2> features_ms{0, 0};
  std::array<FeatureTimings, 2> feature_stages{};  // the feature detector's stages, per image
  double total_ms = 0;
};

struct PerceptionResult {
  TrackObservation observation;
  PerceptionStats stats;
  std::vector<GroundEdge> edges;  // the tape edges on the ground (for overlays and tests)
};

class TrackPerception {
 public:
  static Result<std::unique_ptr<TrackPerception>> Create(const StereoRig& rig, const PerceptionOptions& options);
  ~TrackPerception();

  // One stereo pair taken at `timestamp_ns`: 8-bit grey (or BGR, converted) images of the rig's size.
  // InvalidArgument for empty or wrongly sized images.
  Result<PerceptionResult> Process(const cv::Mat& left, const cv::Mat& right, int64_t timestamp_ns);
  // Back to the calibration's ground plane.
  void Reset();

  const StereoRig& rig() const { return rig_; }
  const PerceptionOptions& options() const { return options_; }
  // The ground each camera sees (vehicle frame, level ground, out to max_range_m).
  const std::vector<std::vector<Vec2d>>& footprints() const { return footprints_; }
  const GroundPlaneEstimator& ground() const { return ground_; }

 private:
  TrackPerception(const StereoRig& rig, const PerceptionOptions& options);
  struct View;

  StereoRig rig_;
  PerceptionOptions options_;
  std::vector<std::unique_ptr<FeatureDetector>> detectors_;
  std::vector<std::vector<Vec2d>> footprints_;
  GroundPlaneEstimator ground_;
  Mat3d fundamental_ = Mat3d::Zero();  // x_right^T F x_left = 0 (undistorted pixels)
};

}  // namespace idi::rmp
