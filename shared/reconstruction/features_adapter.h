// Converts the features module's result (EMPL lines, IDI points with topology) into the reconstruction's
// ViewFeatures. Both use undistorted pixel coordinates when the detector was given the camera.
#pragma once

#include "shared/features/features.h"
#include "shared/reconstruction/view_features.h"

namespace idi {

struct AdaptedFeatures {
  ViewFeatures features;
  std::vector<double> line_sigma_px;  // per line: standard deviation of its offset (for bundle adjustment)
};

AdaptedFeatures FromFeatureResult(const FeatureResult& result);

}  // namespace idi
