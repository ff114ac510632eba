// The Biclops head: two cameras, each on a Directed Perception pan-tilt unit, carried by an arm
// (§3.4.1, eqs. 3.10-3.14; §6.2).
//
// Chain for one camera, points in the robot base B to pixels:
//   ^B T_E  the tool control frame (TCF) pose reported by the arm, eq. 3.10 (ZYZ: yaw, pitch, roll)
//   ^E T_0  the PTU base in the TCF, eq. 3.11: Tr(tx, ty, tz) Rx(theta_x) Ry(theta_y) Rz(theta_z)
//   ^0 T_1  pan: Rz(pan), eq. 3.12
//   ^1 T_2  tilt link: DH(alpha1, a1, theta1 + tilt, d1), eq. 3.13
//   ^2 T_3  camera link: DH(alpha2, a2, theta2, d2), eq. 3.14; frame 3 is the camera frame
//   pinhole: fx, fy, cx, cy (+ k1, k2, p1, p2, k3), see shared/camera/pinhole.h
// The calibration matrix of eq. 6.2 is K [I|0] (^B T_3)^-1. Frame 3 is taken at the optical centre
// (x right, y down, z forward); the dissertation puts it on the CCD, f behind, which only changes d2.
#pragma once

#include <vector>

#include "shared/camera/pinhole.h"
#include "shared/geometry/rigid3.h"
#include "shared/util/param_set.h"

namespace idi {

// A TCF pose as the arm reports it (eq. 3.10): position (mm) and yaw alpha, pitch beta, roll gamma.
struct TcfPose {
  double x_mm = 0, y_mm = 0, z_mm = 0;
  double alpha_rad = 0, beta_rad = 0, gamma_rad = 0;
};

// ^B T_E of eq. 3.10: Rz(alpha) Ry(beta) Rz(gamma) with the translation.
template <typename T>
Rigid3<T> BaseFromTcf(const T& x, const T& y, const T& z, const T& alpha, const T& beta, const T& gamma) {
  Rigid3<T> out = RotZ(alpha) * RotY(beta) * RotZ(gamma);
  out.translation << x, y, z;
  return out;
}
Rigid3d BaseFromTcf(const TcfPose& pose);
// The inverse of eq. 3.10: ZYZ angles from a rotation (beta in [0, pi]; gamma = 0 when beta = 0).
TcfPose TcfPoseFromTransform(const Rigid3d& base_from_tcf);

enum PtuParam : int {
  kPtuTx = 0, kPtuTy, kPtuTz, kPtuThetaX, kPtuThetaY, kPtuThetaZ,  // ^E T_0, eq. 3.11
  kPtuTheta1, kPtuAlpha1, kPtuA1, kPtuD1,                           // tilt link, eq. 3.13
  kPtuTheta2, kPtuAlpha2, kPtuA2, kPtuD2,                           // camera link, eq. 3.14
};
inline constexpr int kPtuParamCount = kPtuD2 + 1;

enum class BiclopsSide { kLeft, kRight };
const char* BiclopsSideName(BiclopsSide side);

// Parameter specs with the as-designed nominal values (close to Table 6.1).
std::vector<ParamSpec> PtuParamSpecs(BiclopsSide side);
// The nominal camera (Basler A602fc, 640x480, about 12 mm lens at ~101 px/mm: fx ≈ fy ≈ 1240 px).
CameraModel BiclopsNominalCamera(BiclopsSide side);

// ^E T_3: the camera frame in the TCF for pan and tilt angles (radians).
template <typename T>
Rigid3<T> TcfFromCamera(const T* ptu, const T& pan, const T& tilt) {
  const Rigid3<T> e_from_0 = Translation(ptu[kPtuTx], ptu[kPtuTy], ptu[kPtuTz]) * RotX(ptu[kPtuThetaX]) *
                             RotY(ptu[kPtuThetaY]) * RotZ(ptu[kPtuThetaZ]);
  const Rigid3<T> t01 = RotZ(pan);
  const Rigid3<T> t12 = DhLink(ptu[kPtuAlpha1], ptu[kPtuA1], ptu[kPtuTheta1] + tilt, ptu[kPtuD1]);
  const Rigid3<T> t23 = DhLink(ptu[kPtuAlpha2], ptu[kPtuA2], ptu[kPtuTheta2], ptu[kPtuD2]);
  return e_from_0 * t01 * t12 * t23;
}

// Projects a point in the robot base frame to pixels (the calibration matrix of eq. 6.2 followed
// by distortion). `intrinsics` is the 9-vector of pinhole.h. Returns false when the point is
// behind the camera (then `pixel` is untouched).
template <typename T>
bool ProjectThroughBiclops(const Rigid3<T>& base_from_tcf, const T* ptu, const T* intrinsics, const T& pan,
                           const T& tilt, const Vec3<T>& point_in_base, Vec2<T>* pixel) {
  const Rigid3<T> base_from_cam = base_from_tcf * TcfFromCamera(ptu, pan, tilt);
  const Vec3<T> p_cam = base_from_cam.Inverse() * point_in_base;
  if (!(p_cam.z() > T(1e-9))) {
    return false;
  }
  *pixel = ProjectToPixel(intrinsics, p_cam);
  return true;
}

// The 3x4 projection matrix K [R | t] of eq. 6.2 (no distortion), cam_from_base = (^B T_3)^-1.
Eigen::Matrix<double, 3, 4> ProjectionMatrix(const CameraModel& camera, const Rigid3d& cam_from_base);

}  // namespace idi
