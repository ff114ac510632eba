#include "shared/reconstruction/epipolar.h"

#include <Eigen/Dense>
#include <cmath>

namespace idi {

ProjectionMatrix34 MakeProjection(const Mat3d& k, const Rigid3d& cam_from_world) {
  return k * cam_from_world.Matrix3x4();
}

std::optional<Vec3d> CameraCentre(const ProjectionMatrix34& p) {
  const Mat3d m = p.leftCols<3>();
  Eigen::FullPivLU<Mat3d> lu(m);
  if (!lu.isInvertible()) {
    return std::nullopt;
  }
  // P = [M | p4] and P (C, 1) = 0 gives C = -M^-1 p4 (the ray origin of eq. 8.9).
  return Vec3d(-lu.solve(p.col(3)));
}

std::optional<Mat3d> FundamentalFromProjections(const ProjectionMatrix34& p1, const ProjectionMatrix34& p2) {
  const auto c1 = CameraCentre(p1);
  const auto c2 = CameraCentre(p2);
  if (!c1 || !c2 || (*c1 - *c2).norm() < 1e-9 * std::max(1.0, c1->norm())) {
    return std::nullopt;
  }
  const Eigen::Vector3d e2 = p2 * c1->homogeneous();
  Mat3d ex;
  ex << 0, -e2.z(), e2.y(), e2.z(), 0, -e2.x(), -e2.y(), e2.x(), 0;
  // For finite cameras P = [M | p4] the pseudo-inverse route of eq. 8.16 equals [e2]x M2 M1^-1 (the
  // homography of the plane at infinity; the null-space part of P1^+ is killed by [e2]x). Solving
  // with M1 is far better conditioned than inverting P1 P1^T, whose entries are ~f^2.
  const Mat3d m1 = p1.leftCols<3>(), m2 = p2.leftCols<3>();
  Mat3d f = ex * m2 * m1.fullPivLu().inverse();
  const double norm = f.norm();
  if (!(norm > 0) || !f.allFinite()) {
    return std::nullopt;
  }
  return Mat3d(f / norm);
}

Line2d LineFromHomogeneous(const Eigen::Vector3d& b) {
  const double n = std::hypot(b.x(), b.y());
  return {Vec2d(b.x() / n, b.y() / n), -b.z() / n};
}

Eigen::Vector3d HomogeneousLine(const Line2d& line) { return {line.normal.x(), line.normal.y(), -line.offset}; }

Line2d EpipolarLine(const Mat3d& f, const Vec2d& x1) { return LineFromHomogeneous(f * x1.homogeneous()); }

Line2d EpipolarLineInFirst(const Mat3d& f, const Vec2d& x2) {
  return LineFromHomogeneous(f.transpose() * x2.homogeneous());
}

double EpipolarDistance(const Mat3d& f, const Vec2d& x1, const Vec2d& x2) {
  return std::abs(EpipolarLine(f, x1).SignedDistance(x2));
}

}  // namespace idi
