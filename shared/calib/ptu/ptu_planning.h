// Acquisition planning for the single-point pan-tilt calibration (§6.4.4, steps 2-3): random arm
// poses (joints drawn inside a box within the joint limits) and, for each, pan and tilt readings that
// put the spot at a random place in each camera's image; of those where both cameras see the spot,
// about 60 are kept so that every axis is exercised over its range (persistent excitation) and the
// information matrix is well conditioned, plus held-out poses for validation.
//
// Needs an approximate point and a model (nominal or a preliminary calibration); the margin absorbs
// their error. Reduction: first the candidates at the two ends of each axis (pan and tilt of both
// PTUs, the six joints), then greedy D-optimal selection (largest log det of the information matrix of
// the column-scaled Jacobian); the validation poses are drawn at random from the rest.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "shared/calib/ptu/ptu_calibration.h"
#include "shared/kinematics/rx130.h"

namespace idi::calib {

// Pan and tilt readings (radians) that put `point_mm` at `target_px` for a camera model at a TCF pose;
// nullopt when no solution lies inside `range`. Newton's method on the two equations from four starts
// around the pan axis; among several solutions the first inside the range is returned.
std::optional<std::array<double, 2>> AimPtuAt(const PtuCameraModel& model, const TcfPose& tcf, const Vec3d& point_mm,
                                              const Vec2d& target_px, const PtuRange& range);

struct PtuPlanOptions {
  int poses = 60;                // kept for the calibration
  int validation_poses = 20;     // held out
  int candidates = 400;          // candidate poses (both cameras see the spot) drawn before reducing
  int max_draws = 20000;         // random joint draws before giving up
  double margin_px = 20;         // the predicted spot stays this far inside the image
  double min_distance_mm = 500;  // camera to point
  double min_flange_z_mm = -200;      // keeps the head off the floor (the base frame is at shoulder height)
  double min_flange_radius_mm = 300;  // keeps the head out of the arm's own column
  double joint_range_fraction = 1.0;  // joints are drawn in this central fraction of each joint's range
  bool extremes_first = true;    // keep each axis' two extreme candidates before the D-optimal picks
  // Weight of the point in the selection: the criterion is log det(information) + point_weight x
  // log det(the point's information with the other parameters unknown), so the poses also give the
  // point parallax (the point is far from the arm compared with the arm's reach).
  double point_weight = 3.0;
  PtuRange range;
  uint64_t seed = 1;
  Status Check() const;
};

struct PtuPlannedPose {
  Joints q{};             // arm joint readings to command
  TcfPose tcf;            // the TCF pose the model predicts for them
  std::array<double, 2> pan_rad{};   // left, right
  std::array<double, 2> tilt_rad{};
  std::array<Vec2d, 2> predicted_px{Vec2d::Zero(), Vec2d::Zero()};
};

// How far the kept poses exercise one axis.
struct PtuAxisCoverage {
  std::string axis;              // "left.pan", "j3", ...
  double min_deg = 0, max_deg = 0;            // over the kept poses
  double range_min_deg = 0, range_max_deg = 0;  // over all candidates
};

struct PtuPlan {
  std::vector<PtuPlannedPose> calibration;
  std::vector<PtuPlannedPose> validation;
  int draws = 0;        // joint draws made
  int candidates = 0;   // of which both cameras could see the spot
  double log_det = 0;   // of the kept poses' column-scaled information matrix
  std::vector<PtuAxisCoverage> coverage;
  std::string Summary() const;
};

// `robot`: the Biclops arm's model (Rx130ParamSpecs values); `models`: left and right camera models.
// FailedPrecondition when too few candidate poses see the spot.
Result<PtuPlan> PlanPtuAcquisition(const ParamSet& robot, const JointLimits& limits,
                                   const std::array<PtuCameraModel, 2>& models, const Vec3d& approx_point_mm,
                                   const PtuPlanOptions& options = {});

}  // namespace idi::calib
