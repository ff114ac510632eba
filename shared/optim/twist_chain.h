// A chain of elementary motions (Rx, Ry, Rz, Tx, Ty, Tz) that also accumulates the derivative of the
// resulting frame with respect to chosen parameters, as twists in the chain's outer frame.
//
// For the calibration costs the joint readings are constants, so every parameter of the RX-130 chain
// (eqs. 3.1-3.2 links, the laser tool of §3.3.3, the rail of eq. 3.3 and eq. 3.5) enters through exactly
// one elementary motion. Differentiating a product of elementary motions is then cheap: a rotation by
// angle a about local axis e, taken at the running frame (R, t), moves every point p attached further
// down the chain with velocity (R e) x (p - t) per unit of a; a translation along e moves it by R e.
// Summing per parameter gives the twist (omega, v0): velocity omega x p + v0 for a point p in the outer
// frame. That costs a few flops per motion instead of the dual numbers of a Jet<double, 27>.
#pragma once

#include <Eigen/Core>
#include <cmath>

#include "shared/geometry/rigid3.h"

namespace idi::optim {

class TwistChain {
 public:
  static constexpr int kMaxColumns = 40;
  using Twists = Eigen::Matrix<double, 3, kMaxColumns>;

  TwistChain() {
    omega_.setZero();
    v0_.setZero();
  }

  // Rotations and translations along the running frame's axes. `amount` = sign_a * p_a + sign_b * p_b + c
  // for the parameters in columns col_a, col_b (-1: none): the derivative columns get sign times the
  // motion's twist.
  void RotX(double angle, int col_a = -1, double sign_a = 1, int col_b = -1, double sign_b = 1) {
    Record(rotation_.col(0), true, col_a, sign_a, col_b, sign_b);
    RotateColumns(1, 2, angle);
  }
  void RotY(double angle, int col_a = -1, double sign_a = 1, int col_b = -1, double sign_b = 1) {
    Record(rotation_.col(1), true, col_a, sign_a, col_b, sign_b);
    RotateColumns(2, 0, angle);
  }
  void RotZ(double angle, int col_a = -1, double sign_a = 1, int col_b = -1, double sign_b = 1) {
    Record(rotation_.col(2), true, col_a, sign_a, col_b, sign_b);
    RotateColumns(0, 1, angle);
  }
  void TransX(double d, int col = -1, double sign = 1) { Translate(0, d, col, sign); }
  void TransY(double d, int col = -1, double sign = 1) { Translate(1, d, col, sign); }
  void TransZ(double d, int col = -1, double sign = 1) { Translate(2, d, col, sign); }

  // The running frame: outer_from_current.
  const Mat3d& rotation() const { return rotation_; }
  const Vec3d& translation() const { return translation_; }
  Rigid3d frame() const {
    Rigid3d f;
    f.rotation = rotation_;
    f.translation = translation_;
    return f;
  }
  // Column k: angular velocity (dR/dp_k = [omega_k]x R) and velocity of the outer frame's origin.
  const Twists& omega() const { return omega_; }
  const Twists& v0() const { return v0_; }
  // Velocity of a point p (outer frame) attached to the end of the chain, per parameter.
  Twists PointVelocity(const Vec3d& p) const {
    Twists v = v0_;
    for (int k = 0; k < kMaxColumns; ++k) v.col(k) += omega_.col(k).cross(p);
    return v;
  }

 private:
  void Record(const Vec3d& axis, bool rotation, int col_a, double sign_a, int col_b, double sign_b) {
    for (const auto& [col, sign] : {std::pair{col_a, sign_a}, std::pair{col_b, sign_b}}) {
      if (col < 0) continue;
      if (rotation) {
        // Rotation about `axis` through the running origin t: v(p) = a x (p - t) = a x p + t x a.
        omega_.col(col) += sign * axis;
        v0_.col(col) += sign * translation_.cross(axis);
      } else {
        v0_.col(col) += sign * axis;
      }
    }
  }
  // R <- R * elementary rotation mixing columns i and j (i -> j is the positive sense).
  void RotateColumns(int i, int j, double angle) {
    const double c = std::cos(angle), s = std::sin(angle);
    const Vec3d ci = rotation_.col(i), cj = rotation_.col(j);
    rotation_.col(i) = c * ci + s * cj;
    rotation_.col(j) = -s * ci + c * cj;
  }
  void Translate(int axis, double d, int col, double sign) {
    Record(rotation_.col(axis), false, col, sign, -1, 0);
    translation_ += d * rotation_.col(axis);
  }

  Mat3d rotation_ = Mat3d::Identity();
  Vec3d translation_ = Vec3d::Zero();
  Twists omega_;
  Twists v0_;
};

}  // namespace idi::optim
