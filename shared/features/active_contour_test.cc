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

// The same arc crossing a line twice, given as a curve directly: fitted to 0.2 px RMS it places both
// crossings, but a curve whose points scatter by 3 px RMS cannot (each crossing's sigma is over 1 px),
// and IdiOptions::max_point_sigma_px keeps those out unless it is 0.
TEST(ActiveContourTest, ACrossingTheCurveCannotPlaceIsNotAPoint) {
  const Vec2d c(80, 55);
  const double radius = 30, yline = 70;
  auto run = [&](double curve_rms, const IdiOptions& options) {
    std::vector<Curve> curves(1);
    curves[0].id = 0;
    curves[0].fit_rms_px = curve_rms;
    for (int k = 0; k <= 24; ++k) {
      const double a = 3.14159265358979323846 * k / 24.0;  // the lower half of the circle, left to right
      curves[0].points.push_back(c + radius * Vec2d(-std::cos(a), std::sin(a)));
    }
    std::vector<EmplLine> lines(1);
    EmplLine& l = lines[0];
    l.id = 0;
    l.normal = Vec2d(0, 1);
    l.offset = yline;
    l.p1 = Vec2d(30, yline);
    l.p2 = Vec2d(130, yline);
    l.extension1 = l.p1 - Vec2d(5, 0);
    l.extension2 = l.p2 + Vec2d(5, 0);
    l.length_px = 100;
    // Angle sd 0.001 rad and offset sd 0.03 px at the segment's middle (x = 80).
    Eigen::Matrix2d j;
    j << 1, 0, -80, 1;
    l.covariance = j * Eigen::Vector2d(1e-6, 9e-4).asDiagonal() * j.transpose();
    std::vector<IdiPoint> points;
    AddCurveLinePoints(options, &curves, &lines, &points);
    return points;
  };
  const double dx = std::sqrt(radius * radius - (yline - c.y()) * (yline - c.y()));
  const auto precise = run(0.2, IdiOptions{});
  ASSERT_EQ(precise.size(), 2u);
  for (const IdiPoint& p : precise) {
    EXPECT_NEAR(std::fabs(p.xy.x() - c.x()), dx, 0.3);
    EXPECT_LT(std::sqrt(p.covariance.trace()), 0.3);
  }
  EXPECT_TRUE(run(3.0, IdiOptions{}).empty());
  IdiOptions keep_all;
  keep_all.max_point_sigma_px = 0;
  const auto scattered = run(3.0, keep_all);
  ASSERT_EQ(scattered.size(), 2u);
  for (const IdiPoint& p : scattered) EXPECT_GT(std::sqrt(p.covariance.trace()), IdiOptions{}.max_point_sigma_px);
}

}  // namespace
}  // namespace idi
