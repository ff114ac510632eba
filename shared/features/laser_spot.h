// The laser spot (§6.4.3): the bright spot of the laser pointer in a short-exposure image, located
// to sub-pixel precision by its background-subtracted intensity centroid. Images with no spot,
// several spots or a saturated bloom are reported as such, never as a wrong position.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "shared/util/status.h"

namespace idi {

enum class LaserSpotStatus {
  kFound,     // exactly one spot: spots[0]
  kNoSpot,    // nothing bright and compact enough
  kSeveral,   // more than one comparable spot (reflections, a second laser): spots lists them
  kSaturated, // the brightest spot is a saturated bloom: its centroid is given but not trustworthy
};
const char* LaserSpotStatusName(LaserSpotStatus status);

struct LaserSpotOptions {
  // A spot's peak must exceed the background by this much (8-bit grey levels, scaled for 16-bit)
  // and by noise_sigmas times the estimated image noise.
  double min_peak_above_background = 30;
  double noise_sigmas = 8;
  // Pixels brighter than background + fraction * (peak - background) form the spot's centroid.
  double centroid_fraction = 0.1;
  int max_area_px = 1500;       // larger bright regions are not a spot
  int max_saturated_px = 9;     // more saturated pixels than this make a bloom
  double saturation_level = 0;  // 0: 255 for 8-bit, 65535 for 16-bit, 1 for float
  // A second spot whose peak reaches this fraction of the brightest makes the image ambiguous.
  double second_spot_ratio = 0.5;

  Status Check() const;
};

struct LaserSpot {
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();  // pixel coordinates (centres at integers)
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
  double peak = 0;        // brightest pixel above background
  double total = 0;       // summed intensity above background
  int area_px = 0;
  int saturated_px = 0;
};

struct LaserSpotResult {
  LaserSpotStatus status = LaserSpotStatus::kNoSpot;
  std::vector<LaserSpot> spots;  // brightest first
  double background = 0;
  double noise_sigma = 0;
  std::string message;
};

// InvalidArgument for empty, colour or unsupported images; otherwise a result with its status.
Result<LaserSpotResult> FindLaserSpot(const cv::Mat& image, const LaserSpotOptions& options = {});

}  // namespace idi
