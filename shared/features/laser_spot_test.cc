// The laser spot: sub-pixel centroid of one spot; no spot, several spots and a saturated bloom are
// reported as such; bad images give errors.
#include "shared/features/laser_spot.h"

#include <gtest/gtest.h>

#include <cmath>

#include "shared/features/analytic_images.h"

namespace idi {
namespace {

cv::Mat Spots(const std::vector<std::array<double, 4>>& spots, double bg, double noise) {
  cv::Mat img(120, 160, CV_32F, cv::Scalar(bg));
  for (const auto& s : spots) {  // x, y, sigma, peak
    for (int y = 0; y < img.rows; ++y) {
      for (int x = 0; x < img.cols; ++x) {
        const double r2 = (x - s[0]) * (x - s[0]) + (y - s[1]) * (y - s[1]);
        img.at<float>(y, x) += static_cast<float>(s[3] * std::exp(-0.5 * r2 / (s[2] * s[2])));
      }
    }
  }
  return analytic::Quantize(img, noise, 11);
}

TEST(LaserSpotTest, OneSpotToSubPixelPrecision) {
  const auto r = FindLaserSpot(Spots({{{70.3, 41.7, 1.6, 150}}}, 20, 2.0));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->status, LaserSpotStatus::kFound) << r->message;
  EXPECT_NEAR(r->spots[0].xy.x(), 70.3, 0.05);
  EXPECT_NEAR(r->spots[0].xy.y(), 41.7, 0.05);
  EXPECT_GT(r->spots[0].covariance(0, 0), 0);
  EXPECT_LT(std::sqrt(r->spots[0].covariance(0, 0)), 0.05);
  EXPECT_NEAR(r->background, 20, 1.0);
}

TEST(LaserSpotTest, NoneSeveralAndSaturatedAreReported) {
  auto r = FindLaserSpot(Spots({}, 40, 2.0));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->status, LaserSpotStatus::kNoSpot);
  EXPECT_TRUE(r->spots.empty());
  r = FindLaserSpot(Spots({{{30, 30, 1.5, 140}}, {{120, 90, 1.5, 120}}}, 20, 2.0));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->status, LaserSpotStatus::kSeveral);
  EXPECT_EQ(r->spots.size(), 2u);
  r = FindLaserSpot(Spots({{{80, 60, 4.0, 900}}}, 20, 2.0));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->status, LaserSpotStatus::kSaturated) << r->message;
  EXPECT_NEAR(r->spots[0].xy.x(), 80, 0.3);
  // A faint reflection next to a strong spot does not make it ambiguous.
  r = FindLaserSpot(Spots({{{50, 50, 1.5, 200}}, {{100, 30, 1.5, 50}}}, 20, 2.0));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->status, LaserSpotStatus::kFound);
  EXPECT_NEAR(r->spots[0].xy.x(), 50, 0.05);
}

TEST(LaserSpotTest, BadImages) {
  EXPECT_EQ(FindLaserSpot(cv::Mat()).status().code(), StatusCode::kInvalidArgument);
  const auto colour = FindLaserSpot(cv::Mat(20, 20, CV_8UC3, cv::Scalar(0, 0, 0)));
  EXPECT_NE(colour.status().message().find("channels"), std::string::npos);
  EXPECT_EQ(FindLaserSpot(cv::Mat(2, 2, CV_8U, cv::Scalar(0))).status().code(), StatusCode::kInvalidArgument);
  LaserSpotOptions bad;
  bad.centroid_fraction = 2;
  EXPECT_EQ(FindLaserSpot(cv::Mat(20, 20, CV_8U, cv::Scalar(0)), bad).status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace idi
