#include "shared/calib/evaluation.h"

#include <cmath>

namespace idi::calib {

Result<SpreadStats> SpreadAbout(const std::vector<Line3d>& lines, const Vec3d& reference) {
  if (lines.size() < 2) return InvalidArgument("spread: need at least 2 laser lines, got " + std::to_string(lines.size()));
  Vec3d mean_dir = Vec3d::Zero();
  for (const Line3d& l : lines) mean_dir += l.direction;
  if (!(mean_dir.norm() > 1e-9)) return InvalidArgument("spread: the laser lines point every way");
  const Vec3d n = mean_dir.normalized();
  // In-plane basis.
  const Vec3d u = (std::abs(n.z()) < 0.9 ? Vec3d::UnitZ() : Vec3d::UnitX()).cross(n).normalized();
  const Vec3d v = n.cross(u);
  const Plane3d plane{n, n.dot(reference)};
  SpreadStats s;
  s.center = reference;
  double sum = 0, sum2 = 0;
  for (const Line3d& l : lines) {
    const auto t = IntersectLinePlane(l, plane);
    if (!t) return InvalidArgument("spread: a laser line is parallel to the evaluation plane");
    const Vec3d d = l.PointAt(*t) - reference;
    s.projected.emplace_back(d.dot(u), d.dot(v));
    const double r = d.norm();
    s.max_mm = std::max(s.max_mm, r);
    sum += r;
    sum2 += r * r;
  }
  const double n_lines = static_cast<double>(lines.size());
  s.mean_mm = sum / n_lines;
  s.std_mm = std::sqrt(std::max(0.0, sum2 / n_lines - s.mean_mm * s.mean_mm));
  return s;
}

Result<SpreadStats> LaserSpread(const std::vector<Line3d>& lines) {
  const auto p = PointClosestToLines(lines);
  if (!p) return InvalidArgument("spread: the laser lines do not define a closest point (fewer than 2, or parallel)");
  return SpreadAbout(lines, *p);
}

std::vector<Line3d> LaserLines(const ParamSet& robot, const ParamSet& laser, const std::vector<Joints>& readings) {
  std::vector<Line3d> out;
  out.reserve(readings.size());
  for (const Joints& q : readings) out.push_back(LaserLineInBase(robot.data(), laser.data(), q.data()));
  return out;
}

Result<SpreadStats> RailTransferSpread(const std::vector<RailReading>& readings, const ArmModel& arm1,
                                       const ArmModel& arm2, const std::array<double, 4>& psi) {
  std::vector<Line3d> lines2, lines1_in_r2;
  const Rigid3d r2_from_r1 = Rail1FromRail2(psi.data()).Inverse();
  for (const RailReading& r : readings) {
    lines2.push_back(ArmLineInRailFrame(arm2, r.q2, r.rail2_mm));
    const Line3d l1 = ArmLineInRailFrame(arm1, r.q1, r.rail1_mm);
    lines1_in_r2.push_back({r2_from_r1 * l1.origin, r2_from_r1.RotateVector(l1.direction)});
  }
  const auto p = PointClosestToLines(lines2);
  if (!p) return InvalidArgument("rail spread: robot 2's lines do not define a point");
  return SpreadAbout(lines1_in_r2, *p);
}

}  // namespace idi::calib
