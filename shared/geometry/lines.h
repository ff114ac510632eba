// Lines and planes in 2D and 3D, templated on the scalar.
#pragma once

#include <Eigen/Core>
#include <Eigen/Dense>
#include <cmath>
#include <optional>
#include <vector>

#include "shared/geometry/rigid3.h"

namespace idi {

// A 3D line through `origin` along the unit vector `direction`.
template <typename T>
struct Line3 {
  Vec3<T> origin = Vec3<T>::Zero();
  Vec3<T> direction = Vec3<T>::UnitZ();

  Vec3<T> PointAt(const T& s) const { return origin + s * direction; }
};
using Line3d = Line3<double>;

// The line through two distinct points.
template <typename T>
Line3<T> LineThrough(const Vec3<T>& a, const Vec3<T>& b) {
  return {a, (b - a).normalized()};
}

// Vector from the line's closest point to p (perpendicular to the line).
template <typename T>
Vec3<T> PerpendicularToLine(const Line3<T>& line, const Vec3<T>& p) {
  const Vec3<T> v = p - line.origin;
  return v - v.dot(line.direction) * line.direction;
}

// Shortest distance from a point to a line. Written as the norm of the cross product so that
// automatic differentiation stays finite whenever the distance is not exactly zero.
template <typename T>
T DistancePointToLine(const Line3<T>& line, const Vec3<T>& p) {
  return (p - line.origin).cross(line.direction).norm();
}

// Signed parameter s of the point on `line` closest to p.
template <typename T>
T ProjectOntoLine(const Line3<T>& line, const Vec3<T>& p) {
  return (p - line.origin).dot(line.direction);
}

// Closest points between two lines: returns (s, t) with a.PointAt(s), b.PointAt(t) closest;
// nullopt when the lines are parallel to within `parallel_tol` (|sin angle|).
template <typename T>
std::optional<std::pair<T, T>> ClosestPointsBetweenLines(const Line3<T>& a, const Line3<T>& b,
                                                         double parallel_tol = 1e-12) {
  const Vec3<T> w0 = a.origin - b.origin;
  const T bd = a.direction.dot(b.direction);
  const T denom = T(1) - bd * bd;
  using std::abs;
  if (abs(denom) < T(parallel_tol)) {
    return std::nullopt;
  }
  const T d = a.direction.dot(w0);
  const T e = b.direction.dot(w0);
  const T s = (bd * e - d) / denom;
  const T t = (e - bd * d) / denom;
  return std::make_pair(s, t);
}

// Shortest distance between two lines (the common perpendicular), eq. used by chapter 5's cost.
template <typename T>
T DistanceBetweenLines(const Line3<T>& a, const Line3<T>& b) {
  const Vec3<T> n = a.direction.cross(b.direction);
  const T nn = n.norm();
  using std::abs;
  if (nn < T(1e-12)) {
    return DistancePointToLine(a, b.origin);
  }
  return abs((b.origin - a.origin).dot(n)) / nn;
}

// The point minimising the sum of squared distances to a set of lines (least squares over all
// rays, §8.4 and §4.5.4). nullopt when the lines are all parallel.
inline std::optional<Vec3d> PointClosestToLines(const std::vector<Line3d>& lines) {
  Mat3d a = Mat3d::Zero();
  Vec3d b = Vec3d::Zero();
  for (const Line3d& l : lines) {
    const Mat3d p = Mat3d::Identity() - l.direction * l.direction.transpose();
    a += p;
    b += p * l.origin;
  }
  Eigen::JacobiSVD<Mat3d> svd(a, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const auto& sv = svd.singularValues();
  if (lines.size() < 2 || sv(2) < 1e-9 * std::max(1.0, sv(0))) {
    return std::nullopt;
  }
  return svd.solve(b);
}

// A plane n·x = offset with unit normal n.
template <typename T>
struct Plane3 {
  Vec3<T> normal = Vec3<T>::UnitZ();
  T offset = T(0);

  T SignedDistance(const Vec3<T>& p) const { return normal.dot(p) - offset; }
};
using Plane3d = Plane3<double>;

// Intersection of a line with a plane; nullopt if parallel. Returns the line parameter s.
template <typename T>
std::optional<T> IntersectLinePlane(const Line3<T>& line, const Plane3<T>& plane, double parallel_tol = 1e-12) {
  const T denom = plane.normal.dot(line.direction);
  using std::abs;
  if (abs(denom) < T(parallel_tol)) {
    return std::nullopt;
  }
  return (plane.offset - plane.normal.dot(line.origin)) / denom;
}

// A 2D line n·x = offset with unit normal n (DESIGN.md §6: lines are sets of x with normal·x = offset).
template <typename T>
struct Line2 {
  Vec2<T> normal = Vec2<T>::UnitY();
  T offset = T(0);

  T SignedDistance(const Vec2<T>& p) const { return normal.dot(p) - offset; }
  Vec2<T> Direction() const { return Vec2<T>(-normal.y(), normal.x()); }
  // The line's point closest to the origin.
  Vec2<T> Foot() const { return normal * offset; }
};
using Line2d = Line2<double>;

// The 2D line through two distinct points.
inline Line2d Line2Through(const Vec2d& a, const Vec2d& b) {
  const Vec2d d = (b - a).normalized();
  const Vec2d n(-d.y(), d.x());
  return {n, n.dot(a)};
}

// Intersection of two 2D lines; nullopt if parallel to within |sin angle| < parallel_tol.
template <typename T>
std::optional<Vec2<T>> IntersectLines2(const Line2<T>& a, const Line2<T>& b, double parallel_tol = 1e-12) {
  const T det = a.normal.x() * b.normal.y() - a.normal.y() * b.normal.x();
  using std::abs;
  if (abs(det) < T(parallel_tol)) {
    return std::nullopt;
  }
  return Vec2<T>((a.offset * b.normal.y() - b.offset * a.normal.y()) / det,
                 (a.normal.x() * b.offset - b.normal.x() * a.offset) / det);
}

}  // namespace idi
