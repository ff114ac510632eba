// Active contours on a curved silhouette, and IDI points where the curve meets a straight edge.
#include "shared/features/active_contour.h"

#include <gtest/gtest.h>

#include <cmath>

#include "shared/features/analytic_images.h"

namespace idi {
namespace {

TEST(ActiveContourTest, DiskBoundaryIsACurveOnTheCircle) {
  const Vec2d c(80.3, 60.7);
  const double radius = 30;
  cv::Mat img(120, 160, CV_32F);
  for (int y = 0; y < img.rows; ++y) {
    for (int x = 0; x < img.cols; ++x) {
      const double rr = (Vec2d(x, y) - c).norm();
      img.at<float>(y, x) = static_cast<float>(50 + 140 * analytic::Phi((radius - rr) / 1.04));
    }
  }
  const auto r = DetectFeatures(analytic::Quantize(img, 1.0, 8));
  ASSERT_TRUE(r.ok());
  ASSERT_FALSE(r->curves.empty());
  std::size_t points = 0;
  double worst = 0;
  for (const Curve& curve : r->curves) {
    for (const Eigen::Vector2d& p : curve.points) {
      worst = std::max(worst, std::fabs((p - c).norm() - radius));
      ++points;
    }
  }
  EXPECT_GT(points, 30u);
  EXPECT_LT(worst, 0.35);
}

TEST(ActiveContourTest, CurveMeetingALineGivesAnIdiPoint) {
  // Bright disk on dark, cut by a bright half plane below y = 70: the circle meets the line at
  // x = cx +- sqrt(r^2 - (70 - cy)^2).
  const Vec2d c(80, 55);
  const double radius = 30, yline = 70.5;
  cv::Mat img(120, 160, CV_32F);
  for (int y = 0; y < img.rows; ++y) {
    for (int x = 0; x < img.cols; ++x) {
      const double disk = analytic::Phi((radius - (Vec2d(x, y) - c).norm()) / 1.04);
      const double plane = analytic::PixelStep1(y, yline, 1.0);
      img.at<float>(y, x) = static_cast<float>(40 + 150 * (1 - (1 - disk) * (1 - plane)));
    }
  }
  const auto r = DetectFeatures(analytic::Quantize(img, 1.0, 8));
  ASSERT_TRUE(r.ok());
  const double dx = std::sqrt(radius * radius - (yline - 0.5 - c.y()) * (yline - 0.5 - c.y()));
  int near = 0;
  for (const IdiPoint& p : r->points) {
    if (p.kind != IdiPointKind::kCurveLine) continue;
    EXPECT_EQ(p.line_ids.size(), 1u);
    EXPECT_EQ(p.curve_ids.size(), 1u);
    for (double sx : {-1.0, 1.0}) {
      if ((p.xy - Vec2d(c.x() + sx * dx, yline - 0.5)).norm() < 1.5) ++near;
    }
  }
  EXPECT_GE(near, 1);
}

}  // namespace
}  // namespace idi
