#include "shared/features/laser_spot.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace idi {

const char* LaserSpotStatusName(LaserSpotStatus status) {
  switch (status) {
    case LaserSpotStatus::kFound:
      return "found";
    case LaserSpotStatus::kNoSpot:
      return "no_spot";
    case LaserSpotStatus::kSeveral:
      return "several_spots";
    case LaserSpotStatus::kSaturated:
      return "saturated";
  }
  return "unknown";
}

Status LaserSpotOptions::Check() const {
  if (!(min_peak_above_background >= 0) || !(noise_sigmas >= 0)) {
    return InvalidArgument("laser spot: min_peak_above_background and noise_sigmas must be >= 0");
  }
  if (!(centroid_fraction >= 0 && centroid_fraction < 1)) {
    return InvalidArgument("laser spot: centroid_fraction must be in [0, 1)");
  }
  if (max_area_px < 1 || max_saturated_px < 0) {
    return InvalidArgument("laser spot: max_area_px must be >= 1 and max_saturated_px >= 0");
  }
  if (!(saturation_level >= 0) || !(second_spot_ratio > 0 && second_spot_ratio <= 1)) {
    return InvalidArgument("laser spot: saturation_level must be >= 0 and second_spot_ratio in (0, 1]");
  }
  return Status::Ok();
}

Result<LaserSpotResult> FindLaserSpot(const cv::Mat& image, const LaserSpotOptions& o) {
  IDI_RETURN_IF_ERROR(o.Check());
  if (image.empty()) {
    return InvalidArgument("laser spot: image is empty");
  }
  if (image.channels() != 1) {
    return InvalidArgument("laser spot: expected a single-channel (grey) image, got " +
                           std::to_string(image.channels()) + " channels");
  }
  const int depth = image.depth();
  if (depth != CV_8U && depth != CV_16U && depth != CV_32F) {
    return InvalidArgument("laser spot: unsupported pixel type; expected 8-bit, 16-bit or float grey");
  }
  if (image.cols < 3 || image.rows < 3) {
    return InvalidArgument("laser spot: image smaller than 3 x 3 px");
  }
  cv::Mat f;
  image.convertTo(f, CV_32F);
  if (depth == CV_32F && !cv::checkRange(f)) {
    return InvalidArgument("laser spot: float image contains NaN or infinite values");
  }
  const double scale = depth == CV_16U ? 257.0 : (depth == CV_32F ? 1.0 / 255.0 : 1.0);
  const double saturation =
      o.saturation_level > 0 ? o.saturation_level : (depth == CV_16U ? 65535.0 : (depth == CV_32F ? 1.0 : 255.0));
  // Background and noise from a subsample: median and MAD.
  std::vector<float> sample;
  sample.reserve(static_cast<std::size_t>(f.total() / 4 + 1));
  for (int y = 0; y < f.rows; y += 2) {
    const float* r = f.ptr<float>(y);
    for (int x = 0; x < f.cols; x += 2) {
      sample.push_back(r[x]);
    }
  }
  auto mid = sample.begin() + static_cast<std::ptrdiff_t>(sample.size() / 2);
  std::nth_element(sample.begin(), mid, sample.end());
  const double background = *mid;
  for (float& v : sample) {
    v = std::fabs(v - static_cast<float>(background));
  }
  std::nth_element(sample.begin(), mid, sample.end());
  const double noise = std::max(1.4826 * *mid, 0.3 * scale);
  LaserSpotResult result;
  result.background = background;
  result.noise_sigma = noise;
  const double detect = background + std::max(o.min_peak_above_background * scale, o.noise_sigmas * noise);
  cv::Mat bright = f > detect;
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(bright, labels, stats, centroids, 8, CV_32S);
  std::vector<LaserSpot> spots;
  bool rejected_large = false;
  for (int k = 1; k < n; ++k) {
    const int x0 = stats.at<int>(k, cv::CC_STAT_LEFT), y0 = stats.at<int>(k, cv::CC_STAT_TOP);
    const int bw = stats.at<int>(k, cv::CC_STAT_WIDTH), bh = stats.at<int>(k, cv::CC_STAT_HEIGHT);
    const int area = stats.at<int>(k, cv::CC_STAT_AREA);
    double peak = 0;
    int saturated = 0;
    for (int y = y0; y < y0 + bh; ++y) {
      for (int x = x0; x < x0 + bw; ++x) {
        if (labels.at<int>(y, x) == k) {
          const double v = f.at<float>(y, x);
          peak = std::max(peak, v);
          saturated += v >= saturation ? 1 : 0;
        }
      }
    }
    if (area > o.max_area_px && saturated <= o.max_saturated_px) {
      rejected_large = true;
      continue;
    }
    // Centroid over a window around the component, weights above a fraction of the peak.
    const double cut = background + std::max(3.0 * noise, o.centroid_fraction * (peak - background));
    const int m = 3;
    double sw = 0, sx = 0, sy = 0;
    int used = 0;
    for (int y = std::max(0, y0 - m); y < std::min(f.rows, y0 + bh + m); ++y) {
      for (int x = std::max(0, x0 - m); x < std::min(f.cols, x0 + bw + m); ++x) {
        const double v = f.at<float>(y, x);
        const int label = labels.at<int>(y, x);
        if (v > cut && (label == k || label == 0)) {
          const double w = v - background;
          sw += w;
          sx += w * x;
          sy += w * y;
          ++used;
        }
      }
    }
    if (sw <= 0) {
      continue;
    }
    LaserSpot s;
    s.xy = Eigen::Vector2d(sx / sw, sy / sw);
    double vxx = 0, vyy = 0;
    for (int y = std::max(0, y0 - m); y < std::min(f.rows, y0 + bh + m); ++y) {
      for (int x = std::max(0, x0 - m); x < std::min(f.cols, x0 + bw + m); ++x) {
        const double v = f.at<float>(y, x);
        const int label = labels.at<int>(y, x);
        if (v > cut && (label == k || label == 0)) {
          vxx += (x - s.xy.x()) * (x - s.xy.x());
          vyy += (y - s.xy.y()) * (y - s.xy.y());
        }
      }
    }
    // Noise on each weight moves the centroid by (x - xc) * noise / sum(w).
    const double nv = noise * noise / (sw * sw);
    s.covariance << vxx * nv, 0, 0, vyy * nv;
    s.peak = peak - background;
    s.total = sw;
    s.area_px = used;
    s.saturated_px = saturated;
    spots.push_back(s);
  }
  std::sort(spots.begin(), spots.end(), [](const LaserSpot& a, const LaserSpot& b) { return a.total > b.total; });
  result.spots = spots;
  if (spots.empty()) {
    result.status = rejected_large ? LaserSpotStatus::kNoSpot : LaserSpotStatus::kNoSpot;
    result.message = rejected_large ? "bright regions found but none small enough to be a laser spot"
                                    : "no pixel brighter than the detection threshold";
    return result;
  }
  const LaserSpot& best = spots.front();
  int comparable = 0;
  for (const LaserSpot& s : spots) {
    comparable += s.peak >= o.second_spot_ratio * best.peak ? 1 : 0;
  }
  if (best.saturated_px > o.max_saturated_px) {
    result.status = LaserSpotStatus::kSaturated;
    result.message = std::to_string(best.saturated_px) + " saturated pixels: the spot is a bloom; shorten the exposure";
  } else if (comparable > 1) {
    result.status = LaserSpotStatus::kSeveral;
    result.message = std::to_string(comparable) + " comparable bright spots";
  } else {
    result.status = LaserSpotStatus::kFound;
    result.message = "one spot";
  }
  return result;
}

}  // namespace idi
