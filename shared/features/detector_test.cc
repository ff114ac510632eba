// The whole pipeline on closed-form scenes: corners and chessboard junctions as IDI points with their
// topology, lens distortion handled in undistorted coordinates, bad input and options rejected
// clearly, images without lines giving an empty result.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "shared/features/analytic_images.h"
#include "shared/features/features.h"

namespace idi {
namespace {

const IdiPoint* Nearest(const FeatureResult& r, const Vec2d& xy, double* dist) {
  const IdiPoint* best = nullptr;
  *dist = 1e18;
  for (const IdiPoint& p : r.points) {
    const double d = (p.xy - xy).norm();
    if (d < *dist) {
      *dist = d;
      best = &p;
    }
  }
  return best;
}

TEST(DetectorTest, LCornerIsOneIdiPointWithItsTwoLines) {
  const cv::Mat img = analytic::Quantize(analytic::CornerImage(120, 100, 50.3, 40.6, 40, 190, 1.0), 1.0, 9);
  const auto r = DetectFeatures(img);
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->lines.size(), 2u);
  ASSERT_EQ(r->points.size(), 1u);
  const IdiPoint& p = r->points[0];
  EXPECT_LT((p.xy - Vec2d(50.3, 40.6)).norm(), 0.03);
  EXPECT_EQ(p.line_ids, (std::vector<int>{0, 1}));
  EXPECT_EQ(r->lines[0].point_ids, std::vector<int>{0});
  EXPECT_EQ(r->lines[1].point_ids, std::vector<int>{0});
  EXPECT_GT(p.covariance(0, 0), 0);
  EXPECT_LT(std::sqrt(p.covariance(0, 0) + p.covariance(1, 1)), 0.03);
  EXPECT_GT(r->timing.total_ms, 0);
}

// A corner whose lines meet at 24 deg (a box corner seen obliquely): near the apex the two blurred edges
// overlap and pull each line's fit away from the other, which moves the IDI point out of the wedge along
// its bisector. Either the refit clear of the other line (EmplOptions::junction_refit_angle_deg) or the
// photometric window stopping short of the other edge (photometric_stop_at_other_edge, the default)
// removes that.
TEST(DetectorTest, ShallowCornerIsNotPulledOutOfTheWedge) {
  struct Case {
    const char* name;
    double refit_deg;
    bool stop_at_other_edge;
  };
  for (const Case& c : {Case{"refit", 40, false}, Case{"stop at the other edge", 0, true}, Case{"neither", 0, false}}) {
    FeatureOptions o;
    o.empl.junction_refit_angle_deg = c.refit_deg;
    o.empl.photometric_stop_at_other_edge = c.stop_at_other_edge;
    constexpr int kImages = 10;
    double bias = 0, sum2 = 0;
    int found = 0;
    for (int k = 0; k < kImages; ++k) {
      const Vec2d apex(60.3 + 0.17 * k, 60.7 - 0.11 * k);
      const double bisector = 0.05 * (k - 3);
      const cv::Mat img = analytic::Quantize(
          analytic::WedgeImage(200, 120, apex.x(), apex.y(), bisector, 24 * 3.14159265358979323846 / 180, 40, 190, 1.0),
          5.0,
          100 + static_cast<std::uint64_t>(k));
      const auto r = DetectFeatures(img, o);
      ASSERT_TRUE(r.ok());
      double d;
      const IdiPoint* p = Nearest(*r, apex, &d);
      if (p == nullptr || d > 3.0) continue;
      ++found;
      sum2 += d * d;
      bias += (p->xy - apex).dot(Vec2d(std::cos(bisector), std::sin(bisector)));
    }
    ASSERT_EQ(found, kImages) << c.name;
    bias /= kImages;
    const double rms = std::sqrt(sum2 / kImages);
    std::printf("%s: bias along the bisector %+.3f px, RMS %.3f px\n", c.name, bias, rms);
    if (c.refit_deg > 0 || c.stop_at_other_edge) {
      EXPECT_LT(std::fabs(bias), 0.03) << c.name;
      EXPECT_LT(rms, 0.05) << c.name;
    } else {
      // What either removes: without both the same images put the point this far out of the wedge.
      EXPECT_LT(bias, -0.05);
    }
  }
}

TEST(DetectorTest, ChessboardJunctionsAreAllFoundAndPrecise) {
  const double x0 = 30.35, y0 = 25.8, pitch = 30;
  const int nx = 7, ny = 5;
  const cv::Mat img = analytic::Quantize(
      analytic::ChessboardImage(280, 220, x0, y0, pitch, nx, ny, 30, 210, 120, 1.0), 2.0, 21);
  const auto r = DetectFeatures(img);
  ASSERT_TRUE(r.ok());
  int found = 0;
  double worst = 0;
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) {
      const Vec2d truth(x0 + i * pitch, y0 + j * pitch);
      double d;
      const IdiPoint* p = Nearest(*r, truth, &d);
      if (p && d < 1.0) {
        ++found;
        worst = std::max(worst, d);
      }
    }
  }
  EXPECT_EQ(found, (nx + 1) * (ny + 1));
  EXPECT_LT(worst, 0.05);
  // Inner junctions have 2 lines; nothing spurious.
  EXPECT_EQ(static_cast<int>(r->points.size()), (nx + 1) * (ny + 1));
}

