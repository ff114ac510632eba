#include "shared/grasp/grasp_planner.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "shared/util/units.h"

namespace idi {
namespace {

double Cross2(const Vec2d& a, const Vec2d& b) { return a.x() * b.y() - a.y() * b.x(); }

struct HullHit {
  Vec2d point;
  Vec2d normal;  // outward normal of the edge hit
  double t = 0;  // parameter along the ray
};

// Where the line origin + t dir leaves the convex polygon (largest t), with that edge's outward normal.
std::optional<HullHit> ExitPoint(const std::vector<Vec2d>& hull, const Vec2d& origin, const Vec2d& dir) {
  std::optional<HullHit> best;
  const std::size_t n = hull.size();
  for (std::size_t i = 0; i < n; ++i) {
    const Vec2d a = hull[i], b = hull[(i + 1) % n];
    const Vec2d e = b - a;
    const double denom = Cross2(dir, e);
    if (std::abs(denom) < 1e-12) continue;
    const double t = Cross2(a - origin, e) / denom;
    const double u = Cross2(a - origin, dir) / denom;
    if (u < -1e-9 || u > 1 + 1e-9) continue;
    if (!best || t > best->t) {
      const Vec2d te = e.normalized();
      best = HullHit{origin + t * dir, Vec2d(te.y(), -te.x()), t};
    }
  }
  return best;
}

double AngleBetween(const Vec2d& a, const Vec2d& b) { return std::acos(std::clamp(a.dot(b), -1.0, 1.0)); }

// A candidate grasp in the plane: contacts, their outward normals and the direction each finger pushes.
struct PlanarGrasp {
  std::vector<Vec2d> contacts, normals, pushes;  // contact 0 is the thumb (finger 3)
  double spread_rad = 0;
  double width_mm = 0;
  Vec2d axis = Vec2d::UnitX();  // hand x axis (thumb towards fingers 1-2)
  Vec2d centre = Vec2d::Zero();
};

// No-slip margin: every finger's push must lie inside the friction cone about the inward normal.
double FrictionMargin(const PlanarGrasp& g, double cone) {
  double margin = cone;
  for (std::size_t k = 0; k < g.contacts.size(); ++k) {
    margin = std::min(margin, cone - AngleBetween(g.pushes[k], -g.normals[k]));
  }
  return margin;
}

}  // namespace

std::vector<Vec2d> ConvexHull2d(std::vector<Vec2d> p) {
  std::sort(p.begin(), p.end(), [](const Vec2d& a, const Vec2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  p.erase(std::unique(p.begin(), p.end(), [](const Vec2d& a, const Vec2d& b) { return (a - b).norm() < 1e-9; }),
          p.end());
  if (p.size() < 3) return p;
  std::vector<Vec2d> hull(2 * p.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {  // lower hull (Andrew's monotone chain)
    while (k >= 2 && Cross2(hull[k - 1] - hull[k - 2], p[i] - hull[k - 2]) <= 0) --k;
    hull[k++] = p[i];
  }
  for (std::size_t i = p.size() - 1, t = k + 1; i > 0; --i) {  // upper hull
    while (k >= t && Cross2(hull[k - 1] - hull[k - 2], p[i - 1] - hull[k - 2]) <= 0) --k;
    hull[k++] = p[i - 1];
  }
  hull.resize(k - 1);
  return hull;
}

namespace {

Vec2d HullCentroid(const std::vector<Vec2d>& hull) {
  Vec2d centroid = Vec2d::Zero();
  double area = 0;
  for (std::size_t i = 0; i < hull.size(); ++i) {
    const Vec2d& a = hull[i];
    const Vec2d& b = hull[(i + 1) % hull.size()];
    const double c = Cross2(a, b);
    area += c;
    centroid += (a + b) * c;
  }
  return std::abs(area) > 1e-9 ? Vec2d(centroid / (3.0 * area)) : hull.front();
}

// The model's cross-section at height z: where its edges cross the plane, and the points above it (less
// `tol_mm`) seen from above - an object standing on the table does not overhang, so every point above
// lies over its cross-section; a missing edge then makes the section smaller, never larger. Convex
// hull; empty when fewer than three points.
//
// A wall: when the edges crossing the plane and the points above it all lie on one line (at least two
// crossings, spanning `min_wall_mm`), the section is a single face seen from one side - the standing
// leg of a bracket whose inner face was not reconstructed. Its thickness is unknown, and the object
// need not be convex (the leg rises from one end of its foot), so the section is not guessed: `wall`
// gets the face's two ends and the hull is empty.
struct Wall {
  Vec2d a = Vec2d::Zero(), b = Vec2d::Zero();
};

std::vector<Vec2d> CrossSection(const std::vector<Vec3d>& points,
                                const std::vector<std::pair<int, int>>& edges,
                                double z,
                                double tol_mm,
                                std::optional<Wall>* wall = nullptr,
                                double min_wall_mm = 0.0,
                                bool* inner_estimate = nullptr) {
  if (inner_estimate != nullptr) *inner_estimate = false;
  std::vector<Vec2d> xy;
  int crossings = 0;
  for (const auto& [i, j] : edges) {
    const Vec3d& a = points[static_cast<std::size_t>(i)];
    const Vec3d& b = points[static_cast<std::size_t>(j)];
    if ((a.z() - z) * (b.z() - z) < 0) {
      const double t = (z - a.z()) / (b.z() - a.z());
      xy.push_back((a + t * (b - a)).head<2>());
      ++crossings;
    }
  }
  for (const Vec3d& p : points) {
    if (p.z() >= z - tol_mm) xy.push_back(p.head<2>());
  }
  auto area = [](const std::vector<Vec2d>& h) {
    double a = 0;
    for (std::size_t i = 0; i < h.size(); ++i) a += Cross2(h[i], h[(i + 1) % h.size()]);
    return 0.5 * a;
  };
  std::vector<Vec2d> hull = xy.size() >= 3 ? ConvexHull2d(xy) : std::vector<Vec2d>{};
  if (hull.size() >= 3 && area(hull) > 100.0) return hull;
  if (wall != nullptr) wall->reset();
  if (crossings >= 2) {
    // The two points furthest apart, and every point within 2 mm of the line through them.
    Vec2d a = xy[0], b = xy[0];
    double longest = 0;
    for (const Vec2d& p : xy) {
      for (const Vec2d& q : xy) {
        if ((p - q).norm() > longest) {
          longest = (p - q).norm();
          a = p;
          b = q;
        }
      }
    }
    const Vec2d u = longest > 0 ? Vec2d((b - a) / longest) : Vec2d::UnitX();
    const bool on_line = std::all_of(xy.begin(), xy.end(), [&](const Vec2d& p) { return std::abs(Cross2(u, p - a)) < 2.0; });
    if (on_line && longest >= min_wall_mm) {
      if (wall != nullptr) *wall = Wall{a, b};
      return {};
    }
  }
  // Too few edges seen to outline the section (e.g. a prism whose sloped edges were not confirmed):
  // for a convex object every segment between two of its points lies inside it, so where the segments
  // between points below and above cross the plane is inside the section (an inner estimate again).
  // Its sides are not the object's faces - and an object need not be convex: across a bracket's L these
  // segments span the open side - so it serves the walls' lean above and below a contact, and
  // `inner_estimate` tells the planner to put no finger on it.
  if (inner_estimate != nullptr) *inner_estimate = true;
  for (const Vec3d& a : points) {
    for (const Vec3d& b : points) {
      if (a.z() < z - tol_mm && b.z() > z + tol_mm) {
        const double t = (z - a.z()) / (b.z() - a.z());
        xy.push_back((a + t * (b - a)).head<2>());
      }
    }
  }
  if (xy.size() < 3) return {};
  return ConvexHull2d(xy);
}

// Candidate grasps on one silhouette (two-on-one on each edge, tripods about the centroid).
std::vector<PlanarGrasp> Candidates(const std::vector<Vec2d>& hull, const Vec2d& centroid, const GraspOptions& o) {
  const double half_spacing = 0.5 * o.hand.finger_spacing_mm;
  const double pad_offset = std::max(0.0, half_spacing - 0.25 * o.hand.finger_width_mm);
  std::vector<PlanarGrasp> candidates;
  // Two-on-one (spread 0): the thumb on a silhouette edge, pushing along its inward normal; fingers 1
  // and 2, half the finger spacing either side, push back from the far side.
  const std::size_t n = hull.size();
  for (std::size_t i = 0; i < n; ++i) {
    const Vec2d a0 = hull[i], a1 = hull[(i + 1) % n];
    const double len = (a1 - a0).norm();
    if (len < o.hand.finger_width_mm) continue;
    const Vec2d side = (a1 - a0) / len;
    const Vec2d na(side.y(), -side.x());
    const Vec2d axis = -na;
    const double margin_along = 0.5 * o.hand.finger_width_mm;
    const double s = std::clamp((centroid - a0).dot(side), margin_along, len - margin_along);
    PlanarGrasp g;
    g.axis = axis;
    g.contacts.push_back(a0 + s * side);
    g.normals.push_back(na);
    g.pushes.push_back(axis);
    bool ok = true;
    // Each finger's pad is finger_width wide about its offset, and the fingers touch with any part of
    // it: the ray through the pad's inner half must meet the far side. A bracket's leg as wide as the
    // finger spacing (50 mm) then still takes fingers 1 and 2, whose centres fall on its two end edges,
    // where the ray through the pad's centre grazes a corner or misses.
    for (const double off : {-pad_offset, pad_offset}) {
      const auto hit = ExitPoint(hull, g.contacts[0] + off * side, axis);
      if (!hit || hit->t <= 0) {
        ok = false;
        break;
      }
      g.contacts.push_back(hit->point);
      g.normals.push_back(hit->normal);
      g.pushes.push_back(-axis);
      g.width_mm = std::max(g.width_mm, hit->t);
    }
    if (!ok) continue;
    g.centre = g.contacts[0] + 0.5 * g.width_mm * axis;
    g.spread_rad = 0;
    candidates.push_back(g);
  }
  // Tripod (spread 60 degrees: the three fingers 120 degrees apart) closing on the centroid: suits
  // round and three-sided objects.
  for (int step = 0; step < 24; ++step) {
    const double phi = 2.0 * kPi / 3.0 * step / 24.0;
    PlanarGrasp g;
    g.spread_rad = kPi / 3.0;
    g.centre = centroid;
    bool ok = true;
    for (int k = 0; k < 3; ++k) {
      const double ang = phi + 2.0 * kPi / 3.0 * k;
      const Vec2d dir(std::cos(ang), std::sin(ang));
      const auto hit = ExitPoint(hull, centroid, dir);
      if (!hit || hit->t <= 0) {
        ok = false;
        break;
      }
      g.contacts.push_back(hit->point);
      g.normals.push_back(hit->normal);
      g.pushes.push_back(-dir);
      g.width_mm = std::max(g.width_mm, 2.0 * hit->t);
    }
    if (!ok) continue;
    const Vec2d thumb_dir = (g.contacts[0] - centroid).normalized();
    g.axis = -thumb_dir;
    candidates.push_back(g);
  }
  return candidates;
}

// Two-on-one across a wall seen from one side: the thumb on the seen face pushing through it towards
// the rest of the object (where the wall's thickness must lie), fingers 1 and 2 half the finger spacing
// either side of it on the far face, pushing back; both faces parallel (a plate). The far face is put
// at the nearest model point behind the seen face (the foot's corner where the inner face meets it),
// else at the hand's smallest aperture: the fingers close until they meet it, so the width only sets
// how deep the palm goes. Empty when the face is too short for the fingers or nothing says which side
// the wall's thickness is on.
std::optional<PlanarGrasp> WallGrasp(const Wall& wall, const std::vector<Vec3d>& points, const Vec2d& object_centroid,
                                     const GraspOptions& o) {
  const double len = (wall.b - wall.a).norm();
  const double half_spacing = 0.5 * o.hand.finger_spacing_mm;
  const double end_margin = 0.25 * o.hand.finger_width_mm;
  if (len < 2.0 * (half_spacing + end_margin)) return std::nullopt;
  const Vec2d side = (wall.b - wall.a) / len;
  Vec2d inward(-side.y(), side.x());
  const double towards = inward.dot(object_centroid - wall.a);
  if (std::abs(towards) < 5.0) return std::nullopt;
  if (towards < 0) inward = -inward;
  double thickness = o.hand.min_aperture_mm;
  double nearest = 1e300;
  for (const Vec3d& p : points) {
    const Vec2d q = p.head<2>() - wall.a;
    const double along = q.dot(side), depth = q.dot(inward);
    if (along >= -5.0 && along <= len + 5.0 && depth >= 2.0 && depth < nearest) nearest = depth;
  }
  if (nearest <= 40.0) thickness = std::max(thickness, nearest);
  const double s = std::clamp((object_centroid - wall.a).dot(side), half_spacing + end_margin, len - half_spacing - end_margin);
  PlanarGrasp g;
  g.axis = inward;
  g.contacts.push_back(wall.a + s * side);
  g.normals.push_back(-inward);
  g.pushes.push_back(inward);
  for (const double off : {-half_spacing, half_spacing}) {
    g.contacts.push_back(wall.a + s * side + off * side + thickness * inward);
    g.normals.push_back(inward);
    g.pushes.push_back(-inward);
  }
  g.width_mm = thickness;
  g.centre = g.contacts[0] + 0.5 * thickness * inward;
  g.spread_rad = 0;
  return g;
}

// How far a wall leans at a contact: the silhouettes `dz` above and below, measured along the push from
// the contact's line. The face's normal tilts by atan(inset / rise) out of the horizontal plane.
double WallTilt(const std::vector<Vec2d>& below, const std::vector<Vec2d>& above, const Vec2d& contact, const Vec2d& push,
                double dz) {
  auto reach = [&](const std::vector<Vec2d>& hull) -> std::optional<double> {
    if (hull.size() < 3) return std::nullopt;
    // Entry distance along the push from well outside: the hull's boundary facing the finger.
    const Vec2d from = contact - 1000.0 * push;
    const auto hit = ExitPoint(hull, contact + 1000.0 * push, -push);
    if (!hit) return std::nullopt;
    return (hit->point - from).dot(push);
  };
  const auto lo = reach(below), hi = reach(above);
  if (!lo || !hi) return kPi / 2;  // the wall ends within dz: not a face to push on
  return std::atan2(std::abs(*hi - *lo), 2.0 * dz);
}

}  // namespace

Result<std::vector<GraspPlan>> PlanTopGrasps(const std::vector<Vec3d>& points,
                                             double table_z_mm,
                                             const GraspOptions& o,
                                             const std::vector<std::pair<int, int>>& edges,
                                             int max_plans) {
  if (max_plans < 1) return InvalidArgument("grasp planning: max_plans must be at least 1");
  if (!o.Check()) {
    return InvalidArgument("grasp planning: invalid options");
  }
  if (points.size() < 3) {
    return InvalidArgument("grasp planning: need at least 3 model points, got " + std::to_string(points.size()));
  }
  if (!std::isfinite(table_z_mm)) {
    // A NaN height would turn off the height and clearance checks: contacts below the table top.
    return InvalidArgument("grasp planning: the table height is not finite");
  }
  double z_top = -1e300;
  for (const Vec3d& p : points) {
    if (!p.allFinite()) return InvalidArgument("grasp planning: a model point is not finite");
    z_top = std::max(z_top, p.z());
  }
  for (const auto& [i, j] : edges) {
    if (i < 0 || j < 0 || i >= static_cast<int>(points.size()) || j >= static_cast<int>(points.size())) {
      return InvalidArgument("grasp planning: an edge names a point that does not exist");
    }
  }
  const double height = z_top - table_z_mm;
  if (height < o.table_clearance_mm + 2.0) {
    return NotFound("grasp planning: the object is only " + FormatNumber(height) + " mm high");
  }
  // Silhouette at grasp height (§8.11: the top layer's outline for a solid object). Without edges: the
  // hull of all points, right for objects with vertical walls and for flat objects. With the model's
  // edges: the true cross-section at each candidate height, so sloped faces (a prism's roof) and parts
  // that stick out lower down (a bracket's foot) are seen as they are, and the walls' lean at the
  // contacts enters the friction check.
  std::vector<Vec2d> xy;
  for (const Vec3d& p : points) xy.push_back(p.head<2>());
  const std::vector<Vec2d> all_hull = ConvexHull2d(xy);
  if (all_hull.size() < 3) {
    return NotFound("grasp planning: the silhouette is degenerate (points in a line)");
  }
  const double default_z =
      std::max(z_top - std::min(o.grasp_depth_mm, 0.5 * height), table_z_mm + o.table_clearance_mm);
  std::vector<double> heights = {default_z};
  if (!edges.empty()) {
    for (double f : {0.15, 0.3, 0.45, 0.6, 0.75}) {
      const double z = z_top - f * height;
      if (z >= table_z_mm + o.table_clearance_mm && std::abs(z - default_z) > 1.0) heights.push_back(z);
    }
  }
  const double cone = std::atan(o.friction);
  const double dz = std::max(2.0, std::min(6.0, 0.1 * height));
  const Vec2d all_centroid = HullCentroid(all_hull);

  std::vector<GraspPlan> plans;
  int considered = 0;
  const double min_wall_mm = o.hand.finger_spacing_mm + 0.5 * o.hand.finger_width_mm;
  for (const double contact_z : heights) {
    std::vector<Vec2d> hull = all_hull;
    std::vector<Vec2d> below, above;
    std::vector<PlanarGrasp> candidates;
    std::optional<Wall> wall, wall_below, wall_above;
    bool inner_estimate = false;
    if (!edges.empty()) {
      hull = CrossSection(points, edges, contact_z, 0.5, &wall, min_wall_mm, &inner_estimate);
      below = CrossSection(points, edges, contact_z - dz, 0.5, &wall_below, min_wall_mm);
      above = CrossSection(points, edges, contact_z + dz, 0.5, &wall_above, min_wall_mm);
      if (wall && wall_below && wall_above) {
        // A wall standing straight: its face at dz below and above lies on the same line.
        const Vec2d u = (wall->b - wall->a).normalized();
        const double lean = std::max(std::abs(Cross2(u, wall_below->a - wall->a)), std::abs(Cross2(u, wall_above->a - wall->a)));
        const std::optional<PlanarGrasp> g = WallGrasp(*wall, points, all_centroid, o);
        if (g && std::atan2(lean, dz) < cone) candidates.push_back(*g);
      }
      if (hull.size() < 3 && candidates.empty()) continue;
    }
    if (hull.size() >= 3 && !inner_estimate) {
      const std::vector<PlanarGrasp> on_hull = Candidates(hull, HullCentroid(hull), o);
      candidates.insert(candidates.end(), on_hull.begin(), on_hull.end());
    }
    considered += static_cast<int>(candidates.size());
    for (const PlanarGrasp& g : candidates) {
      if (g.width_mm < o.hand.min_aperture_mm || g.width_mm > o.hand.max_aperture_mm) continue;
      double margin = FrictionMargin(g, cone);
      if (!edges.empty() && hull.size() >= 3) {
        for (std::size_t k = 0; k < g.contacts.size(); ++k) {
          const double tilt = WallTilt(below, above, g.contacts[k], g.pushes[k], dz);
          const double planar = AngleBetween(g.pushes[k], -g.normals[k]);
          // Angle between the horizontal push and the tilted normal (small-angle composition is exact
          // enough here: both are below the cone for a feasible grasp).
          margin = std::min(margin, cone - std::sqrt(planar * planar + tilt * tilt));
        }
      }
      if (margin <= 0) continue;
      // Torque when lifting: the hand's centre line should pass near the object's centroid.
      const double offset = (g.centre - all_centroid).norm();
      // Contacts at the default depth unless another height is clearly better: the same grasp found
      // at several heights (equal but for rounding) is taken at the default one.
      const double quality = margin / cone - offset / 50.0 - 0.2 * g.width_mm / o.hand.max_aperture_mm -
                             0.05 * std::abs(contact_z - default_z) / height;
      GraspPlan best;
      best.quality = quality;
      best.width_mm = g.width_mm;
      best.spread_rad = g.spread_rad;
      best.friction_margin_rad = margin;
      best.centroid_offset_mm = offset;
      best.thumb_contact = Vec3d(g.contacts[0].x(), g.contacts[0].y(), contact_z);
      Vec2d fingers = Vec2d::Zero();
      for (std::size_t k = 1; k < g.contacts.size(); ++k) fingers += g.contacts[k];
      fingers /= static_cast<double>(g.contacts.size() - 1);
      best.finger_contact = Vec3d(fingers.x(), fingers.y(), contact_z);
      // Hand frame: x along the grip (thumb towards fingers 1-2), z down, y = z cross x.
      const Vec3d x(g.axis.x(), g.axis.y(), 0.0);
      const Vec3d z(0, 0, -1);
      const Vec3d y = z.cross(x);
      best.world_from_grasp.rotation << x, y, z;
      best.world_from_grasp.translation = Vec3d(g.centre.x(), g.centre.y(), contact_z);
      best.world_from_approach = Translation(0.0, 0.0, o.approach_mm) * best.world_from_grasp;
      best.world_from_lift = Translation(0.0, 0.0, o.lift_mm) * best.world_from_grasp;
      plans.push_back(best);
    }
  }
  if (plans.empty()) {
    return NotFound("grasp planning: no grasp fits the hand with friction " + FormatNumber(o.friction) + " (" +
                    std::to_string(considered) + " candidates considered)");
  }
  // Best first (ties keep the order found: the default contact height first); the same grasp found at
  // several heights or from several hull edges (within 2 mm and 2 deg) is listed once.
  std::stable_sort(
      plans.begin(), plans.end(), [](const GraspPlan& a, const GraspPlan& b) { return a.quality > b.quality; });
  std::vector<GraspPlan> distinct;
  for (const GraspPlan& p : plans) {
    const bool seen = std::any_of(distinct.begin(), distinct.end(), [&](const GraspPlan& d) {
      const Vec3d dx = p.world_from_grasp.rotation.col(0), ex = d.world_from_grasp.rotation.col(0);
      return (p.world_from_grasp.translation - d.world_from_grasp.translation).norm() < 2.0 &&
             dx.dot(ex) > std::cos(2.0 * kPi / 180.0) && std::abs(p.spread_rad - d.spread_rad) < 1e-6;
    });
    if (seen) continue;
    distinct.push_back(p);
    distinct.back().candidates_considered = considered;
    if (static_cast<int>(distinct.size()) >= max_plans) break;
  }
  return distinct;
}

Result<GraspPlan> PlanTopGrasp(const std::vector<Vec3d>& points,
                               double table_z_mm,
                               const GraspOptions& o,
                               const std::vector<std::pair<int, int>>& edges) {
  IDI_ASSIGN_OR_RETURN(std::vector<GraspPlan> plans, PlanTopGrasps(points, table_z_mm, o, edges, 1));
  return plans.front();
}

}  // namespace idi
