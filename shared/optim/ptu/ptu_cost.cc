#include "shared/optim/ptu/ptu_cost.h"

#include "shared/optim/twist_chain.h"

namespace idi::optim {
namespace {

std::vector<int> PtuSpotBlockSizes() {
  std::vector<int> sizes(static_cast<std::size_t>(kPtuParamCount + kCameraParamCount), 1);
  sizes.push_back(3);
  return sizes;
}

// ^E T_3 of one image as a chain of elementary motions (eqs. 3.11-3.14), the PTU parameters in
// columns 0..13 (PtuParam order); twists are in the TCF frame E.
TwistChain PtuCameraChain(const double* const* parameters, double pan, double tilt) {
  auto p = [parameters](int k) { return parameters[k][0]; };
  TwistChain c;
  // ^E T_0, eq. 3.11.
  c.TransX(p(kPtuTx), kPtuTx);
  c.TransY(p(kPtuTy), kPtuTy);
  c.TransZ(p(kPtuTz), kPtuTz);
  c.RotX(p(kPtuThetaX), kPtuThetaX);
  c.RotY(p(kPtuThetaY), kPtuThetaY);
  c.RotZ(p(kPtuThetaZ), kPtuThetaZ);
  // ^0 T_1, eq. 3.12: the pan reading.
  c.RotZ(pan);
  // ^1 T_2, eq. 3.13: modified DH Rx(alpha1) Tx(a1) Rz(theta1 + tilt) Tz(d1).
  c.RotX(p(kPtuAlpha1), kPtuAlpha1);
  c.TransX(p(kPtuA1), kPtuA1);
  c.RotZ(p(kPtuTheta1) + tilt, kPtuTheta1);
  c.TransZ(p(kPtuD1), kPtuD1);
  // ^2 T_3, eq. 3.14.
  c.RotX(p(kPtuAlpha2), kPtuAlpha2);
  c.TransX(p(kPtuA2), kPtuA2);
  c.RotZ(p(kPtuTheta2), kPtuTheta2);
  c.TransZ(p(kPtuD2), kPtuD2);
  return c;
}

}  // namespace

PtuSpotResidual::PtuSpotResidual(const Rigid3d& base_from_tcf, double pan_rad, double tilt_rad,
                                 const Vec2d& observed_px, double sigma_px)
    : ResidualFunction(2, PtuSpotBlockSizes()),
      base_from_tcf_(base_from_tcf),
      pan_rad_(pan_rad),
      tilt_rad_(tilt_rad),
      observed_px_(observed_px),
      inv_sigma_(1.0 / sigma_px) {
  IDI_CHECK(sigma_px > 0, "PtuSpotResidual: sigma_px must be positive");
}

bool PtuSpotResidual::Evaluate(const double* const* parameters, double* residuals, double** jacobians) const {
  constexpr int kIntr = kPtuParamCount;
  constexpr int kPoint = kPtuParamCount + kCameraParamCount;
  double intr[kCameraParamCount];
  for (int i = 0; i < kCameraParamCount; ++i) intr[i] = parameters[kIntr + i][0];
  // The point in the TCF frame (^B T_E is a constant of the image), then in the camera frame.
  const Vec3d x_base(parameters[kPoint][0], parameters[kPoint][1], parameters[kPoint][2]);
  const Vec3d x = base_from_tcf_.rotation.transpose() * (x_base - base_from_tcf_.translation);
  const TwistChain chain = PtuCameraChain(parameters, pan_rad_, tilt_rad_);
  const Mat3d& r = chain.rotation();  // tcf_from_camera
  const Vec3d p = r.transpose() * (x - chain.translation());
  if (!(p.z() > 1e-9)) return false;
  const Vec2d px = ProjectToPixel(intr, p);
  residuals[0] = (px.x() - observed_px_.x()) * inv_sigma_;
  residuals[1] = (px.y() - observed_px_.y()) * inv_sigma_;
  if (jacobians == nullptr) return true;

  // Pixel with respect to the point in the camera frame: K' (distortion Jacobian) (perspective division).
  const double xn = p.x() / p.z(), yn = p.y() / p.z();
  const double r2 = xn * xn + yn * yn;
  const double k1 = intr[kK1], k2 = intr[kK2], k3 = intr[kK3], p1 = intr[kP1], p2 = intr[kP2];
  const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
  const double d_radial_d_r2 = k1 + r2 * (2 * k2 + 3 * r2 * k3);
  const double xd = xn * radial + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn * xn);
  const double yd = yn * radial + p1 * (r2 + 2 * yn * yn) + 2 * p2 * xn * yn;
  Eigen::Matrix2d d_dist;
  d_dist << radial + 2 * xn * xn * d_radial_d_r2 + 2 * p1 * yn + 6 * p2 * xn,
      2 * xn * yn * d_radial_d_r2 + 2 * p1 * xn + 2 * p2 * yn,  //
      2 * xn * yn * d_radial_d_r2 + 2 * p1 * xn + 2 * p2 * yn,
      radial + 2 * yn * yn * d_radial_d_r2 + 6 * p1 * yn + 2 * p2 * xn;
  Eigen::Matrix<double, 2, 3> d_norm;
  d_norm << 1 / p.z(), 0, -xn / p.z(), 0, 1 / p.z(), -yn / p.z();
  const Eigen::Matrix<double, 2, 3> d_px_d_p =
      (Eigen::Vector2d(intr[kFx], intr[kFy]).asDiagonal() * d_dist * d_norm) * inv_sigma_;

