// Point-in-polygon on the ground plane, shared by the track model (footprint tests), the synthetic
// observations and the planner (how much of a path stays in view).
#pragma once

#include <vector>

#include "shared/geometry/rigid3.h"

namespace idi::rmp {

// True when p lies inside the polygon by the even-odd rule: a ray from p towards +x crosses its
// outline an odd number of times. A polygon of fewer than three vertices contains nothing.
inline bool PointInPolygon(const std::vector<Vec2d>& polygon, const Vec2d& p) {
  if (polygon.size() < 3) return false;
  bool inside = false;
  for (std::size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
    const Vec2d& a = polygon[i];
    const Vec2d& b = polygon[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) && p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      inside = !inside;
    }
  }
  return inside;
}

}  // namespace idi::rmp
