// Projection matrices and epipolar geometry of two calibrated views (§8.3, §8.6).
#pragma once

#include <Eigen/Core>
#include <optional>

#include "shared/camera/pinhole.h"
#include "shared/geometry/lines.h"
#include "shared/geometry/rigid3.h"

namespace idi {

using ProjectionMatrix34 = Eigen::Matrix<double, 3, 4>;

// P = K [R | t] with [R | t] = cam_from_world (eqs. 8.3, 8.5, 8.7). Distortion is not part of P:
// image measurements are undistorted before they meet P.
ProjectionMatrix34 MakeProjection(const Mat3d& k, const Rigid3d& cam_from_world);

// The camera centre C with P C = 0 (eq. 8.18), as a 3D point; nullopt when P's left 3x3 block is
// singular (not a finite camera).
std::optional<Vec3d> CameraCentre(const ProjectionMatrix34& p);

// The fundamental matrix F with x2^T F x1 = 0 for corresponding pixels x1 in view 1 and x2 in view 2:
// F = [e2]x P2 P1^+ with e2 = P2 C1 (eqs. 8.16-8.18). Normalised to unit Frobenius norm.
// nullopt when the two camera centres coincide (no epipolar geometry).
std::optional<Mat3d> FundamentalFromProjections(const ProjectionMatrix34& p1, const ProjectionMatrix34& p2);

// The epipolar line in view 2 of pixel x1 of view 1 (l2 = F x1), as a normalised Line2d.
Line2d EpipolarLine(const Mat3d& f, const Vec2d& x1);
// ... and in view 1 of pixel x2 of view 2 (l1 = F^T x2).
Line2d EpipolarLineInFirst(const Mat3d& f, const Vec2d& x2);

// Distance (px) of x2 from the epipolar line of x1, the "epipolar error" of §8.12.1.
double EpipolarDistance(const Mat3d& f, const Vec2d& x1, const Vec2d& x2);

// A 2D image line as the homogeneous row B = (b1, b2, b3) with B U = 0 (eq. 8.10); from Line2d
// (normal . x = offset) it is (n_x, n_y, -offset).
Eigen::Vector3d HomogeneousLine(const Line2d& line);
Line2d LineFromHomogeneous(const Eigen::Vector3d& b);

}  // namespace idi