  // Parameters move the camera: d p / d k = -R^T (omega_k x X + v0_k) (see twist_chain.h).
  const Eigen::Matrix<double, 2, 3> d_px_d_tcf = d_px_d_p * r.transpose();
  for (int k = 0; k < kPtuParamCount; ++k) {
    if (jacobians[k] == nullptr) continue;
    const Vec3d velocity = chain.omega().col(k).cross(x) + chain.v0().col(k);
    const Eigen::Vector2d d = -d_px_d_tcf * velocity;
    jacobians[k][0] = d.x();
    jacobians[k][1] = d.y();
  }
  // Intrinsics.
  const double fx = intr[kFx] * inv_sigma_, fy = intr[kFy] * inv_sigma_;
  const double d_intr[kCameraParamCount][2] = {
      {xd * inv_sigma_, 0},                                // fx
      {0, yd * inv_sigma_},                                // fy
      {inv_sigma_, 0},                                     // cx
      {0, inv_sigma_},                                     // cy
      {fx * xn * r2, fy * yn * r2},                        // k1
      {fx * xn * r2 * r2, fy * yn * r2 * r2},              // k2
      {fx * 2 * xn * yn, fy * (r2 + 2 * yn * yn)},         // p1
      {fx * (r2 + 2 * xn * xn), fy * 2 * xn * yn},         // p2
      {fx * xn * r2 * r2 * r2, fy * yn * r2 * r2 * r2},    // k3
  };
  for (int k = 0; k < kCameraParamCount; ++k) {
    if (jacobians[kIntr + k] == nullptr) continue;
    jacobians[kIntr + k][0] = d_intr[k][0];
    jacobians[kIntr + k][1] = d_intr[k][1];
  }
  if (jacobians[kPoint] != nullptr) {
    const Eigen::Matrix<double, 2, 3> d_px_d_base = d_px_d_tcf * base_from_tcf_.rotation.transpose();
    for (int i = 0; i < 2; ++i) {
      for (int k = 0; k < 3; ++k) jacobians[kPoint][3 * i + k] = d_px_d_base(i, k);
    }
  }
  return true;
}

std::vector<double*> PtuSpotBlocks(double* ptu, double* intrinsics, double* point) {
  std::vector<double*> blocks;
  blocks.reserve(static_cast<std::size_t>(kPtuSpotBlockCount));
  for (int i = 0; i < kPtuParamCount; ++i) blocks.push_back(ptu + i);
  for (int i = 0; i < kCameraParamCount; ++i) blocks.push_back(intrinsics + i);
  blocks.push_back(point);
  return blocks;
}

}  // namespace idi::optim
