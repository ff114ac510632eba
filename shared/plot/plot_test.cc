#include "shared/plot/plot.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "shared/plot/png_file.h"

namespace idi::plot {
namespace {

cv::Mat Decode(const std::vector<std::uint8_t>& png) { return cv::imdecode(png, cv::IMREAD_COLOR); }

int CountColor(const cv::Mat& img, Color c) {
  int n = 0;
  for (int y = 0; y < img.rows; ++y) {
    for (int x = 0; x < img.cols; ++x) {
      const cv::Vec3b p = img.at<cv::Vec3b>(y, x);
      n += std::abs(p[0] - c.b) < 10 && std::abs(p[1] - c.g) < 10 && std::abs(p[2] - c.r) < 10;
    }
  }
  return n;
}

TEST(PlotTest, LinePlotOnALogAxisDrawsTheSeries) {
  Figure f(640, 480);
  f.SetTitle("cost per iteration");
  f.x_axis().label = "iteration";
  f.y_axis().label = "cost";
  f.y_axis().log = true;
  std::vector<double> x, y;
  for (int i = 0; i < 10; ++i) {
    x.push_back(i);
    y.push_back(std::pow(10.0, -i));
  }
  f.AddLine(x, y, "robot 1", kBlue, Marker::kCircle);
  const auto png = f.EncodePng();
  ASSERT_TRUE(png.ok()) << png.status().ToString();
  const cv::Mat img = Decode(*png);
  ASSERT_EQ(img.cols, 640);
  ASSERT_EQ(img.rows, 480);
  EXPECT_GT(CountColor(img, kBlue), 300);  // the line (and its legend swatch)
  EXPECT_EQ(CountColor(img, kRed), 0);
}

TEST(PlotTest, ScatterHistogramAndCircle) {
  Figure f;
  f.SetEqualAspect(true);
  f.AddScatter({-1, 0, 1}, {0, 1, 0}, "nominal", kRed, Marker::kCross);
  f.AddCircle(0, 0, 1.0, "mean radius", kGreen);
  const auto png = f.EncodePng();
  ASSERT_TRUE(png.ok());
  const cv::Mat img = Decode(*png);
  EXPECT_GT(CountColor(img, kRed), 10);
  EXPECT_GT(CountColor(img, kGreen), 100);
  Figure h;
  ASSERT_TRUE(h.AddHistogram({0.1, 0.2, 0.2, 0.3, 0.9}, 4, "residuals", kOrange).ok());
  const auto hp = h.EncodePng();
  ASSERT_TRUE(hp.ok());
  EXPECT_GT(CountColor(Decode(*hp), kOrange), 1000);
}

TEST(PlotTest, HistogramCounts) {
  const auto h = Histogram({0, 0.5, 1, 1.5, 2, 2, 4}, 4);
  ASSERT_TRUE(h.ok());
  EXPECT_EQ(h->edges.size(), 5u);
  EXPECT_EQ(h->counts, (std::vector<int>{2, 2, 2, 1}));  // [0,1) [1,2) [2,3) [3,4]
  EXPECT_FALSE(Histogram({1.0, std::nan("")}, 3).ok());
  EXPECT_FALSE(Histogram({}, 3).ok());
}

TEST(PlotTest, BadDataIsRefusedNamingTheSeries) {
  Figure f;
  EXPECT_FALSE(f.EncodePng().ok());  // empty
  f.y_axis().log = true;
  f.AddLine({0, 1}, {1, 0}, "cost", kBlue);
  const auto r = f.EncodePng();
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("'cost'"), std::string::npos);
  Figure g;
  g.AddLine({0, 1, 2}, {1, 2}, "short", kBlue);
  EXPECT_EQ(g.EncodePng().status().code(), StatusCode::kInvalidArgument);
}

// Finite values whose range overflows, a fixed range that is empty, and values far from zero that
// differ by a few units: refused or drawn, never a write outside the bins (the bin index was NaN) or a
// tick loop that does not advance (a step of 0.5 added to 5e15).
TEST(PlotTest, ExtremeRangesAreRefusedOrDrawn) {
  EXPECT_EQ(Histogram({-1e308, 1e308}, 10).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(Histogram({1.0, 2.0}, 10, -std::numeric_limits<double>::infinity()).status().code(),
            StatusCode::kInvalidArgument);
  const auto one = Histogram({1e17, 1e17}, 3);  // one value far from zero: a bin around it, not a zero width
  ASSERT_TRUE(one.ok());
  EXPECT_EQ(one->counts[0], 2);
  Figure far;
  far.AddLine({0, 1, 2}, {5e15, 5e15 + 1, 5e15 + 2}, "far", kBlue);
  EXPECT_TRUE(far.EncodePng().ok());
  Figure flat;
  flat.AddLine({0, 1}, {5e15, 5e15}, "flat", kBlue);
  EXPECT_TRUE(flat.EncodePng().ok());
  Figure fixed;
  fixed.AddLine({0, 1}, {1, 2}, "", kBlue);
  fixed.x_axis().min = 2.0;
  fixed.x_axis().max = 1.0;
  EXPECT_EQ(fixed.EncodePng().status().code(), StatusCode::kInvalidArgument);
  fixed.x_axis().max = 3.0;
  fixed.y_axis().log = true;
  fixed.y_axis().min = -1.0;
  EXPECT_EQ(fixed.EncodePng().status().code(), StatusCode::kInvalidArgument);
}

TEST(PlotTest, SavesAtomically) {
  Figure f;
  f.AddLine({0, 1}, {0, 1}, "", kBlue);
  const std::string path = ::testing::TempDir() + "/plot_test_" + std::to_string(::getpid()) + ".png";
  ASSERT_TRUE(f.SavePng(path).ok());
  EXPECT_FALSE(cv::imread(path).empty());
  EXPECT_FALSE(f.SavePng("/nonexistent-dir/x.png").ok());
}

// An image as a PNG file: read back pixel for pixel; an empty image or a folder that is not there is an
// error naming the file, and nothing is written.
TEST(PngFileTest, WritesAnImageThatReadsBackAndNamesTheFileOnError) {
  cv::Mat img(7, 5, CV_8UC1);
  for (int r = 0; r < img.rows; ++r) {
    for (int c = 0; c < img.cols; ++c) img.at<uchar>(r, c) = static_cast<uchar>(r * 30 + c);
  }
  const std::string path = ::testing::TempDir() + "/png_file_test_" + std::to_string(::getpid()) + ".png";
  ASSERT_TRUE(WritePngFile(path, img).ok());
  const cv::Mat back = cv::imread(path, cv::IMREAD_UNCHANGED);
  ASSERT_EQ(back.type(), CV_8UC1);
  EXPECT_EQ(cv::norm(back, img, cv::NORM_INF), 0.0);
  const Status empty = WritePngFile(path + ".empty.png", cv::Mat());
  EXPECT_EQ(empty.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(empty.message().find(path + ".empty.png"), std::string::npos) << empty.message();
  const Status nowhere = WritePngFile("/nonexistent-dir/y.png", img);
  EXPECT_FALSE(nowhere.ok());
  EXPECT_NE(nowhere.message().find("/nonexistent-dir/y.png"), std::string::npos) << nowhere.message();
  std::remove(path.c_str());
}

}  // namespace
}  // namespace idi::plot
