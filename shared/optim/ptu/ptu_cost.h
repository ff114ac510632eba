// The residual of the single-point pan-tilt camera calibration (chapter 6, eq. 6.4 with the point
// unknown): the pixel where the Biclops model (eqs. 3.10-3.14, 6.2; shared/kinematics/biclops.h)
// projects the stationary point, minus the pixel where the spot was found, divided by the spot's
// standard deviation (so the residuals are whitened).
//
// Parameter blocks, so that any single parameter can be held constant (gauge fixing, optional
// distortion terms): kPtuParamCount blocks of size 1 (the PTU parameters in PtuParam order), then
// kCameraParamCount blocks of size 1 (fx, fy, cx, cy, k1, k2, p1, p2, k3), then the point (size 3).
// Derivatives are analytic: every PTU parameter enters the chain through one elementary motion, so
// its derivative is a twist (optim/twist_chain.h); the pinhole and distortion are differentiated
// in closed form.
#pragma once

#include <memory>

#include "shared/geometry/rigid3.h"
#include "shared/kinematics/biclops.h"
#include "shared/optim/least_squares.h"

namespace idi::optim {

inline constexpr int kPtuSpotBlockCount = kPtuParamCount + kCameraParamCount + 1;

class PtuSpotResidual final : public ResidualFunction {
 public:
  // base_from_tcf: ^B T_E of eq. 3.10; pan/tilt: the PTU readings (radians); observed_px: the spot.
  PtuSpotResidual(const Rigid3d& base_from_tcf, double pan_rad, double tilt_rad, const Vec2d& observed_px,
                  double sigma_px);
  // False when the point is behind the camera.
  bool Evaluate(const double* const* parameters, double* residuals, double** jacobians) const override;

 private:
  Rigid3d base_from_tcf_;
  double pan_rad_, tilt_rad_;
  Vec2d observed_px_;
  double inv_sigma_;
};

// The blocks a PtuSpotResidual expects, in its order: pointers into a PTU vector (kPtuParamCount
// values), an intrinsics vector (kCameraParamCount values) and a point (3 values).
std::vector<double*> PtuSpotBlocks(double* ptu, double* intrinsics, double* point);

}  // namespace idi::optim
