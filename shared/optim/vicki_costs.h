// The ViCKi cost functions (chapter 4, eq. 4.2; chapter 5) with analytic derivatives.
//
// Robot calibration (eq. 4.2): a reading's joints aim the laser at a fixed point P (set 1) or at
// P + offset * t(phi_l, phi_m) (set 2: offset = +D for a second point at a known distance, -D when the
// base moved by D along the rail, §4.3). The error is the shortest distance of the point from the
// laser line over the laser line's length. We keep it as the 2-vector (x/z, y/z) of the point in the
// laser frame (frame 7, the beam its z axis): its norm is exactly eq. 4.2's normalised distance, and,
// unlike the norm, it is smooth where the line passes through the point. Each reading's 2-vector is
// whitened by its expected noise (AimNoiseCovariance), so the sum of squares is eq. 4.2 weighted by
// how well each reading can be expected to fit.
//
// Rail calibration (chapter 5, eqs. 5.1-5.3): both arms aim at one point; the error is the signed
// shortest distance between the two laser lines (in robot 1's rail frame R1) over their mean length,
// whitened by its expected standard deviation.
#pragma once

#include <Eigen/Core>
#include <array>
#include <optional>

#include "shared/geometry/lines.h"
#include "shared/kinematics/rtu.h"
#include "shared/kinematics/rx130.h"
#include "shared/optim/least_squares.h"
#include "shared/optim/twist_chain.h"

namespace idi::optim {

// Appends the RX-130 (§3.1.1) and laser tool (§3.3.3) chain to `chain`. Derivative columns start at
// robot_col (18 robot parameters), laser_col (4), joint_col (6 joint readings); -1 leaves them out.
void AppendRx130LaserChain(TwistChain& chain, const double* robot, const double* laser, const Joints& q,
                           int robot_col, int laser_col, int joint_col);
// Appends ^R T_B of eq. 3.3 (base in the arm's rail frame at rail position `rail_mm`): columns for
// phi_l, phi_m (rail_col, rail_col + 1) and the rail position (position_col).
void AppendRailFromBase(TwistChain& chain, const double* phi, double rail_mm, int rail_col, int position_col);
// Appends ^{R1}T_{R2} of eq. 3.5, columns psi_col .. psi_col + 3.
void AppendRail1FromRail2(TwistChain& chain, const double* psi, int psi_col);

// Eq. 4.2 for one reading, with derivatives. Columns of the 2 x 28 Jacobian: robot (0..17), laser
// (18..21), joints (22..27).
struct AimEvaluation {
  Eigen::Vector2d r = Eigen::Vector2d::Zero();  // (x, y) / z of the point in the laser frame
  double length_mm = 0;                          // z: distance of the point along the beam
  Mat3d laser_axes = Mat3d::Identity();          // base_from_laser rotation (columns X, Y, Z)
  Eigen::Matrix<double, 2, 28> d_chain = Eigen::Matrix<double, 2, 28>::Zero();
  Eigen::Matrix<double, 2, 3> d_point = Eigen::Matrix<double, 2, 3>::Zero();
};
inline constexpr int kAimLaserCol = 18;
inline constexpr int kAimJointCol = 22;
// False if the point is not at least `min_length_mm` in front of the laser.
bool EvaluateAim(const double* robot, const double* laser, const Joints& q, const Vec3d& point, AimEvaluation* out,
                 double min_length_mm = 1.0);

// Noise of one reading's (x/z, y/z): the spot's error on the observation plane (sigma per in-plane
// axis; the plane's normal in the base frame, or none: perpendicular to the beam) plus the joint
// readings' errors (std per joint, radians).
struct AimNoiseModel {
  double spot_sigma_mm = 0.05;
  std::optional<Vec3d> plane_normal;
  std::array<double, kRx130Joints> joint_sigma_rad{};
};
Eigen::Matrix2d AimNoiseCovariance(const AimEvaluation& e, const AimNoiseModel& noise);
// Joint reading std of encoder rounding (Table 4.2): one count / sqrt(12).
std::array<double, kRx130Joints> EncoderRoundingSigmaRad();

// One reading of eq. 4.2 as a residual. Blocks: robot (18), laser (4), point (3), and, for a reading of
// set 2, the direction (phi_l, phi_m). The point aimed at is P + offset_mm * t(phi).
class AimResidual final : public ResidualFunction {
 public:
  AimResidual(const Joints& q, std::optional<double> offset_mm, const Eigen::Matrix2d& sqrt_information);
  bool Evaluate(const double* const* parameters, double* residuals, double** jacobians) const override;
  // d(whitened residual) / d offset_mm (0 for set 1): how the reading reacts to the known distance.
  Eigen::Vector2d DerivativeWrtOffset(const double* const* parameters) const;
  const Joints& joints() const { return q_; }

