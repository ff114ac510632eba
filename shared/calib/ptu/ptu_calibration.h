// Pan-tilt camera calibration from one unknown stationary laser spot (chapter 6, eq. 6.4 with the
// point added to the unknowns, §6.3).
//
// Unknowns per camera: ^E T_0 (tx, ty, tz, theta_x, theta_y, theta_z; eq. 3.11), the tilt link
// (theta1, alpha1, a1, d1; eq. 3.13), the camera link (theta2, alpha2, a2, d2; eq. 3.14), the intrinsics
// fx, fy, cx, cy (fx = f px, fy = f py of §6.2.2, see shared/camera/pinhole.h) and optionally k1, k2;
// plus the point (3), shared by the cameras when both are in the data.
//
// Identifiability. With frame 0 a full 6-parameter pose and the two modified-DH links, the model is
// minimal: a pan axis (4 line parameters), the tilt axis relative to it (4), the zero of each joint
// and the camera's pose on the tilt link (6) make 14 independent kinematic quantities, exactly the 14
// parameters; the dissertation's f, px, py are already merged into fx, fy, and its CCD-plane offset
// into d2. So with rich data there is no exact gauge freedom. Data that do not excite everything
// create some (e.g. the TCF orientation never changing: the point's position against tx, ty, tz; pan
// never moving: theta_z against the tilt link). CalibratePtu therefore checks the column-scaled
// Jacobian at the start values: every direction the data cannot see is named (the parameter
// combination) and fixed by holding its largest member at its start value; PtuCalibrationResult::gauge
// lists them. Near-degenerate pairs (|correlation| > 0.95 at the solution) are reported too.
//
// The solve: Levenberg-Marquardt (shared/optim) in three stages: a Huber loss at 10x the robust scale
// from the start values, a Cauchy loss at the robust scale (a wrong spot then has almost no pull),
// then plain least squares on the observations whose error is within max(outlier_sigmas x the robust
// sigma, outlier_floor_px); the covariance (a posteriori variance factor x (J^T J)^-1) comes from the
// last stage.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "shared/calib/ptu/ptu_observations.h"
#include "shared/camera/pinhole.h"
#include "shared/kinematics/biclops.h"
#include "shared/optim/covariance.h"
#include "shared/util/param_set.h"
#include "shared/util/status.h"

namespace idi::calib {

// One camera's model: the PTU parameters (PtuParamSpecs) and the intrinsics (CameraParamSpecs).
struct PtuCameraModel {
  BiclopsSide side = BiclopsSide::kLeft;
  ParamSet ptu;
  ParamSet intrinsics;
  int width = 640;
  int height = 480;

