// Triangulation of points from rays and of lines from planes (§8.4, §8.5), over two or more views.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include "shared/reconstruction/epipolar.h"

namespace idi {

// One observation of a point: the view's camera (intrinsics with distortion and pose) and the pixel.
struct PointObservation {
  const CameraModel* camera = nullptr;
  Rigid3d cam_from_world;
  Vec2d pixel;
  double sigma_px = 0;  // > 0: the residual is weighted by 1 / sigma; 0: every observation weighs the same
};

struct TriangulatedPoint {
  Vec3d xyz;
  double reprojection_rms_px = 0;      // over the observations
  double min_ray_angle_rad = 0;        // largest angle between two rays (conditioning)
  double chi2 = 0;                     // sum of the squared residuals in sigmas (in px^2 when unweighted)
};

// Least squares over all rays (§8.4): the point closest to the back-projected rays, then refined by
// Gauss-Newton on the reprojection error (so each view counts in pixels, or in its sigmas). nullopt
// with fewer than two observations, rays (nearly) parallel, or the point behind a camera.
std::optional<TriangulatedPoint> TriangulatePoint(const std::vector<PointObservation>& observations,
                                                  double min_angle_rad = 1e-3);

// Whether a triangulation weighted by the observations' sigmas passes the chi-square test at z standard
// deviations: n observations give 2n residuals for 3 unknowns.
bool ChiSquareConsistent(const TriangulatedPoint& point, std::size_t observations, double z);

// The observation without which the rest agree best (the rest's lowest chi-square; when a precise but
// wrong observation pulls the point, the largest residual often belongs to a right one), and the rest's
// triangulation. nullopt when no n - 1 of them triangulate.
struct LeftOut {
  std::size_t index = 0;
  TriangulatedPoint rest;
};
std::optional<LeftOut> LeaveOneOut(const std::vector<PointObservation>& observations, double min_angle_rad = 1e-3);

// One observation of a 3D line: its image line (undistorted pixel coordinates, normal . x = offset) in
// a view with projection matrix P.
struct LineObservation {
  ProjectionMatrix34 p;
  Line2d line;
};

// The 3D line from the back-projected planes B P X = 0 (eqs. 8.10-8.13): two views give two planes
// whose intersection is the line; more views give the least-squares line, the 2D null space of the
// stacked planes (SVD). nullopt when the planes are (nearly) parallel.
std::optional<Line3d> TriangulateLine(const std::vector<LineObservation>& observations, double min_angle_rad = 1e-3);

}  // namespace idi
