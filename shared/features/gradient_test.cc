// Gradients, noise estimate and Canny edges on closed-form images; bad input gives clear errors.
#include "shared/features/gradient.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "shared/features/analytic_images.h"

namespace idi {
namespace {

TEST(GradientTest, NoiseEstimateMatchesTheAddedNoise) {
  for (double sigma : {1.0, 3.0, 6.0}) {
    cv::Mat flat(240, 320, CV_32F, cv::Scalar(100));
    const cv::Mat img = analytic::Quantize(flat, sigma, 7);
    GradientImages g;
    ASSERT_TRUE(ComputeGradients(img, 1.0, &g).ok());
    EXPECT_NEAR(g.noise_sigma, sigma, 0.08 * sigma + 0.1) << sigma;
  }
}

TEST(GradientTest, CannyMarksOneColumnAtAVerticalEdge) {
  const cv::Mat img = analytic::Quantize(analytic::EdgeImage(64, 48, Vec2d(1, 0), 30.3, 50, 120, 1.0), 1.0, 3);
  GradientImages g;
  ASSERT_TRUE(ComputeGradients(img, 1.0, &g).ok());
  EdgeMap e;
  DetectEdges(g, EdgeOptions{}, &e);
  ASSERT_GT(e.pixels.size(), 40u);
  for (const cv::Point& p : e.pixels) {
    EXPECT_EQ(p.x, 30) << p.y;
  }
  // The gradient points across the edge, with magnitude contrast / (sqrt(2 pi) sigma_total).
  const double mag = std::sqrt(static_cast<double>(g.mag2.at<float>(24, 30)));
  EXPECT_NEAR(mag, 120 / (std::sqrt(2 * 3.14159265) * std::sqrt(1.0 + 1.0 + 1.0 / 12 + 1.0 / 3)), 4.0);
}

// The Canny mask, pixel for pixel, equals the textbook definition written out plainly here: a pixel
// is kept when its magnitude passes the low threshold and is a maximum across the edge (one of four
// sectors by the gradient direction), and it is connected through kept pixels to one above the high
// threshold. The image (a noisy disc and a tilted square, 67 px wide so rows do not split into
// whole SIMD groups) has edges in every direction and noise pixels near both thresholds.
TEST(GradientTest, CannyMaskIsTheTextbookDefinitionOnEveryPixel) {
  cv::Mat scene(53, 67, CV_32F, cv::Scalar(90));
  cv::circle(scene, cv::Point(22, 25), 15, cv::Scalar(170), cv::FILLED, cv::LINE_AA);
  const std::vector<cv::Point> square = {{44, 8}, {62, 17}, {53, 35}, {35, 26}};
  cv::fillConvexPoly(scene, square, cv::Scalar(30), cv::LINE_AA);
  const cv::Mat img = analytic::Quantize(scene, 10.0, 11);
  GradientImages g;
  ASSERT_TRUE(ComputeGradients(img, 1.0, &g).ok());
  EdgeMap e;
  DetectEdges(g, EdgeOptions{}, &e);
  const int w = img.cols, h = img.rows;
  const float low2 = static_cast<float>(e.low_threshold * e.low_threshold);
  const float high2 = static_cast<float>(e.high_threshold * e.high_threshold);
  const auto mag2 = [&](int x, int y) { return g.mag2.at<float>(y, x); };
  cv::Mat kept(h, w, CV_8U, cv::Scalar(0));  // 1 candidate, 2 strong
  for (int y = 1; y < h - 1; ++y) {
    for (int x = 1; x < w - 1; ++x) {
      const float gx = g.gx.at<float>(y, x), gy = g.gy.at<float>(y, x), v = mag2(x, y);
      const double deg = std::atan2(std::fabs(gy), std::fabs(gx)) * 180.0 / 3.14159265358979;
      int dx = 1, dy = 0;  // the neighbour across the edge on one side (the other is -dx, -dy)
      if (deg >= 67.5) {
        dx = 0;
        dy = 1;
      } else if (deg > 22.5) {
        dx = (gx > 0) == (gy > 0) ? 1 : -1;
        dy = 1;
      }
      if (v >= low2 && v > mag2(x - dx, y - dy) && v >= mag2(x + dx, y + dy)) {
        kept.at<uint8_t>(y, x) = v >= high2 ? 2 : 1;
      }
    }
  }
  cv::Mat expected(h, w, CV_8U, cv::Scalar(0));
  std::vector<cv::Point> todo;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (kept.at<uint8_t>(y, x) == 2) todo.emplace_back(x, y);
    }
  }
  int strong = static_cast<int>(todo.size());
  while (!todo.empty()) {
    const cv::Point p = todo.back();
    todo.pop_back();
    if (expected.at<uint8_t>(p) == 1) continue;
    expected.at<uint8_t>(p) = 1;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const cv::Point q(p.x + dx, p.y + dy);
        if (kept.at<uint8_t>(q) != 0 && expected.at<uint8_t>(q) == 0) todo.push_back(q);
      }
    }
  }
  ASSERT_GT(strong, 100);  // the test image does exercise both thresholds
  ASSERT_GT(cv::countNonZero(kept == 1), 10);
  EXPECT_EQ(cv::countNonZero(e.mask != expected), 0);
  EXPECT_EQ(static_cast<int>(e.pixels.size()), cv::countNonZero(expected));
  for (const cv::Point& p : e.pixels) {
    EXPECT_EQ(expected.at<uint8_t>(p), 1) << p;
  }
}

TEST(GradientTest, RejectsBadImagesWithAClearMessage) {
  GradientImages g;
  Status s = ComputeGradients(cv::Mat(), 1.0, &g);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("empty"), std::string::npos);
  s = ComputeGradients(cv::Mat(32, 32, CV_8UC3, cv::Scalar(1, 2, 3)), 1.0, &g);
  EXPECT_NE(s.message().find("3 channels"), std::string::npos) << s.message();
  s = ComputeGradients(cv::Mat(8, 100, CV_8U, cv::Scalar(0)), 1.0, &g);
  EXPECT_NE(s.message().find("100 x 8"), std::string::npos) << s.message();
  s = ComputeGradients(cv::Mat(16, 70000, CV_8U, cv::Scalar(0)), 1.0, &g);  // a line-scan strip
  EXPECT_NE(s.message().find("maximum 16384"), std::string::npos) << s.message();
  s = ComputeGradients(cv::Mat(32, 32, CV_64F, cv::Scalar(0)), 1.0, &g);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  cv::Mat nan(32, 32, CV_32F, cv::Scalar(0));
  nan.at<float>(3, 4) = std::numeric_limits<float>::quiet_NaN();
  s = ComputeGradients(nan, 1.0, &g);
  EXPECT_NE(s.message().find("NaN"), std::string::npos);
  // A no-data marker of -3e38 next to 0: its gradient's square overflows (the noise histogram's bin was
  // an out-of-range cast, a write far before the histogram).
  cv::Mat huge(32, 32, CV_32F, cv::Scalar(0));
  huge.at<float>(10, 10) = -3e38f;
  s = ComputeGradients(huge, 1.0, &g);
  EXPECT_NE(s.message().find("1e6"), std::string::npos) << s.message();
  // 16-bit is accepted, with thresholds scaled to its range.
  EXPECT_TRUE(ComputeGradients(cv::Mat(32, 32, CV_16U, cv::Scalar(1000)), 1.0, &g).ok());
  EXPECT_DOUBLE_EQ(g.level_scale, 257.0);
}

}  // namespace
}  // namespace idi
