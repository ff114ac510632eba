// Grasp planning for the Barrett BH8 hand from a reconstructed model (§8.11).
//
// The dissertation uses a curvature-aided silhouette method for flat objects and the topmost layer of
// points for solid ones. Here both become one criterion with a sound physical basis: the hand comes
// from above, the silhouette at grasp height is the convex hull of the model's points, and each finger
// pushes along its closing direction, which must lie inside the friction cone of the contact normal
// (no slip; with the contacts opposing each other this is force closure). Two hand shapes are tried:
// two-on-one (spread 0: the thumb, finger 3, on one silhouette edge and fingers 1 and 2 side by side
// opposite, the antipodal grasp of parallel faces) and the tripod (spread 60 deg: three fingers 120 deg
// apart closing on the centroid, for round and three-sided objects). A wall seen from one side only (a
// bracket's leg whose inner face was not reconstructed: the section at contact height is a line) is
// gripped across its thickness, thumb on the seen face, fingers 1 and 2 on the side of the rest of the
// object. Among feasible grasps the planner
// prefers a large friction margin, a grasp centre close to the centroid (little torque when lifting)
// and a small aperture.
#pragma once

#include <cmath>
#include <optional>
#include <utility>
#include <vector>

#include "shared/geometry/rigid3.h"
#include "shared/util/status.h"

namespace idi {

struct BarrettHandGeometry {
  double max_aperture_mm = 190.0;   // widest object the fingers can close on
  double min_aperture_mm = 10.0;
  double finger_spacing_mm = 50.0;  // fingers 1 and 2 side by side at spread 0 (palm offsets +/-25 mm)
  double finger_width_mm = 20.0;
  double finger_reach_mm = 110.0;   // palm to fingertip contact depth when closed around an object
  double palm_to_flange_mm = 120.0; // the hand's palm centre along the flange's z axis
};

struct GraspOptions {
  BarrettHandGeometry hand;
  double friction = 0.4;            // Coulomb coefficient at the fingertips
  double top_layer_mm = 8.0;        // points within this of the top form the top layer
  double grasp_depth_mm = 25.0;     // contacts this far below the top (less on thin objects)
  double table_clearance_mm = 8.0;  // fingertips stay this far above the table
  double approach_mm = 120.0;       // approach from this far above the grasp
  double lift_mm = 150.0;
  // Every value finite (a NaN compares false, and a NaN clearance turned the table checks off), the
  // clearance not negative.
  bool Check() const {
    const double all[] = {friction,
                          top_layer_mm,
                          grasp_depth_mm,
                          table_clearance_mm,
                          approach_mm,
                          lift_mm,
                          hand.max_aperture_mm,
                          hand.min_aperture_mm,
                          hand.finger_spacing_mm,
                          hand.finger_width_mm,
                          hand.finger_reach_mm,
                          hand.palm_to_flange_mm};
    for (const double v : all) {
      if (!std::isfinite(v)) return false;
    }
    return friction > 0 && top_layer_mm >= 0 && grasp_depth_mm > 0 && table_clearance_mm >= 0 && approach_mm > 0 &&
           lift_mm > 0 && hand.max_aperture_mm > hand.min_aperture_mm;
  }
};

struct GraspPlan {
  // The hand frame in the world (the model's frame): origin at the palm-centre line at contact height,
  // z pointing down (approach direction), x along the grasp axis from the thumb to fingers 1-2.
  Rigid3d world_from_grasp;
  Rigid3d world_from_approach;  // the same, approach_mm higher
  Rigid3d world_from_lift;      // the same, lift_mm higher
  double width_mm = 0;          // distance between the contact faces
  double spread_rad = 0;        // Barrett spread for this grasp (0: two fingers opposite the thumb)
  Vec3d thumb_contact = Vec3d::Zero();
  Vec3d finger_contact = Vec3d::Zero();  // midpoint of fingers 1 and 2
  double friction_margin_rad = 0;        // how far inside the friction cones the contact normals are
  double centroid_offset_mm = 0;         // grasp axis distance from the silhouette centroid
  double quality = 0;                    // higher is better
  int candidates_considered = 0;
};

// Plans a top grasp on an object given its model points (world frame, mm; z up, the table at
// table_z_mm) and, when known, its edges (index pairs into `points`): with edges the silhouette is the
// model's cross-section at each candidate contact height and leaning walls count against friction; a
// height whose section the edges and points above do not outline gets no fingers.
// NotFound when no antipodal grasp fits the hand; InvalidArgument on bad input.
Result<GraspPlan> PlanTopGrasp(const std::vector<Vec3d>& points, double table_z_mm, const GraspOptions& options = {},
                               const std::vector<std::pair<int, int>>& edges = {});

// The feasible grasps, best first, at most max_plans of them, each distinct (not the same grasp found
// at another height or from another hull edge): for a robot that cannot reach the best one. The same
// errors as PlanTopGrasp; InvalidArgument for max_plans < 1.
Result<std::vector<GraspPlan>> PlanTopGrasps(const std::vector<Vec3d>& points,
                                             double table_z_mm,
                                             const GraspOptions& options,
                                             const std::vector<std::pair<int, int>>& edges,
                                             int max_plans);

// The convex hull (counter-clockwise) of 2D points; exposed for tests and the twin's contact check.
std::vector<Vec2d> ConvexHull2d(std::vector<Vec2d> points);

}  // namespace idi