TEST(DetectorTest, LensDistortionLinesAreStraightInUndistortedCoordinates) {
  CameraModel cam;
  cam.width = 160;
  cam.height = 120;
  cam.params = {150, 150, 79.5, 59.5, -0.25, 0.05, 0, 0, 0};
  // An edge straight in undistorted coordinates, drawn through the distortion (per pixel: the
  // undistorted position of its centre; the small footprint change is irrelevant here).
  const Vec2d n = Vec2d(0.2, 1.0).normalized();
  const double d = n.dot(Vec2d(80, 28));
  cv::Mat img(cam.height, cam.width, CV_32F);
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const Vec2d u = UndistortPixel(cam, Vec2d(x, y));
      img.at<float>(y, x) = static_cast<float>(40 + 150 * analytic::PixelStep(n, d, u, 1.0));
    }
  }
  const cv::Mat q = analytic::Quantize(img, 0.5, 4);
  const auto with_camera = DetectFeatures(q, FeatureOptions{}, cam);
  ASSERT_TRUE(with_camera.ok());
  const EmplLine* best = nullptr;
  for (const EmplLine& l : with_camera->lines) {
    if (!best || l.length_px > best->length_px) best = &l;
  }
  ASSERT_NE(best, nullptr);
  EXPECT_GT(best->length_px, 120);
  EXPECT_GT(std::fabs(best->normal.dot(n)), 0.99999);
  EXPECT_LT(std::fabs(best->SignedDistance(Vec2d(80, 28) + 0 * n)), 0.05);
  EXPECT_LT(best->fit_rms_px, 0.06);
  // Without the camera the same edge is a curve: no single line over the whole length fits as well.
  const auto without = DetectFeatures(q);
  ASSERT_TRUE(without.ok());
  for (const EmplLine& l : without->lines) {
    if (l.length_px > 120) {
      EXPECT_GT(l.fit_rms_px, best->fit_rms_px);
    }
  }
}

TEST(DetectorTest, ImagesWithoutLinesGiveAnEmptyResult) {
  cv::Mat flat(60, 80, CV_8U, cv::Scalar(90));
  auto r = DetectFeatures(flat);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r->lines.empty());
  EXPECT_TRUE(r->points.empty());
  r = DetectFeatures(analytic::Quantize(cv::Mat(120, 160, CV_32F, cv::Scalar(100)), 8.0, 2));
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r->lines.empty()) << r->lines.size();
  EXPECT_NEAR(r->noise_sigma, 8.0, 1.0);
  // 16-bit input works like 8-bit.
  cv::Mat img16;
  analytic::CornerImage(120, 100, 50.3, 40.6, 40, 190, 1.0).convertTo(img16, CV_16U, 257.0);
  r = DetectFeatures(img16);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->points.size(), 1u);
}

