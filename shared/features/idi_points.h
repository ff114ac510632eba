// IDI points (§7.10): intersections of EMPL lines near their segments, with topology and covariance.
#pragma once

#include <functional>
#include <vector>

#include "shared/features/features.h"
#include "shared/features/gradient.h"
#include "shared/features/pixel_geometry.h"

namespace idi {

// The variance of the signed distance n·x - d of point x from a line, from the line's (angle, offset)
// covariance.
double LineDistanceVariance(const EmplLine& line, const Eigen::Vector2d& x);

// Weighted least-squares point of two or more lines, each weighted by the inverse variance of its
// distance at the point; the covariance is the inverse of the normal matrix (for two lines this is
// exactly the first-order propagation of both lines' covariances). False if degenerate.
bool IntersectLinesWeighted(const std::vector<const EmplLine*>& lines, const Eigen::Vector2d& start,
                            Eigen::Vector2d* xy, Eigen::Matrix2d* covariance);

// Finds the IDI points of `lines` (§7.10): pairs meeting at least min_angle_deg apart whose
// intersection lies on both confirmed segments or their unconfirmed extensions (§8.8.2); points
// closer than merge_radius_px become one point of all their lines; a point its lines place no better
// than max_point_sigma_px is dropped before the next rule, so that it does not stand in a line's way;
// with first_point_beyond_end, a line stays only in the nearest point beyond each end of its segment
// (points left with fewer than two lines go, and so do those that become too imprecise). Sets each
// line's point_ids (ordered from p1 to p2) and returns the points with ids 0..n-1.
//
// With `gap`, an intersection up to options.max_gap_px beyond a line's confirmed segment but past its
// extension still counts for that line when gap(line, end, x) says the image between the segment's
// nearer end and x carries the line's edge.
using GapTest = std::function<bool(const EmplLine& line, const Eigen::Vector2d& end, const Eigen::Vector2d& x)>;
std::vector<IdiPoint> FindIdiPoints(
    std::vector<EmplLine>* lines, const IdiOptions& options, int width, int height, const GapTest& gap = nullptr);

// Whether the gradient images carry `line`'s edge on the line from `end` (an end of its confirmed
// segment) to `x` (beyond that end), leaving out the last `skip_px` before x (where the edge of the
// line it meets there is within reach of the smoothing): in every stretch of at most 3 px, the mean
// gradient along the line's normal (0 where the gradient's direction is more than 30 deg off the normal,
// and with the sign of the edge's contrast next to `end`) is at least `min_strength` times its mean
// over the 10 px of the segment next to `end`. Positions are in fit coordinates (`geometry`).
bool EdgeContinues(const GradientImages& gradients,
                   const PixelGeometry& geometry,
                   const EmplLine& line,
                   const Eigen::Vector2d& end,
                   const Eigen::Vector2d& x,
                   double skip_px,
                   double min_strength);

// Whether `point`'s own standard deviation, sqrt(trace) of its covariance, is within
// options.max_point_sigma_px (always, when that is 0): points beyond it are not reported.
bool PlacedPreciselyEnough(const IdiPoint& point, const IdiOptions& options);

// Distance of x beyond the confirmed segment of `line` measured along the line (0 when x projects
// inside [p1, p2]).
double DistanceBeyondSegment(const EmplLine& line, const Eigen::Vector2d& x);

}  // namespace idi
