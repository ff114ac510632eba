// What the reconstruction needs from one image: EMPL lines and IDI points with their topology
// (§8.8.1), in undistorted pixel coordinates of that view. The features module's results convert to
// this (features_adapter.h); tests build it from projected wireframes.
#pragma once

#include <vector>

#include "shared/geometry/lines.h"

namespace idi {

struct ViewLine {
  Line2d line;                 // normal . x = offset, undistorted pixels
  Vec2d end1 = Vec2d::Zero();  // confirmed segment ends (§8.8.2)
  Vec2d end2 = Vec2d::Zero();
  double extension_px = 0;     // unconfirmed extension allowed beyond each confirmed end
  std::vector<int> points;     // IDI points on this line (indices into ViewFeatures::points)
};

struct ViewPoint {
  Vec2d xy = Vec2d::Zero();  // undistorted pixels
  double sigma_px = 0.1;     // position uncertainty (largest axis of the covariance), px
  std::vector<int> lines;    // lines through this point (indices into ViewFeatures::lines)
};

struct ViewFeatures {
  std::vector<ViewLine> lines;
  std::vector<ViewPoint> points;
};

// Where `p` falls along the segment end1->end2 as a fraction (0 at end1, 1 at end2).
double SegmentFraction(const ViewLine& line, const Vec2d& p);
// True when p, projected onto the line, lies within the confirmed segment extended by `extension_px`
// plus `margin_px` at both ends.
bool WithinExtendedSegment(const ViewLine& line, const Vec2d& p, double margin_px);

}  // namespace idi
