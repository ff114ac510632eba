// Gradients, noise estimate and Canny edges on closed-form images; bad input gives clear errors.
#include "shared/features/gradient.h"

#include <gtest/gtest.h>

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

TEST(GradientTest, RejectsBadImagesWithAClearMessage) {
  GradientImages g;
  Status s = ComputeGradients(cv::Mat(), 1.0, &g);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("empty"), std::string::npos);
  s = ComputeGradients(cv::Mat(32, 32, CV_8UC3, cv::Scalar(1, 2, 3)), 1.0, &g);
  EXPECT_NE(s.message().find("3 channels"), std::string::npos) << s.message();
  s = ComputeGradients(cv::Mat(8, 100, CV_8U, cv::Scalar(0)), 1.0, &g);
  EXPECT_NE(s.message().find("100 x 8"), std::string::npos) << s.message();
  s = ComputeGradients(cv::Mat(32, 32, CV_64F, cv::Scalar(0)), 1.0, &g);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  cv::Mat nan(32, 32, CV_32F, cv::Scalar(0));
  nan.at<float>(3, 4) = std::numeric_limits<float>::quiet_NaN();
  s = ComputeGradients(nan, 1.0, &g);
  EXPECT_NE(s.message().find("NaN"), std::string::npos);
  // 16-bit is accepted, with thresholds scaled to its range.
  EXPECT_TRUE(ComputeGradients(cv::Mat(32, 32, CV_16U, cv::Scalar(1000)), 1.0, &g).ok());
  EXPECT_DOUBLE_EQ(g.level_scale, 257.0);
}

}  // namespace
}  // namespace idi
