// Rail (RTU) calibration, chapter 5: the robot-to-robot transform psi = (psi_x, psi_y, psi_z,
// psi_alpha) of eq. 3.5 from readings where both arms aim their lasers at one (unknown) point.
//
// Each arm's 22 robot + laser parameters and its rail direction (phi_l, phi_m) come from its chapter 4
// calibration. The cost (eqs. 5.1-5.3): the shortest distance between the two laser lines in robot 1's
// rail frame, over their mean length; we whiten each reading's signed distance by its expected std
// (spot noise on the wall, rail repeatability, encoder rounding) instead of dividing by the length.
//
// Start: closed form. Readings aiming at the same point are grouped; each group's point is located
// from robot 1's lines in R1 and from robot 2's lines in R2 (no psi needed), and psi's twist about the
// rail and its translation follow from those point pairs (a 2D Procrustes fit). Then Levenberg-
// Marquardt.
//
// Observability: psi_alpha turns the far robot about the rail axis, moving a point at height z by
// -alpha z sideways and one at distance y from the rail by alpha y vertically. Points on one wall
// parallel to the rail (y nearly constant) cannot tell psi_alpha from psi_z; points on two walls (or a
// wall and the floor) can. The report's condition number shows it.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "shared/calib/robot_calibration.h"
#include "shared/geometry/lines.h"
#include "shared/kinematics/rtu.h"
#include "shared/kinematics/rx130.h"
#include "shared/optim/covariance.h"
#include "shared/optim/least_squares.h"

namespace idi::calib {

struct RailReading {
  Joints q1{};
  double rail1_mm = 0;
  Joints q2{};
  double rail2_mm = 0;
  int row = 0;
};

// One arm's calibrated model.
struct ArmModel {
  ParamSet robot = Rx130Nominal();
  ParamSet laser = LaserNominal();
  ParamSet rail = ParamSet(RailParamSpecs());  // phi_l, phi_m
  // Covariance of the 24 values above (robot, laser, rail; code units) from the arm's calibration.
  // Empty: the arm is taken as exact.
  Eigen::MatrixXd covariance;
};
inline constexpr int kArmModelParamCount = kRx130ParamCount + kLaserParamCount + kRailParamCount;

// The arm model's covariance from that of chapter 4's 27 unknowns (RobotCalibrationSpecs order): the
// fixed point left out. Empty unless `unknowns` is a finite 27 x 27 matrix.
Eigen::MatrixXd ArmCovarianceFromUnknowns(const Eigen::MatrixXd& unknowns);
// The arm's model from its chapter 4 calibration, with its covariance.
ArmModel ArmFromRobotCalibration(const RobotCalibrationResult& r);

struct RailNoiseModel {
  double spot_sigma_mm = 0.05;   // each spot on the wall, per in-plane axis
  bool encoder_rounding = true;
  double rail_sigma_mm = 0.1;    // each rail position's repeatability
  Status Check() const;
};

// Nominal psi: the rail frames 5650 mm apart along the rail, no offset, no twist.
std::array<double, kRobotToRobotParamCount> NominalPsi();

struct RailCalibrationOptions {
  std::array<double, kRobotToRobotParamCount> initial_psi = NominalPsi();
  RailNoiseModel noise;
  int min_readings_per_unknown = 5;
  double outlier_sigmas = 5.0;
  double outlier_floor_mm = 0.02;
  int max_outlier_rounds = 4;
  optim::SolverOptions solver;
  optim::IdentifiabilityOptions identifiability;
  Status Check() const;
};

struct RailCalibrationResult {
  ParamSet psi = ParamSet(RobotToRobotParamSpecs());  // with std
  optim::SolverSummary summary;
  std::vector<double> cost_per_iteration;
  std::string start;
  std::array<double, kRobotToRobotParamCount> start_psi{};
  std::vector<int> outliers;    // reading indices left out
  int readings_used = 0;
  double rms_distance_mm = 0;   // shortest distance between the two lines
  double rms_normalized = 0;    // chapter 5's cost: distance / mean length
  double variance_factor = 0;
  optim::CovarianceReport identifiability;
  // psi's std with the arms taken as exact (the rail readings' noise alone). psi.stddev adds the arms'
  // own uncertainty when both arms carry a covariance: their link lengths rest on the rail's
  // repeatability (chapter 4's only scale), and a few hundredths of a millimetre there move psi_x by
  // more than the rail readings can tell.
  std::array<double, kRobotToRobotParamCount> std_given_arms{};
  bool arms_uncertainty_included = false;
  std::string Summary() const;
};

Result<RailCalibrationResult> CalibrateRail(const std::vector<RailReading>& readings, const ArmModel& arm1,
                                            const ArmModel& arm2, const RailCalibrationOptions& options);

// Covariance of psi at given values for the noise model (with the true values: the Cramer-Rao bound).
Result<Eigen::Matrix4d> RailCovarianceAt(const std::vector<RailReading>& readings, const ArmModel& arm1,
                                         const ArmModel& arm2, const std::array<double, 4>& psi,
                                         const RailNoiseModel& noise);

// Arms and rail together: both arms' chapter 4 data and the rail readings in one problem (27 + 27 + 4
// unknowns; phi_l, phi_m of each arm shared by its translate-method set 2 and the rail model), started
// from the separate solutions.
struct JointCalibrationResult {
  RobotCalibrationResult arm1, arm2;  // values and std of the joint solve
  ParamSet psi = ParamSet(RobotToRobotParamSpecs());
  optim::SolverSummary summary;
  double condition_number = 0;
};
Result<JointCalibrationResult> CalibrateArmsAndRail(const RobotCalibrationData& data1, const RobotCalibrationData& data2,
                                                    const std::vector<RailReading>& rail,
                                                    const RobotCalibrationResult& start1,
                                                    const RobotCalibrationResult& start2,
                                                    const RailCalibrationResult& start_rail,
                                                    const RobotNoiseModel& robot_noise, const RailNoiseModel& rail_noise,
                                                    const optim::SolverOptions& solver = {});

// Each arm's laser line in its own rail frame (eq. 3.3) for a reading.
Line3d ArmLineInRailFrame(const ArmModel& arm, const Joints& q, double rail_mm);

}  // namespace idi::calib
