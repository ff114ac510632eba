#include "rmp/planning/path.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace idi::rmp {

double CornerCut(double radius_m, double turn_rad) {
  const double half = 0.5 * std::min(std::abs(turn_rad), kPi - 1e-6);
  return radius_m * (1.0 / std::cos(half) - 1.0);
}

double RadiusForCut(double cut_m, double turn_rad) {
  const double half = 0.5 * std::min(std::abs(turn_rad), kPi - 1e-6);
  const double k = 1.0 / std::cos(half) - 1.0;
  return k < 1e-12 ? std::numeric_limits<double>::infinity() : cut_m / k;
}

SmoothPath SmoothPath::Build(const std::vector<Vec2d>& input, const std::vector<double>& wanted_radii) {
  SmoothPath path;
  // Drop duplicates, carrying each kept interior vertex's radius.
  std::vector<Vec2d> v;
  std::vector<double> wanted;
  for (std::size_t i = 0; i < input.size(); ++i) {
    if (!v.empty() && (input[i] - v.back()).norm() < 1e-6) continue;
    v.push_back(input[i]);
    const double r = (i >= 1 && i + 1 < input.size() && i - 1 < wanted_radii.size()) ? wanted_radii[i - 1] : 0.0;
    wanted.push_back(r);
  }
  path.vertices_ = v;
  if (v.size() < 2) return path;
  const std::size_t n = v.size();
  // Tangent lengths: t = r tan(turn / 2), each leg lends at most half its length to a corner (all of
  // it at the path's ends, which have no corner).
  std::vector<double> turn(n, 0.0), radius(n, 0.0), tangent(n, 0.0);
  for (std::size_t i = 1; i + 1 < n; ++i) {
    const Vec2d d0 = (v[i] - v[i - 1]).normalized(), d1 = (v[i + 1] - v[i]).normalized();
    turn[i] = std::atan2(d0.x() * d1.y() - d0.y() * d1.x(), d0.dot(d1));
    const double half_tan = std::tan(0.5 * std::min(std::abs(turn[i]), kPi - 1e-3));
    const double leg0 = (v[i] - v[i - 1]).norm() * (i == 1 ? 1.0 : 0.5);
    const double leg1 = (v[i + 1] - v[i]).norm() * (i + 2 == n ? 1.0 : 0.5);
    double r = std::max(0.0, wanted[i]);
    if (half_tan > 1e-12) r = std::min(r, std::min(leg0, leg1) / half_tan);
    radius[i] = half_tan > 1e-12 ? r : 0.0;
    tangent[i] = radius[i] * half_tan;
  }
  double s = 0.0;
  auto add_line = [&](const Vec2d& a, const Vec2d& b) {
    const double len = (b - a).norm();
    if (len < 1e-9) return;
    path.segments_.push_back({s, len, a, std::atan2(b.y() - a.y(), b.x() - a.x()), 0.0});
    s += len;
  };
  Vec2d cursor = v[0];
  for (std::size_t i = 1; i < n; ++i) {
    const Vec2d d0 = (v[i] - v[i - 1]).normalized();
    if (i + 1 == n) {
      add_line(cursor, v[i]);
      break;
    }
    const Vec2d arc_start = v[i] - tangent[i] * d0;
    add_line(cursor, arc_start);
    const double corner_s0 = s;
    if (radius[i] > 1e-9 && std::abs(turn[i]) > 1e-9) {
      const double len = radius[i] * std::abs(turn[i]);
      const double k = (turn[i] > 0 ? 1.0 : -1.0) / radius[i];
      path.segments_.push_back({s, len, arc_start, std::atan2(d0.y(), d0.x()), k});
      s += len;
      cursor = path.AtSegment(path.segments_.back(), len).xy;
    } else {
      cursor = arc_start;
      // A sharp vertex (no room for an arc): a zero-length turn. Heading jumps here.
    }
    path.corner_spans_.emplace_back(corner_s0, s);
    path.radii_.push_back(radius[i]);
  }
  path.length_ = s;
  return path;
}

PathPoint SmoothPath::AtSegment(const Segment& seg, double ds) const {
  PathPoint p;
  p.curvature = seg.curvature;
  if (seg.curvature == 0.0) {
    p.heading = seg.heading0;
    p.xy = seg.start + ds * Vec2d(std::cos(seg.heading0), std::sin(seg.heading0));
  } else {
    const double r = 1.0 / seg.curvature;  // signed
    p.heading = seg.heading0 + ds * seg.curvature;
    // Centre to the left (r > 0) or right of the start.
    const Vec2d centre = seg.start + r * Vec2d(-std::sin(seg.heading0), std::cos(seg.heading0));
    p.xy = centre + r * Vec2d(std::sin(p.heading), -std::cos(p.heading));
  }
  p.heading = WrapAngle(p.heading);
  return p;
}

PathPoint SmoothPath::At(double s) const {
  if (segments_.empty()) return {};
  s = std::clamp(s, 0.0, length_);
  auto it = std::upper_bound(segments_.begin(), segments_.end(), s,
                             [](double value, const Segment& seg) { return value < seg.s0; });
  const Segment& seg = it == segments_.begin() ? segments_.front() : *std::prev(it);
  return AtSegment(seg, std::min(s - seg.s0, seg.length));
}

