#include "shared/kinematics/biclops.h"

#include <cmath>

#include "shared/util/units.h"

namespace idi {

Rigid3d BaseFromTcf(const TcfPose& p) {
  return BaseFromTcf(p.x_mm, p.y_mm, p.z_mm, p.alpha_rad, p.beta_rad, p.gamma_rad);
}

TcfPose TcfPoseFromTransform(const Rigid3d& t) {
  // R = Rz(a) Ry(b) Rz(g): R(2,2) = cos b, R(0,2) = cos a sin b, R(1,2) = sin a sin b,
  // R(2,0) = -sin b cos g, R(2,1) = sin b sin g.
  const Mat3d& r = t.rotation;
  TcfPose p;
  p.x_mm = t.translation.x();
  p.y_mm = t.translation.y();
  p.z_mm = t.translation.z();
  const double sb = std::hypot(r(0, 2), r(1, 2));
  p.beta_rad = std::atan2(sb, r(2, 2));
  if (sb > 1e-12) {
    p.alpha_rad = std::atan2(r(1, 2), r(0, 2));
    // Gamma from what Rz(alpha) Ry(beta) leaves (Rz(gamma)), not from the third row alone: for a small
    // beta that row is mostly rounding noise, and the pose rebuilt from it missed R by up to 1e-4 rad.
    const Mat3d left = (RotZ(p.alpha_rad) * RotY(p.beta_rad)).rotation.transpose() * r;
    p.gamma_rad = std::atan2(left(1, 0), left(0, 0));
  } else {
    // Gimbal lock: only alpha + gamma (beta = 0) or alpha - gamma (beta = pi) is defined; put it
    // all in alpha. With beta = 0, R = Rz(alpha); with beta = pi, R(0,0) = -cos a, R(1,0) = -sin a.
    p.gamma_rad = 0;
    p.alpha_rad = r(2, 2) > 0 ? std::atan2(r(1, 0), r(0, 0)) : std::atan2(-r(1, 0), -r(0, 0));
  }
  return p;
}

const char* BiclopsSideName(BiclopsSide side) { return side == BiclopsSide::kLeft ? "left" : "right"; }

std::vector<ParamSpec> PtuParamSpecs(BiclopsSide side) {
  const bool left = side == BiclopsSide::kLeft;
  // As-designed values, rounded from the calibrated ones of Table 6.1.
  return {
      {"tx", Unit::kMillimetre, left ? 111.0 : -80.0, "PTU base in the TCF, x (eq. 3.11)"},
      {"ty", Unit::kMillimetre, left ? -60.0 : 122.0, "PTU base in the TCF, y"},
      {"tz", Unit::kMillimetre, left ? 221.0 : 230.0, "PTU base in the TCF, z"},
      {"theta_x", Unit::kDegree, 0.0, "PTU base rotation about x"},
      {"theta_y", Unit::kDegree, 0.0, "PTU base rotation about y"},
      {"theta_z", Unit::kDegree, 45.0, "PTU base rotation about z"},
      {"theta1", Unit::kDegree, 90.0, "tilt link offset (DH, eq. 3.13)"},
      {"alpha1", Unit::kDegree, 90.0, "angle between pan and tilt axes"},
      {"a1", Unit::kMillimetre, left ? -9.0 : -10.0, "distance between pan and tilt axes"},
      {"d1", Unit::kMillimetre, 10.0, "tilt link offset along the tilt axis"},
      {"theta2", Unit::kDegree, -90.0, "camera link rotation (DH, eq. 3.14)"},
      {"alpha2", Unit::kDegree, 90.0, "camera link twist"},
      {"a2", Unit::kMillimetre, left ? 54.0 : 45.0, "camera link length"},
      {"d2", Unit::kMillimetre, left ? 43.0 : 28.0, "camera link offset along the optical axis"},
  };
}

CameraModel BiclopsNominalCamera(BiclopsSide /*side*/) {
  CameraModel c;
  c.width = 640;
  c.height = 480;
  c.params = {1240.0, 1240.0, 319.5, 239.5, 0, 0, 0, 0, 0};
  return c;
}

Eigen::Matrix<double, 3, 4> ProjectionMatrix(const CameraModel& camera, const Rigid3d& cam_from_base) {
  return camera.K() * cam_from_base.Matrix3x4();
}

}  // namespace idi
