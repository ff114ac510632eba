// Curves (§7.9.1): active contours ("snakes", Kass-Witkin-Terzopoulos, minimised greedily) on the
// edge chains that no EMPL line explains, and IDI points where a curve meets a line (§7.10).
#pragma once

#include <vector>

#include "shared/features/features.h"
#include "shared/features/gradient.h"
#include "shared/features/pixel_geometry.h"

namespace idi {

// Snake control points initialised along an ordered chain of pixel positions, then moved to
// minimise continuity + curvature - gradient-magnitude energy; finally each point is put on the
// sub-pixel gradient peak along its normal. Points are in pixel coordinates.
std::vector<Eigen::Vector2d> FitActiveContour(const GradientImages& g, const std::vector<Eigen::Vector2d>& chain,
                                              const CurveOptions& options);

// Curves from the edge pixels left in `edges` after the Hough transform, minus those near `lines`.
// Output points are in fit coordinates (undistorted when the geometry has distortion). `work` is a
// scratch mask kept by the caller between frames.
std::vector<Curve> FindCurves(const GradientImages& g, const EdgeMap& edges, const PixelGeometry& geometry,
                              const std::vector<EmplLine>& lines, const CurveOptions& options, cv::Mat* work);

// Adds IDI points where a curve crosses a line's segment (or its extension) or ends on it; sets
// the curves' and lines' point_ids.
void AddCurveLinePoints(const IdiOptions& options, std::vector<Curve>* curves, std::vector<EmplLine>* lines,
                        std::vector<IdiPoint>* points);

}  // namespace idi