TEST(DetectorTest, BadInputAndBadOptionsAreRejected) {
  EXPECT_EQ(DetectFeatures(cv::Mat()).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(DetectFeatures(cv::Mat(10, 10, CV_8U, cv::Scalar(0))).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(DetectFeatures(cv::Mat(40, 40, CV_8UC3, cv::Scalar(0, 0, 0))).status().code(),
            StatusCode::kInvalidArgument);
  FeatureOptions o;
  o.hough.min_length_px = -3;
  const auto r = DetectFeatures(cv::Mat(40, 40, CV_8U, cv::Scalar(0)), o);
  EXPECT_NE(r.status().message().find("hough.min_length_px"), std::string::npos) << r.status().message();
  o = FeatureOptions{};
  o.empl.max_extension_px = 1;
  EXPECT_FALSE(o.Check().ok());
  o = FeatureOptions{};
  o.empl.curve_min_sagitta_short_px = -0.1;
  EXPECT_NE(o.Check().message().find("empl.curve_min_sagitta_short_px"), std::string::npos) << o.Check().message();
  o = FeatureOptions{};
  o.empl.curve_end_trim_px = std::nan("");
  EXPECT_NE(o.Check().message().find("empl.curve_end_trim_px"), std::string::npos) << o.Check().message();
  o = FeatureOptions{};
  o.empl.min_extension_blur_sigmas = -1;
  EXPECT_NE(o.Check().message().find("empl.min_extension_blur_sigmas"), std::string::npos) << o.Check().message();
  o = FeatureOptions{};
  o.empl.peak_proximity_sigma_px = std::nan("");
  EXPECT_NE(o.Check().message().find("empl.peak_proximity_sigma_px"), std::string::npos) << o.Check().message();
  o.empl.peak_proximity_sigma_px = -1;
  EXPECT_NE(o.Check().message().find("empl.peak_proximity_sigma_px"), std::string::npos) << o.Check().message();
  o = FeatureOptions{};
  o.empl.flat_band_max_texture_ratio = std::nan("");
  EXPECT_NE(o.Check().message().find("empl.flat_band_max_texture_ratio"), std::string::npos) << o.Check().message();
  o.empl.flat_band_max_texture_ratio = -0.5;
  EXPECT_NE(o.Check().message().find("empl.flat_band_max_texture_ratio"), std::string::npos) << o.Check().message();
  o = FeatureOptions{};
  o.hough.max_gap_px = 1e9;  // the EMPL scan would walk a billion pixels beyond every segment
  EXPECT_NE(o.Check().message().find("hough.max_gap_px"), std::string::npos) << o.Check().message();
  o = FeatureOptions{};
  o.idi.max_point_sigma_px = std::nan("");
  EXPECT_NE(o.Check().message().find("idi.max_point_sigma_px"), std::string::npos) << o.Check().message();
  o.idi.max_point_sigma_px = -1;
  EXPECT_NE(o.Check().message().find("idi.max_point_sigma_px"), std::string::npos) << o.Check().message();
  o.idi.max_point_sigma_px = 0;
  EXPECT_TRUE(o.Check().ok()) << o.Check().message();
  for (double* v : {&o.idi.max_gap_px, &o.idi.gap_min_strength, &o.idi.gap_max_contrast}) {
    const double keep = *v;
    const std::string name = v == &o.idi.max_gap_px         ? "idi.max_gap_px"
                             : v == &o.idi.gap_min_strength ? "idi.gap_min_strength"
                                                            : "idi.gap_max_contrast";
    for (const double bad : {std::nan(""), -1.0}) {
      *v = bad;
      EXPECT_NE(o.Check().message().find(name), std::string::npos) << o.Check().message();
    }
    *v = keep;
  }
  o.idi.gap_min_strength = 1.5;  // a fraction
  EXPECT_NE(o.Check().message().find("idi.gap_min_strength"), std::string::npos) << o.Check().message();
  o.idi.gap_min_strength = 0.9;
  o.idi.max_gap_px = 0;  // off
  EXPECT_TRUE(o.Check().ok()) << o.Check().message();
  CameraModel cam;
  cam.params[kK1] = 0.1;
  auto det = FeatureDetector::Create(FeatureOptions{}, cam);
  ASSERT_TRUE(det.ok());
  const auto wrong_size = det->Detect(cv::Mat(100, 100, CV_8U, cv::Scalar(0)));
  EXPECT_NE(wrong_size.status().message().find("camera model is 640 x 480"), std::string::npos);
  // A distortion no lens has (the radial map folds over inside the image) is refused up front.
  CameraModel folded;
  folded.width = 160;
  folded.height = 120;
  folded.params = {200, 200, 79.5, 59.5, -5.0, 0, 0, 0, 0};
  const auto bad = FeatureDetector::Create(FeatureOptions{}, folded);
  EXPECT_EQ(bad.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("cannot be inverted"), std::string::npos) << bad.status().message();
}

}  // namespace
}  // namespace idi
