// Maps between image pixels and the coordinates lines are fitted in: the same pixels without a
// camera, undistorted pixels (same K) with a camera that has lens distortion.
#pragma once

#include <opencv2/core.hpp>
#include <optional>

#include "shared/camera/pinhole.h"
#include "shared/features/fast_math.h"

namespace idi {

class PixelGeometry {
 public:
  PixelGeometry() = default;
  // Precomputes the undistortion of every pixel (a one-time cost per detector).
  explicit PixelGeometry(const CameraModel& camera);

  bool identity() const { return !camera_.has_value(); }
  // False when the distortion could not be inverted at some pixel (a model no lens has).
  bool valid() const { return valid_; }

  // Fit coordinates of an integer pixel.
  Vec2d ToFit(int x, int y) const {
    if (!camera_) {
      return Vec2d(x, y);
    }
    const cv::Vec2f& v = map_.at<cv::Vec2f>(y, x);
    return Vec2d(v[0], v[1]);
  }
  // Fit coordinates of a sub-pixel image position (bilinear in the precomputed map).
  Vec2d ToFit(const Vec2d& pixel) const;
  // Image position of a point given in fit coordinates.
  Vec2d ToPixel(const Vec2d& fit) const { return camera_ ? Distorted(fit) : fit; }

 private:
  Vec2d Distorted(const Vec2d& fit) const;
  std::optional<CameraModel> camera_;
  cv::Mat map_;  // CV_32FC2, undistorted coordinates of each pixel
  bool valid_ = true;
};

}  // namespace idi
