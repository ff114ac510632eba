// The Stäubli RX-130 arm and its laser-pointer tool (§3.1.1, §3.3.3; Tables 3.1, 4.1, 4.2).
//
// Frames: base = frame 1 at joint-1 reading zero (so ^0T_1 is a pure rotation by the joint-1
// reading); links 2, 4, 5, 6 are modified DH (eq. 3.1); link 3 is Hayati (eq. 3.2) because axes 2
// and 3 are parallel. Link 6 has theta6 = pi and d6 = 110 mm fixed. Each theta_i is an offset added
// to the joint reading. That leaves the 18 free parameters of Table 4.1.
//
// Table 3.1 prints alpha4 = +pi/2 while Tables 4.1-4.6 use -90 deg; we use -90 deg (the calibrated
// real robots in Tables 4.5-4.6 come out near -90).
//
// Joint readings are in this model's convention. With nominal parameters and all readings zero the
// flange sits at (625, 0, 735) mm with the base's orientation: upper arm along +x, forearm and tool
// along +z (see rx130_test.cc for the derivation).
#pragma once

#include <array>
#include <vector>

#include "shared/geometry/lines.h"
#include "shared/geometry/rigid3.h"
#include "shared/util/param_set.h"
#include "shared/util/units.h"

namespace idi {

enum Rx130Param : int {
  kAlpha2 = 0, kA2, kTheta2, kD2,   // link 2, DH
  kAlpha3, kA3, kTheta3, kBeta3,    // link 3, Hayati
  kAlpha4, kA4, kTheta4, kD4,       // link 4, DH
  kAlpha5, kA5, kTheta5, kD5,       // link 5, DH
  kAlpha6, kA6,                     // link 6, DH with theta6 = pi, d6 = 110 mm fixed
};
inline constexpr int kRx130ParamCount = kA6 + 1;

// ^6T_7 of §3.3.3: Rx(theta_x) Ry(theta_y) Tx(px) Ty(py). The laser line is frame 7's z axis.
enum LaserParam : int { kLaserThetaX = 0, kLaserThetaY, kLaserPx, kLaserPy };
inline constexpr int kLaserParamCount = kLaserPy + 1;

inline constexpr int kRx130Joints = 6;
inline constexpr double kRx130D6Mm = 110.0;
inline constexpr double kRx130Theta6Rad = kPi;

// Encoder counts per degree of each joint (Table 4.2).
inline constexpr std::array<double, kRx130Joints> kRx130CountsPerDeg = {147219, 147219, 115019, 100124, 30720, 36409};

using Joints = std::array<double, kRx130Joints>;  // joint readings, radians

// Table 4.1 names and nominal ("industrial") values.
std::vector<ParamSpec> Rx130ParamSpecs();
std::vector<ParamSpec> LaserParamSpecs();
ParamSet Rx130Nominal();
ParamSet LaserNominal();

// Joint limits in this model's convention (radians).
struct JointLimits {
  Joints min{};
  Joints max{};
  bool Contains(const Joints& q, double margin = 0) const;
  // Index of the first joint outside its limits, or -1.
  int FirstViolation(const Joints& q) const;
};

// The RX-130's ranges (J1 ±160°, J2 ±137.5°, J3 ±142.5°, J4 ±270°, J5 −105°..+120.5°, J6 ±270°, from the
// Stäubli data sheet), shifted into this model's convention, whose zero has the upper arm horizontal:
// model = controller + (0, −90°, +90°, 0, 0, 0) if the controller's zero is the arm straight up.
// The workcell's arm driver applies that offset; verify it on a real cell before trusting the limits.
JointLimits Rx130JointLimits();
inline constexpr std::array<double, kRx130Joints> kRx130ControllerToModelDeg = {0, -90, 90, 0, 0, 0};

// ^B T_6: the flange frame in the robot base frame. `p` holds kRx130ParamCount values (code units:
// radians and mm), `q` six joint readings in radians.
template <typename T>
Rigid3<T> Rx130BaseFromFlange(const T* p, const T* q) {
  const Rigid3<T> t1 = RotZ(q[0]);
  const Rigid3<T> t2 = DhLink(p[kAlpha2], p[kA2], p[kTheta2] + q[1], p[kD2]);
  const Rigid3<T> t3 = HayatiLink(p[kAlpha3], p[kA3], p[kBeta3], p[kTheta3] + q[2]);
  const Rigid3<T> t4 = DhLink(p[kAlpha4], p[kA4], p[kTheta4] + q[3], p[kD4]);
  const Rigid3<T> t5 = DhLink(p[kAlpha5], p[kA5], p[kTheta5] + q[4], p[kD5]);
  const Rigid3<T> t6 = DhLink(p[kAlpha6], p[kA6], T(kRx130Theta6Rad) + q[5], T(kRx130D6Mm));
  return t1 * t2 * t3 * t4 * t5 * t6;
}

// ^6T_7 of §3.3.3.
template <typename T>
Rigid3<T> FlangeFromLaser(const T* l) {
  return RotX(l[kLaserThetaX]) * RotY(l[kLaserThetaY]) * Translation(l[kLaserPx], T(0), T(0)) *
         Translation(T(0), l[kLaserPy], T(0));
}

// The laser line in the base frame: origin of frame 7 and its z axis (columns 4 and 3 of ^B T_7).
template <typename T>
Line3<T> LaserLineInBase(const T* robot, const T* laser, const T* q) {
  const Rigid3<T> base_from_laser = Rx130BaseFromFlange(robot, q) * FlangeFromLaser(laser);
  return {base_from_laser.translation, base_from_laser.rotation.col(2)};
}

// The six joint-axis lines (z axes of frames 1..6) in the base frame, for Jacobians and drawings.
std::array<Line3d, kRx130Joints> Rx130JointAxes(const ParamSet& robot, const Joints& q);

// Rounds joint readings to the nearest encoder count (Table 4.2).
Joints QuantizeToEncoders(const Joints& q);

inline Joints JointsFromDeg(const std::array<double, kRx130Joints>& deg) {
  Joints q{};
  for (int i = 0; i < kRx130Joints; ++i) {
    q[static_cast<std::size_t>(i)] = DegToRad(deg[static_cast<std::size_t>(i)]);
  }
  return q;
}
inline std::array<double, kRx130Joints> JointsToDeg(const Joints& q) {
  std::array<double, kRx130Joints> deg{};
  for (int i = 0; i < kRx130Joints; ++i) {
    deg[static_cast<std::size_t>(i)] = RadToDeg(q[static_cast<std::size_t>(i)]);
  }
  return deg;
}

}  // namespace idi