 private:
  Joints q_;
  std::optional<double> offset_mm_;
  Eigen::Matrix2d w_;
};

// The aimed point for offset o: P + o t(phi).
Vec3d AimedPoint(const Vec3d& point, const double* phi, std::optional<double> offset_mm);

// A laser line with derivatives of its origin and direction per chain column.
struct LineJacobian {
  Vec3d origin = Vec3d::Zero();
  Vec3d direction = Vec3d::UnitZ();
  TwistChain::Twists d_origin = TwistChain::Twists::Zero();
  TwistChain::Twists d_direction = TwistChain::Twists::Zero();
};
LineJacobian LineFromChain(const TwistChain& chain);

// Signed shortest distance between lines a and b (along n = da x db / |da x db|) and its derivatives
// per column of a and of b. `mean_length_mm`: mean distance from each origin to the closest points.
struct LineDistance {
  double distance_mm = 0;
  double mean_length_mm = 0;
  Eigen::Matrix<double, 1, TwistChain::kMaxColumns> d_a = Eigen::Matrix<double, 1, TwistChain::kMaxColumns>::Zero();
  Eigen::Matrix<double, 1, TwistChain::kMaxColumns> d_b = Eigen::Matrix<double, 1, TwistChain::kMaxColumns>::Zero();
};
// False if the lines are (nearly) parallel.
bool EvaluateLineDistance(const LineJacobian& a, const LineJacobian& b, LineDistance* out);

// Chapter 5 residual with the arms fixed: robot 1's laser line in R1 and robot 2's in R2 are constants;
// the only block is psi (4). Residual = signed distance / sigma_mm.
class RailResidual final : public ResidualFunction {
 public:
  RailResidual(const Line3d& line1_in_r1, const Line3d& line2_in_r2, double sigma_mm);
  bool Evaluate(const double* const* parameters, double* residuals, double** jacobians) const override;

 private:
  Line3d a_, b_;
  double inv_sigma_;
};

// Chapter 5 residual with the arms free too (joint solve of arms and rail). Blocks: psi (4), robot 1
// (18), laser 1 (4), phi 1 (2), robot 2 (18), laser 2 (4), phi 2 (2).
class RailArmsResidual final : public ResidualFunction {
 public:
  RailArmsResidual(const Joints& q1, double rail1_mm, const Joints& q2, double rail2_mm, double sigma_mm);
  bool Evaluate(const double* const* parameters, double* residuals, double** jacobians) const override;

 private:
  Joints q1_, q2_;
  double rail1_mm_, rail2_mm_;
  double inv_sigma_;
};

// Column layout of a full arm-in-R1 chain used by RailArmsResidual and the rail noise model.
struct ArmChainColumns {
  int psi = -1;       // 4 (robot 2 only)
  int rail = 0;       // 2: phi_l, phi_m
  int robot = 2;      // 18
  int laser = 20;     // 4
  int joints = 24;    // 6
  int position = 30;  // rail position
};
inline constexpr ArmChainColumns kArm1Columns{-1, 0, 2, 20, 24, 30};
inline constexpr ArmChainColumns kArm2Columns{0, 4, 6, 24, 28, 34};
// Robot k's laser line in R1 with derivatives (robot 2 through psi).
LineJacobian ArmLineInRail1(const double* robot, const double* laser, const double* phi, double rail_mm,
                            const Joints& q, const double* psi, const ArmChainColumns& cols);

}  // namespace idi::optim
