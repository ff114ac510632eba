// The path the vehicle's reference point (the midpoint of the wheel axle) drives: the track's centre
// polyline with every corner replaced by a circular arc tangent to both legs (§8.12.4: the RMP moves
// "in a curve from the current direction to the final direction" instead of turning on the spot).
// Arc-length parametrised; lines and arcs only, so heading is continuous and curvature piecewise
// constant.
#pragma once

#include <vector>

#include "rmp/track/polygon.h"
#include "rmp/track/pose2.h"
#include "shared/geometry/rigid3.h"

namespace idi::rmp {

// How much a corner of turn angle `turn_rad` (0 = straight on, pi = reversal) is cut by an arc of
// radius r: the distance from the polyline's vertex to the arc's midpoint, r (1 / cos(turn / 2) - 1).
double CornerCut(double radius_m, double turn_rad);
// The radius that cuts the corner by `cut_m`.
double RadiusForCut(double cut_m, double turn_rad);

struct PathPoint {
  Vec2d xy = Vec2d::Zero();
  double heading = 0.0;    // rad, counter-clockwise from x
  double curvature = 0.0;  // 1/m, positive turning left
};

struct PathProjection {
  double s = 0.0;            // arc length of the closest point
  double lateral_m = 0.0;    // signed distance, positive when the point lies left of the path
  double heading_error = 0.0;  // pose yaw minus path heading, wrapped
  double distance_m = 0.0;   // |lateral| (or the distance to an end point when beyond it)
};

class SmoothPath {
 public:
  SmoothPath() = default;
  // `vertices`: the polyline (at least two distinct points). `radii[i]` is the corner radius wanted
  // at interior vertex i + 1 (radii.size() == vertices.size() - 2); each is reduced where the legs are
  // too short to hold the tangents (each leg lends at most half its length to each corner).
  // Consecutive duplicate vertices are dropped.
  static SmoothPath Build(const std::vector<Vec2d>& vertices, const std::vector<double>& radii);

  bool empty() const { return segments_.empty(); }
  double length() const { return length_; }
  PathPoint At(double s) const;  // clamped to [0, length]
  // Mean curvature over [s0, s1] (the turn between them divided by the distance).
  double MeanCurvature(double s0, double s1) const;
  // Closest point, searched over [s_min, s_max] (the whole path by default).
  PathProjection Project(const Vec2d& p, double yaw, double s_min = -1e300, double s_max = 1e300) const;
  // The corner radii actually used (after shrinking to fit), one per interior vertex.
  const std::vector<double>& radii() const { return radii_; }
  const std::vector<Vec2d>& vertices() const { return vertices_; }
  // Arc length where each interior vertex's corner starts and ends.
  const std::vector<std::pair<double, double>>& corner_spans() const { return corner_spans_; }

 private:
  struct Segment {
    double s0 = 0, length = 0;
    Vec2d start = Vec2d::Zero();
    double heading0 = 0;
    double curvature = 0;  // 0: a straight line
  };
  PathPoint AtSegment(const Segment& seg, double ds) const;

  std::vector<Segment> segments_;
  std::vector<Vec2d> vertices_;
  std::vector<double> radii_;
  std::vector<std::pair<double, double>> corner_spans_;
  double length_ = 0.0;
};

// Douglas-Peucker simplification keeping the end points; points closer than `tolerance_m` to the
// simplified polyline are dropped.
std::vector<Vec2d> SimplifyPolyline(const std::vector<Vec2d>& points, double tolerance_m);

// Length of a polyline.
double PolylineLength(const std::vector<Vec2d>& points);

// Distance from p to the closest point of a polyline (infinite when it is empty).
double DistanceToPolyline(const std::vector<Vec2d>& polyline, const Vec2d& p);

}  // namespace idi::rmp
