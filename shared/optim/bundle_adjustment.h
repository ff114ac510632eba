// Bundle adjustment (§8.9, eq. 8.20): 3D points (and optionally camera poses and intrinsics, §8.9.1)
// refined to minimise the reprojection error over every view that sees them, with a robust loss and
// visibility (only observed point-view pairs contribute). Besides IDI points, EMPL lines contribute:
// a model point that lies on an image line (an edge's end point) is pulled onto it, which uses the
// line fit's precision along its normal (the reason IDI points beat corners, chapter 7).
#pragma once

#include <vector>

#include "shared/camera/pinhole.h"
#include "shared/geometry/lines.h"
#include "shared/geometry/rigid3.h"
#include "shared/util/status.h"

namespace idi::optim {

struct BaView {
  CameraModel camera;       // intrinsics with distortion
  Rigid3d cam_from_world;
  int intrinsics_group = 0; // views sharing a physical camera share intrinsics when those are refined
  // Views taken from one placement of a mount (both cameras of a head at one rail stop) share that
  // placement's error: with BundleAdjustmentOptions::mount_prior_mm > 0, each mount >= 0 gets one
  // unknown shift along `mount_axis` (world frame, unit length; the rail's direction), the same for all
  // of its views, with that prior. -1: the view's pose is as given.
  int mount = -1;
  Vec3d mount_axis = Vec3d::Zero();
};

struct BaPointObservation {
  int point = -1;
  int view = -1;
  Vec2d pixel = Vec2d::Zero();  // measured, raw (distorted) pixel coordinates
  double sigma_px = 0.1;
};

struct BaLineObservation {
  int point = -1;  // the model point that lies on this image line
  int view = -1;
  Line2d line;     // undistorted pixel coordinates (normal . x = offset)
  double sigma_px = 0.05;
};

// Points known to lie on one plane (the table the object stands on, §8.10's model resting on its
// support): normal . x = offset, the normal held, the offset estimated with a Gaussian prior about its
// given value (0: held), each point on it within sigma_mm (the plane's flatness). Points seen from few
// views at low contrast (an object's bottom corners, where a dark face meets a dark table) then gain
// the other points' evidence of the plane's height.
struct BaPlane {
  Vec3d normal = Vec3d::UnitZ();  // unit
  double offset = 0;
  double offset_prior_mm = 0.5;
  double sigma_mm = 0.05;
  std::vector<int> points;
};

struct BundleAdjustmentOptions {
  bool refine_poses = false;       // each pose then gets a prior (the calibrated chain is known to within these)
  double pose_prior_mm = 0.5;
  double pose_prior_deg = 0.05;
  // > 0: the mounts' shifts (BaView::mount) are estimated, each with this prior (the rail's repeatability).
  double mount_prior_mm = 0;
  bool refine_intrinsics = false;  // per intrinsics group: fx, fy, cx, cy, k1, k2 (prior 1% / 2 px / 0.05)
  double huber_sigmas = 3.0;       // robust loss: quadratic up to this many sigmas
  int max_iterations = 50;
  Status Check() const;
};

struct BundleAdjustmentSummary {
  double initial_rms_px = 0;  // point reprojection RMS before
  double final_rms_px = 0;    // and after
  std::vector<double> point_rms_px;  // per point, after
  std::vector<double> mount_shift_mm;  // per mount index (0 for an index no view uses), when estimated
  std::vector<double> plane_offset;    // per plane, estimated
  int iterations = 0;
  bool converged = false;
  std::string message;
};

// Refines `points` (and the views when asked: poses, intrinsics, mount shifts folded into cam_from_world)
// in place, with `planes` constraining the points they list. InvalidArgument for indices out of range,
// non-finite input, a plane without a unit normal or positive sigma, or a point behind a camera that
// observes it.
Result<BundleAdjustmentSummary> BundleAdjust(std::vector<Vec3d>* points,
                                             std::vector<BaView>* views,
                                             const std::vector<BaPointObservation>& point_observations,
                                             const std::vector<BaLineObservation>& line_observations,
                                             const BundleAdjustmentOptions& options = {},
                                             const std::vector<BaPlane>& planes = {});

}  // namespace idi::optim
