#include "shared/reconstruction/view_features.h"

namespace idi {

double SegmentFraction(const ViewLine& line, const Vec2d& p) {
  const Vec2d d = line.end2 - line.end1;
  const double len2 = d.squaredNorm();
  if (len2 <= 0) {
    return 0;
  }
  return (p - line.end1).dot(d) / len2;
}

bool WithinExtendedSegment(const ViewLine& line, const Vec2d& p, double margin_px) {
  const Vec2d d = line.end2 - line.end1;
  const double len = d.norm();
  if (len <= 0) {
    return (p - line.end1).norm() <= line.extension_px + margin_px;
  }
  const double s = (p - line.end1).dot(d / len);
  return s >= -(line.extension_px + margin_px) && s <= len + line.extension_px + margin_px;
}

}  // namespace idi
