// Acquisition for ViCKi (§4.3.1, §4.3.3, §5.3): planning joint configurations that aim the laser at a
// point, choosing them so the calibration is well conditioned, and the closed-loop aiming that drives
// the laser spot onto the point with a camera watching the wall.
//
// The algorithms see only nominal (or previously calibrated) models, the approximate pose of the
// observation plane, joint readings and spot observations; devices come in as callbacks so that the
// real arms, the digital twin and replayed logs all fit.
#pragma once

#include <functional>
#include <vector>

#include "shared/calib/robot_calibration.h"
#include "shared/geometry/rigid3.h"
#include "shared/kinematics/rx130.h"
#include "shared/util/param_set.h"
#include "shared/util/status.h"

namespace idi::calib {

using ProgressFn = std::function<void(int done, int total)>;

struct PlanOptions {
  double near_deg = 25.0;          // keep random draws whose beam points within this of the target
  double wrist_margin_deg = 10.0;  // |q5| at least this (axes 4 and 6 align at q5 = 0)
  double limit_margin_deg = 3.0;   // stay this far inside every joint limit
  double min_length_mm = 1000.0;   // the target at least this far in front of the laser
  int max_draws = 5'000'000;
  unsigned seed = 1;
  Status Check() const;
};

// §4.3.3 steps 1-2: draws random joint configurations within the limits, keeps those whose laser
// (nominal model) points near `target_in_base`, then aims each exactly at it (nominal model, AimLaserAt)
// and keeps it if it stays away from the wrist singularity and the limits. Returns `count` of them.
Result<std::vector<Joints>> PlanAimConfigurations(const ParamSet& robot, const ParamSet& laser,
                                                  const Vec3d& target_in_base, int count, const JointLimits& limits,
                                                  const PlanOptions& options, const ProgressFn& progress = {});

struct SelectionResult {
  std::vector<int> chosen;          // indices into the candidate readings
  double condition_number = 0;      // of the information matrix, parameters scaled to unit diagonal
  double condition_number_first = 0;  // of the first `count` candidates (what no selection would give)
};

// Persistent excitation: picks `per_set` readings of each set from `pool` at `params` and reports the
// condition number of the information matrix of the 27 unknowns. Greedy, lazily re-evaluated: the
// first 2 x 27 picks maximise log det of the information (D-optimal: every unknown gets determined);
// the rest minimise the sum of the variances weighted by `a_weights` (A-optimal: the parameters worst
// determined get the readings; e.g. 1/unit^2 per parameter, 0 for the point). Without weights,
// D-optimal throughout.
Result<SelectionResult> SelectForConditioning(const RobotCalibrationData& pool, const ParamSet& params,
                                              const RobotNoiseModel& noise, int per_set,
                                              const std::vector<double>& a_weights = {});
// A-optimal weights in the calibration files' units (deg, mm) for the robot, laser and rail direction
// unknowns; the point (a nuisance) gets none.
std::vector<double> FileUnitWeights();

// The camera's view: the spot's position on the observation plane, in the plane's x, y (mm).
using SpotObserver = std::function<Result<Vec2d>()>;
// Moves the arm to a commanded configuration and returns the joint reading after the move.
using JointMover = std::function<Result<Joints>(const Joints& command)>;

struct AimLoopOptions {
  double tolerance_mm = 0.15;     // stop correcting when the observed spot is this close to the target
  int max_iterations = 30;
  double max_step_rad = 0.05;     // largest joint correction per step
  // Corrections after the spot is within tolerance, each from a fresh observation (the last one is
  // not observed again before recording). The loop's Jacobian comes from the nominal model, so a
  // correction of e leaves about (J_true - J_nominal) J_nominal^+ e behind; that remainder follows
  // the direction the loop approached from and would not average out over readings. A second
  // correction starts from an error that is only camera noise (or encoder rounding), which does.
  int final_corrections = 2;
  // The arm realises a command at its encoder counts. When set, each correction is rounded here to the
  // combination of neighbouring counts (each joint down or up) whose spot the model Jacobian puts
  // nearest the target. Plain rounding of a correction smaller than a count would leave the spot
  // where the approach left it, on the same side every time, and so shift the fixed point.
  bool round_to_encoder_counts = true;
  double limit_margin_rad = 1e-4;
  Status Check() const;
};

struct AimLoopResult {
  Joints reading{};
  int iterations = 0;
  double last_error_mm = 0;  // observed before the final correction
};

// §4.3.1: moves to `start`, then repeatedly observes the spot and corrects the joints through the
// pseudo-inverse of the spot's Jacobian (nominal model, approximate plane pose `base_from_plane`, the
// plane's z its normal), until the observed spot is within tolerance of `target_on_plane`.
Result<AimLoopResult> AimClosedLoop(const ParamSet& robot, const ParamSet& laser, const Rigid3d& base_from_plane,
                                    const Vec2d& target_on_plane, const Joints& start, const JointLimits& limits,
                                    const JointMover& move, const SpotObserver& observe, const AimLoopOptions& options);

// Where the laser line (model) meets the plane z = 0 of `base_from_plane`, in plane coordinates;
// nullopt if it does not hit the plane in front of the laser.
std::optional<Vec2d> SpotOnPlane(const ParamSet& robot, const ParamSet& laser, const Rigid3d& base_from_plane,
                                 const Joints& q);

}  // namespace idi::calib