double SmoothPath::MeanCurvature(double s0, double s1) const {
  if (segments_.empty()) return 0.0;
  s0 = std::clamp(s0, 0.0, length_);
  s1 = std::clamp(s1, 0.0, length_);
  if (s1 - s0 < 1e-6) return At(s0).curvature;
  double turn = 0.0;
  for (const Segment& seg : segments_) {
    const double a = std::max(s0, seg.s0), b = std::min(s1, seg.s0 + seg.length);
    if (b > a) turn += (b - a) * seg.curvature;
  }
  return turn / (s1 - s0);
}

PathProjection SmoothPath::Project(const Vec2d& p, double yaw, double s_min, double s_max) const {
  PathProjection best;
  best.distance_m = std::numeric_limits<double>::infinity();
  for (const Segment& seg : segments_) {
    if (seg.s0 + seg.length < s_min || seg.s0 > s_max) continue;
    double ds;
    if (seg.curvature == 0.0) {
      const Vec2d dir(std::cos(seg.heading0), std::sin(seg.heading0));
      ds = (p - seg.start).dot(dir);
    } else {
      const double r = 1.0 / seg.curvature;
      const Vec2d centre = seg.start + r * Vec2d(-std::sin(seg.heading0), std::cos(seg.heading0));
      const Vec2d rel = p - centre;
      if (rel.norm() < 1e-12) {
        ds = 0.0;
      } else {
        // Angle swept from the start radius to p's radius, in the arc's direction.
        const Vec2d start_rel = seg.start - centre;
        double ang = std::atan2(start_rel.x() * rel.y() - start_rel.y() * rel.x(), start_rel.dot(rel));
        if (seg.curvature < 0) ang = -ang;
        if (ang < 0) ang += 2 * kPi;  // [0, 2 pi)
        const double sweep = seg.length * std::abs(seg.curvature);
        if (ang > sweep) ang = (ang - sweep < 2 * kPi - ang) ? sweep : 0.0;  // the nearer end
        ds = ang * std::abs(r);
      }
    }
    ds = std::clamp(ds, std::max(0.0, s_min - seg.s0), std::min(seg.length, s_max - seg.s0));
    if (ds < 0) ds = 0;
    const PathPoint q = AtSegment(seg, ds);
    const double d = (p - q.xy).norm();
    if (d < best.distance_m) {
      best.distance_m = d;
      best.s = seg.s0 + ds;
      const Vec2d left(-std::sin(q.heading), std::cos(q.heading));
      best.lateral_m = (p - q.xy).dot(left);
      best.heading_error = WrapAngle(yaw - q.heading);
    }
  }
  return best;
}

namespace {

void SimplifyRange(const std::vector<Vec2d>& pts, std::size_t a, std::size_t b, double tol, std::vector<bool>* keep) {
  if (b <= a + 1) return;
  const Vec2d d = pts[b] - pts[a];
  const double len = d.norm();
  double worst = -1.0;
  std::size_t worst_i = a;
  for (std::size_t i = a + 1; i < b; ++i) {
    const Vec2d r = pts[i] - pts[a];
    const double dist = len < 1e-12 ? r.norm() : std::abs(d.x() * r.y() - d.y() * r.x()) / len;
    if (dist > worst) {
      worst = dist;
      worst_i = i;
    }
  }
  if (worst > tol) {
    (*keep)[worst_i] = true;
    SimplifyRange(pts, a, worst_i, tol, keep);
    SimplifyRange(pts, worst_i, b, tol, keep);
  }
}

}  // namespace

std::vector<Vec2d> SimplifyPolyline(const std::vector<Vec2d>& points, double tolerance_m) {
  if (points.size() <= 2) return points;
  std::vector<bool> keep(points.size(), false);
  keep.front() = keep.back() = true;
  SimplifyRange(points, 0, points.size() - 1, tolerance_m, &keep);
  std::vector<Vec2d> out;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (keep[i]) out.push_back(points[i]);
  }
  return out;
}

double PolylineLength(const std::vector<Vec2d>& points) {
  double len = 0.0;
  for (std::size_t i = 1; i < points.size(); ++i) len += (points[i] - points[i - 1]).norm();
  return len;
}

double DistanceToPolyline(const std::vector<Vec2d>& polyline, const Vec2d& p) {
  double best = std::numeric_limits<double>::infinity();
  if (polyline.size() == 1) return (p - polyline[0]).norm();
  for (std::size_t i = 1; i < polyline.size(); ++i) {
    const Vec2d a = polyline[i - 1], d = polyline[i] - a;
    const double l2 = d.squaredNorm();
    const double t = l2 < 1e-18 ? 0.0 : std::clamp((p - a).dot(d) / l2, 0.0, 1.0);
    best = std::min(best, (a + t * d - p).norm());
  }
  return best;
}

}  // namespace idi::rmp