  // The as-designed model (PtuParamSpecs, BiclopsNominalCamera).
  static PtuCameraModel Nominal(BiclopsSide side);
  CameraModel Camera() const { return CameraFromParamSet(intrinsics, width, height); }
  // ^B T_3, the camera frame in the robot base for a TCF pose and PTU readings.
  Rigid3d BaseFromCamera(const TcfPose& tcf, double pan_rad, double tilt_rad) const;
  // The point's pixel; nullopt when it is behind the camera.
  std::optional<Vec2d> Project(const TcfPose& tcf, double pan_rad, double tilt_rad, const Vec3d& point_mm) const;
};

// The fewest observations per camera CalibratePtu takes by default (PtuCalibrationOptions), so the
// fewest calibration poses an acquisition may plan.
inline constexpr int kPtuMinObservationsPerCamera = 24;

struct PtuCalibrationOptions {
  bool estimate_distortion = false;  // also estimate k1, k2 (p1, p2, k3 stay at their start values)
  bool shared_point = true;          // one point for both cameras (false: one per camera)
  double robust_scale_px = 1.0;      // Cauchy loss scale of the robust stage
  double outlier_sigmas = 5.0;       // rejection threshold in robust sigmas (of the per-axis error)
  double outlier_floor_px = 0.5;     // never reject an error below this
  int min_observations_per_camera = kPtuMinObservationsPerCamera;
  int max_iterations = 200;          // per stage
  PtuRange range;
  std::optional<Vec3d> initial_point_mm;  // default: triangulated from the start model's rays
  // Parameters held at their start values besides the automatic gauge fixes: "left.theta_z", "right.k1".
  std::vector<std::string> fixed;
  optim::IdentifiabilityOptions identifiability;
  std::string source = "observations";  // names the data in messages
  Status Check() const;
};

// A direction of the parameter space the data cannot see, and the parameter fixed to remove it.
struct PtuGaugeFix {
  std::string fixed_parameter;  // "left.theta_z"
  std::string combination;      // "0.71 left.theta_z - 0.70 left.theta1"
  double singular_value = 0;    // relative to the largest, column-scaled
};

struct PtuCameraCalibration {
  BiclopsSide side = BiclopsSide::kLeft;
  PtuCameraModel model;                        // calibrated values; stddev set for estimated parameters
  Vec3d point_mm = Vec3d::Zero();              // the point this camera's data were fitted with
  Vec3d point_std_mm = Vec3d::Zero();
  int observations = 0;
  int inliers = 0;
  double rms_px = 0;         // RMS of the residual components (u and v) over the inliers
  double mean_error_px = 0;  // mean pixel distance over the inliers (the dissertation's projection error)
  double max_error_px = 0;   // largest inlier pixel distance
  std::vector<double> errors_px;   // pixel distance per observation of this camera, in input order
  std::vector<bool> inlier;        // per observation of this camera
};

struct PtuCalibrationResult {
  std::vector<PtuCameraCalibration> cameras;  // in the order left, right (those with data)
  Vec3d point_mm = Vec3d::Zero();             // the (first) recovered point
  Vec3d point_std_mm = Vec3d::Zero();
  Vec3d initial_point_mm = Vec3d::Zero();
  std::vector<PtuGaugeFix> gauge;             // automatic fixes (empty when the data see every direction)
  std::vector<std::string> held_fixed;        // every parameter not estimated (gauge, options, p1/p2/k3, ...)
  std::vector<std::string> free_parameters;   // in the order of the Jacobian's columns
  Eigen::VectorXd singular_values;            // of the column-scaled Jacobian at the solution
  double condition_number = 0;
  std::string correlated;                     // pairs with |correlation| above the threshold
  double variance_factor = 1;                 // sigma0^2 in px^2 per residual component
  int rejected = 0;
  int iterations = 0;                         // over all stages
  // The final (least-squares) stage's: "convergence", or "no_convergence" when it stopped at
  // max_iterations (the result is then usable but may not be the optimum; Summary warns).
  std::string termination;
  double time_ms = 0;
  std::vector<double> cost_per_iteration;     // all stages, in order

  const PtuCameraCalibration* Camera(BiclopsSide side) const;
  std::string Summary() const;
};

// Calibrates every camera present in `observations`. `start` holds start models (missing sides
// start from PtuCameraModel::Nominal). Bad data (non-finite values, PTU readings out of range, two
// spots in one image, too few observations) give InvalidArgument / OutOfRange naming the line;
// NotConverged when the fit fails.
Result<PtuCalibrationResult> CalibratePtu(const std::vector<PtuObservation>& observations,
                                          const std::vector<PtuCameraModel>& start,
                                          const PtuCalibrationOptions& options = {});

struct PtuCameraValidation {
  BiclopsSide side = BiclopsSide::kLeft;
  int observations = 0;
  double rms_px = 0;         // RMS of the residual components
  double mean_error_px = 0;  // mean pixel distance
  double max_error_px = 0;
  std::vector<double> errors_px;
};
struct PtuValidation {
  std::vector<PtuCameraValidation> cameras;
  double rms_px = 0;  // over all cameras
  const PtuCameraValidation* Camera(BiclopsSide side) const;
};

// Errors of held-out observations under a calibration (each camera with its own point estimate).
// InvalidArgument when an observation's camera was not calibrated or the point is behind it.
Result<PtuValidation> ValidatePtu(const PtuCalibrationResult& calibration,
                                  const std::vector<PtuObservation>& observations, const PtuRange& range = {},
                                  const std::string& source = "validation");

// The least-squares point closest to the observations' rays (start models), with a few Cauchy-
// reweighted passes so a wrong spot does not drag it. FailedPrecondition when the rays are (nearly)
// parallel, i.e. the poses give no parallax.
Result<Vec3d> TriangulatePtuPoint(const std::vector<PtuObservation>& observations,
                                  const std::vector<PtuCameraModel>& models);

// "left.tx" style names of a camera's 23 parameters (PTU then intrinsics), for reports.
std::vector<std::string> PtuCameraParameterNames(BiclopsSide side);

}  // namespace idi::calib
