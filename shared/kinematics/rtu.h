// The robot transport unit (rail) and the robot-to-robot transform (§3.2, eqs. 3.3-3.5).
//
// Each robot has a rail frame R whose x axis is the rail direction and whose origin is the robot's
// base origin at rail position zero. Phi_l, Phi_m rotate the base's x axis onto the rail direction
// (about z, then y). The two rail frames are related by Psi (eq. 3.5): Tr(psi_x, psi_y, psi_z)
// Rx(psi_alpha) Rz(pi), the x axes being parallel but opposite.
#pragma once

#include <vector>

#include "shared/geometry/rigid3.h"
#include "shared/util/param_set.h"
#include "shared/util/units.h"

namespace idi {

enum RailParam : int { kPhiL = 0, kPhiM };
inline constexpr int kRailParamCount = kPhiM + 1;
enum RobotToRobotParam : int { kPsiX = 0, kPsiY, kPsiZ, kPsiAlpha };
inline constexpr int kRobotToRobotParamCount = kPsiAlpha + 1;

std::vector<ParamSpec> RailParamSpecs();          // phi_l_deg, phi_m_deg (nominal 0)
std::vector<ParamSpec> RobotToRobotParamSpecs();  // psi_x_mm, psi_y_mm, psi_z_mm, psi_alpha_deg

// The rail direction in the robot's base frame: (cos l cos m, sin l cos m, -sin m) (§4.3).
template <typename T>
Vec3<T> RailDirectionInBase(const T& phi_l, const T& phi_m) {
  using std::cos;
  using std::sin;
  return Vec3<T>(cos(phi_l) * cos(phi_m), sin(phi_l) * cos(phi_m), -sin(phi_m));
}

// ^R T_B of eq. 3.3: the base frame at rail position d (mm) in the robot's rail frame.
template <typename T>
Rigid3<T> RailFromBase(const T& phi_l, const T& phi_m, const T& rail_position) {
  Rigid3<T> out = (RotZ(phi_l) * RotY(phi_m)).Inverse();
  out.translation << rail_position, T(0), T(0);
  return out;
}

// ^{R1}T_{R2} of eq. 3.5.
template <typename T>
Rigid3<T> Rail1FromRail2(const T* psi) {
  return Translation(psi[kPsiX], psi[kPsiY], psi[kPsiZ]) * RotX(psi[kPsiAlpha]) * RotZ(T(kPi));
}

// ^{B1}T_{B2} of eq. 3.4: robot 2's base frame (at its rail position) in robot 1's base frame.
template <typename T>
Rigid3<T> Base1FromBase2(const T* rail1, const T& rail1_position, const T* psi, const T* rail2,
                         const T& rail2_position) {
  return RailFromBase(rail1[kPhiL], rail1[kPhiM], rail1_position).Inverse() * Rail1FromRail2(psi) *
         RailFromBase(rail2[kPhiL], rail2[kPhiM], rail2_position);
}

}  // namespace idi
