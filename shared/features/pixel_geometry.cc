#include "shared/features/pixel_geometry.h"

#include <algorithm>
#include <cmath>

namespace idi {

PixelGeometry::PixelGeometry(const CameraModel& camera) {
  if (!camera.HasDistortion()) {
    return;
  }
  camera_ = camera;
  map_.create(camera.height, camera.width, CV_32FC2);
  for (int y = 0; y < camera.height; ++y) {
    cv::Vec2f* row = map_.ptr<cv::Vec2f>(y);
    for (int x = 0; x < camera.width; ++x) {
      const Vec2d u = UndistortPixel(camera, Vec2d(x, y));
      // The round trip must come back to the pixel, or the model is not invertible here.
      const Vec2d back = Distorted(u);
      if (!u.allFinite() || !back.allFinite() || (back - Vec2d(x, y)).norm() > 0.01 ||
          std::fabs(u.x()) > 1e6 || std::fabs(u.y()) > 1e6) {
        valid_ = false;
        row[x] = cv::Vec2f(static_cast<float>(x), static_cast<float>(y));
        continue;
      }
      row[x] = cv::Vec2f(static_cast<float>(u.x()), static_cast<float>(u.y()));
    }
  }
}

Vec2d PixelGeometry::ToFit(const Vec2d& pixel) const {
  if (!camera_) {
    return pixel;
  }
  const double fx = std::clamp(pixel.x(), 0.0, static_cast<double>(map_.cols - 1) - 1e-9);
  const double fy = std::clamp(pixel.y(), 0.0, static_cast<double>(map_.rows - 1) - 1e-9);
  const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
  const int x1 = std::min(x0 + 1, map_.cols - 1), y1 = std::min(y0 + 1, map_.rows - 1);
  const double ax = fx - x0, ay = fy - y0;
  const cv::Vec2f& a = map_.at<cv::Vec2f>(y0, x0);
  const cv::Vec2f& b = map_.at<cv::Vec2f>(y0, x1);
  const cv::Vec2f& c = map_.at<cv::Vec2f>(y1, x0);
  const cv::Vec2f& d = map_.at<cv::Vec2f>(y1, x1);
  Vec2d out;
  for (int i = 0; i < 2; ++i) {
    out[i] = (1 - ay) * ((1 - ax) * a[i] + ax * b[i]) + ay * ((1 - ax) * c[i] + ax * d[i]);
  }
  // Outside the map, continue linearly with unit slope (only used for clipping decisions).
  out.x() += pixel.x() - fx;
  out.y() += pixel.y() - fy;
  return out;
}

Vec2d PixelGeometry::Distorted(const Vec2d& fit) const {
  const auto& p = camera_->params;
  const Vec2d xn((fit.x() - p[kCx]) / p[kFx], (fit.y() - p[kCy]) / p[kFy]);
  const Vec2d xd = Distort(p.data(), xn);
  return Vec2d(p[kFx] * xd.x() + p[kCx], p[kFy] * xd.y() + p[kCy]);
}

}  // namespace idi
