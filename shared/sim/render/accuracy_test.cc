// Rendering accuracy: edges and laser spots measured from the pixels of noise-free renders agree with
// the analytic projection to better than 0.005 px (issue 3's acceptance), with and without the PSF,
// at several angles and sub-pixel offsets, and through lens distortion.
#include <gtest/gtest.h>

#include <cmath>

#include "shared/sim/render/render.h"
#include "shared/sim/render/shapes.h"
#include "shared/util/units.h"

namespace idi::sim {
namespace {

constexpr double kDepth = 1000;

CameraModel TestCamera(int w = 320, int h = 240) {
  CameraModel c;
  c.width = w;
  c.height = h;
  c.params = {800, 800, (w - 1) / 2.0 + 0.13, (h - 1) / 2.0 - 0.21, 0, 0, 0, 0, 0};
  return c;
}

// A plane at z = kDepth covering the half to the left of the directed line through (x0, y0, kDepth)
// along angle phi (in the plane), radiance `inside`, background `outside`. Only ambient light.
Scene HalfPlaneScene(double x0, double y0, double phi, double inside, double outside) {
  Scene s;
  const Vec3d d(std::cos(phi), std::sin(phi), 0), n(-std::sin(phi), std::cos(phi), 0);
  const double big = 1e5;
  s.solids.push_back(MakeRectangle("half", Vec3d(x0, y0, kDepth) + big * n, d, n, big, big, Gray(inside)));
  s.lighting.ambient = 1;
  s.lighting.directional.clear();
  s.background = Vec3d::Constant(outside);
  return s;
}

RenderOptions NoiseFree(double psf) {
  RenderOptions o;
  o.psf_sigma_px = psf;
  o.sensor.noise = false;
  return o;
}

// Edge position along each row (or column when `by_columns`) by the area of the integrated step:
// exact for an exactly area-integrated straight edge, and unchanged by a symmetric PSF.
// Returns (row, measured position) pairs for rows where the window fits.
std::vector<Vec2d> MeasureEdge(const cv::Mat& img, const Vec2d& normal, double offset, double left, double right,
                               bool by_columns, int half_window = 10) {
  std::vector<Vec2d> out;
  const int rows = by_columns ? img.cols : img.rows;
  const int cols = by_columns ? img.rows : img.cols;
  auto at = [&](int r, int c) -> double {
    return by_columns ? static_cast<double>(img.at<float>(c, r)) : static_cast<double>(img.at<float>(r, c));
  };
  const double na = by_columns ? normal.y() : normal.x(), nb = by_columns ? normal.x() : normal.y();
  for (int r = 15; r < rows - 15; ++r) {
    const double xe = (offset - nb * r) / na;
    const int c0 = static_cast<int>(std::lround(xe)) - half_window, c1 = static_cast<int>(std::lround(xe)) + half_window;
    if (c0 < 0 || c1 >= cols) continue;
    double sum = 0;
    for (int c = c0; c <= c1; ++c) sum += at(r, c);
    out.emplace_back(r, (sum - right * (c1 + 0.5) + left * (c0 - 0.5)) / (left - right));
  }
  return out;
}

struct EdgeCase {
  double phi_deg, dx_px, psf;
};

TEST(RenderAccuracyTest, StraightEdgesAtManyAnglesAndOffsetsAreExact) {
  const CameraModel cam = TestCamera();
  double worst = 0;
  int measured_rows = 0;
  for (const double phi_deg : {90.0, 91.7, 97.0, 113.0, 135.0, 152.0, 180.0, 183.3, 30.0, 44.0}) {
    for (const double dx : {0.0, 0.137, 0.5, 0.77}) {
      for (const double psf : {0.0, 1.0}) {
        const double phi = DegToRad(phi_deg);
        // The edge passes through pixel (160 + dx, 120.3).
        const Vec2d through(160 + dx, 120.3);
        const double x0 = (through.x() - cam.cx()) * kDepth / cam.fx();
        const double y0 = (through.y() - cam.cy()) * kDepth / cam.fy();
        const double inside = 0.8, outside = 0.1;
        const Scene scene = HalfPlaneScene(x0, y0, phi, inside, outside);
        auto img = RenderIrradiance(scene, cam, Rigid3d::Identity(), NoiseFree(psf));
        ASSERT_TRUE(img.ok()) << img.status().ToString();
        const Vec2d dir(std::cos(phi), std::sin(phi));
        const Vec2d normal(-dir.y(), dir.x());  // points into the covered side
        const double offset = normal.dot(through);
        const bool by_columns = std::abs(dir.x()) > std::abs(dir.y());
        // Which value lies at lower x (or y): the covered side is where normal . p > offset.
        const double lower_side = by_columns ? normal.y() : normal.x();
        const double lo = 200 * (lower_side < 0 ? inside : outside), hi = 200 * (lower_side < 0 ? outside : inside);
        for (const Vec2d& m : MeasureEdge(*img, normal, offset, lo, hi, by_columns)) {
          const double r = m.x();
          const double truth = by_columns ? (offset - normal.x() * r) / normal.y() : (offset - normal.y() * r) / normal.x();
          worst = std::max(worst, std::abs(m.y() - truth));
          ++measured_rows;
        }
      }
    }
  }
  EXPECT_GT(measured_rows, 5000);
  EXPECT_LT(worst, 0.005) << "largest edge position error over all rows, px";
  RecordProperty("max_edge_error_px", std::to_string(worst));
}

// Least-squares line through measured edge points: offset error at the image centre.
double FittedOffsetError(const std::vector<Vec2d>& pts, double slope, double intercept) {
  // Model: pos = intercept + slope * r + e; fit e as the mean residual (slope known to 1e-9 from the
  // geometry) and its trend.
  double sr = 0, se = 0, srr = 0, sre = 0;
  for (const Vec2d& p : pts) {
    const double e = p.y() - (intercept + slope * p.x());
    sr += p.x();
    se += e;
    srr += p.x() * p.x();
    sre += p.x() * e;
  }
  const double n = static_cast<double>(pts.size());
  const double b = (n * sre - sr * se) / (n * srr - sr * sr);
  const double a = (se - b * sr) / n;
  return a + b * 120;  // residual offset at the centre row
}

TEST(RenderAccuracyTest, EightBitNoiseFreeEdgeLinesAreExactToBetterThanFiveThousandths) {
  // What an EMPL fit sees: a line through the per-row positions of the quantized image.
  const CameraModel cam = TestCamera();
  double worst = 0;
  for (const double phi_deg : {93.0, 101.0, 117.0, 129.0}) {
    for (const double dx : {0.0, 0.31, 0.62}) {
      const double phi = DegToRad(phi_deg);
      const Vec2d through(160 + dx, 120.0);
      const double x0 = (through.x() - cam.cx()) * kDepth / cam.fx();
      const double y0 = (through.y() - cam.cy()) * kDepth / cam.fy();
      const Scene scene = HalfPlaneScene(x0, y0, phi, 0.85, 0.15);
      auto img8 = RenderScene(scene, cam, Rigid3d::Identity(), NoiseFree(1.0));
      ASSERT_TRUE(img8.ok());
      cv::Mat img;
      img8->convertTo(img, CV_32F);
      const Vec2d dir(std::cos(phi), std::sin(phi));
      const Vec2d normal(-dir.y(), dir.x());
      const double offset = normal.dot(through);
      const double lo = normal.x() < 0 ? 170 : 30, hi = normal.x() < 0 ? 30 : 170;
      const auto pts = MeasureEdge(img, normal, offset, lo, hi, false);
      ASSERT_GT(pts.size(), 150u);
      worst = std::max(worst, std::abs(FittedOffsetError(pts, -normal.y() / normal.x(), offset / normal.x())));
    }
  }
  EXPECT_LT(worst, 0.005);
  RecordProperty("max_line_offset_error_8bit_px", std::to_string(worst));
}

TEST(RenderAccuracyTest, EdgesThroughLensDistortionFollowTheDistortedProjection) {
  // A straight 3D edge becomes a curve; its measured position in each row matches the distorted
  // projection, so distortion adds no blur and no bias.
  CameraModel cam = TestCamera();
  cam.params[kK1] = -0.25;
  cam.params[kK2] = 0.08;
  cam.params[kP1] = 0.001;
  const double phi = DegToRad(97.0);
  const double x0 = 130.0, y0 = 0.0;  // at z = kDepth: right of the centre, where distortion bends it
  const Scene scene = HalfPlaneScene(x0, y0, phi, 0.8, 0.1);
  auto img = RenderIrradiance(scene, cam, Rigid3d::Identity(), NoiseFree(0.8));
  ASSERT_TRUE(img.ok());
  const Vec3d p0(x0, y0, kDepth), d(std::cos(phi), std::sin(phi), 0);
  double worst = 0;
  int rows = 0;
  for (int r = 20; r < cam.height - 20; ++r) {
    // Truth: the t where the distorted projection of p0 + t d has y = r (bisection), then its x.
    auto proj = [&](double t) { return ProjectToPixel(cam.params.data(), Vec3d(p0 + t * d)); };
    double a = -2000, b = 2000;
    for (int it = 0; it < 100; ++it) {
      const double m = 0.5 * (a + b);
      ((proj(m).y() < r) == (proj(a).y() < r) ? a : b) = m;
    }
    const double x_truth = proj(0.5 * (a + b)).x();
    // Measured by the area method in a window where the curve is straight to < 1e-4 px.
    const int c0 = static_cast<int>(std::lround(x_truth)) - 8, c1 = c0 + 16;
    double sum = 0;
    for (int c = c0; c <= c1; ++c) sum += img->at<float>(r, c);
    // The covered side (left of d, which points mostly along +y) is at smaller x.
    const double lo = 200 * 0.8, hi = 200 * 0.1;
    const double x_meas = (sum - hi * (c1 + 0.5) + lo * (c0 - 0.5)) / (lo - hi);
    worst = std::max(worst, std::abs(x_meas - x_truth));
    ++rows;
  }
  EXPECT_GT(rows, 150);
  EXPECT_LT(worst, 0.005);
  RecordProperty("max_distorted_edge_error_px", std::to_string(worst));
}

// Intensity centroid of a spot over a uniform level.
Vec2d Centroid(const cv::Mat& img, const Vec2d& around, double level, int half) {
  double s = 0, sx = 0, sy = 0;
  const int cx = static_cast<int>(std::lround(around.x())), cy = static_cast<int>(std::lround(around.y()));
  for (int y = cy - half; y <= cy + half; ++y) {
    for (int x = cx - half; x <= cx + half; ++x) {
      const double v = static_cast<double>(img.at<float>(y, x)) - level;
      s += v;
      sx += v * x;
      sy += v * y;
    }
  }
  return Vec2d(sx / s, sy / s);
}

TEST(RenderAccuracyTest, LaserSpotCentroidsMatchTheProjectedCentre) {
  // Spots of 0.3 px and 1 px (sigma) on a wall facing the camera and on one turned by 50 deg, at
  // several sub-pixel positions. With a PSF the centroid is exact; without one, a spot much narrower
  // than a pixel has a pixel-locking bias (physics, not the renderer), so that case is left out here
  // and checked pixel by pixel in SpotPixelsAreTheExactAreaIntegral.
  const CameraModel cam = TestCamera();
  double worst = 0, worst_centroid = 0;
  for (const double tilt_deg : {0.0, 50.0}) {
    for (const double sigma_mm : {0.8, 2.5}) {
      for (const Vec2d& sub : {Vec2d(0, 0), Vec2d(0.23, -0.41), Vec2d(0.5, 0.5)}) {
        for (const double psf : {0.0, 0.7, 1.0}) {
          if (psf == 0 && sigma_mm < 1) continue;
          Scene s;
          // A wall through (0, 0, 2000), turned by tilt about the vertical axis.
          const double t = DegToRad(tilt_deg);
          const Vec3d u(std::cos(t), 0, std::sin(t)), v(0, 1, 0);
          const Vec3d c0(0, 0, 2000);
          s.solids.push_back(MakeRectangle("wall", c0, u, v, 1e4, 1e4, Gray(0.2)));
          s.lighting.ambient = 1;
          s.lighting.directional.clear();
          // Spot centre on the wall, projecting to pixel (150, 110) + sub.
          const Vec2d target = Vec2d(150, 110) + sub;
          const Vec3d ray((target.x() - cam.cx()) / cam.fx(), (target.y() - cam.cy()) / cam.fy(), 1);
          const Vec3d n = u.cross(v);
          const Vec3d centre = ray * (n.dot(c0) / n.dot(ray));
          s.laser_spots.push_back({centre, sigma_mm, 3.0, Vec3d(1, 1, 1)});
          GroundTruth truth;
          auto img = RenderIrradiance(s, cam, Rigid3d::Identity(), NoiseFree(psf), &truth);
          ASSERT_TRUE(img.ok());
          ASSERT_EQ(truth.spots.size(), 1u);
          ASSERT_TRUE(truth.spots[0].visible);
          EXPECT_NEAR((truth.spots[0].xy_px - target).norm(), 0, 1e-9);
          const Vec2d c = Centroid(*img, target, 200 * 0.2, 14);
          // Against the centroid of the perspective image (what a centroid can recover), and against
          // the projected centre (the acceptance: 0.005 px; perspective moves it by ~0.003 px here).
          worst_centroid = std::max(worst_centroid, (c - truth.spots[0].centroid_px).norm());
          worst = std::max(worst, (c - truth.spots[0].xy_px).norm());
        }
      }
    }
  }
  EXPECT_LT(worst_centroid, 0.001);
  EXPECT_LT(worst, 0.005);
  RecordProperty("max_spot_centroid_error_px", std::to_string(worst));
  RecordProperty("max_spot_centroid_vs_image_centroid_px", std::to_string(worst_centroid));
}

TEST(RenderAccuracyTest, SpotPixelsAreTheExactAreaIntegral) {
  // No PSF, a spot a third of a pixel wide on a wall facing the camera: every pixel is the integral of
  // the Gaussian over the pixel square (products of error functions).
  const CameraModel cam = TestCamera();
  Scene s;
  s.solids.push_back(MakeRectangle("wall", Vec3d(0, 0, 2000), Vec3d::UnitX(), Vec3d::UnitY(), 1e4, 1e4, Gray(0.2)));
  s.lighting.ambient = 1;
  s.lighting.directional.clear();
  const Vec2d target(150.23, 109.59);
  const Vec3d centre((target.x() - cam.cx()) / cam.fx() * 2000, (target.y() - cam.cy()) / cam.fy() * 2000, 2000);
  s.laser_spots.push_back({centre, 0.8, 3.0, Vec3d(1, 1, 1)});
  auto img = RenderIrradiance(s, cam, Rigid3d::Identity(), NoiseFree(0));
  ASSERT_TRUE(img.ok());
  const double sp = 0.8 * 800 / 2000;
  auto f = [&](double a) { return 0.5 * std::erf(a / (sp * std::sqrt(2.0))); };
  double worst = 0;
  for (int y = 104; y <= 115; ++y) {
    for (int x = 144; x <= 156; ++x) {
      const double expected = 200 * (0.2 + 3 * 2 * kPi * sp * sp * (f(x + 0.5 - target.x()) - f(x - 0.5 - target.x())) *
                                               (f(y + 0.5 - target.y()) - f(y - 0.5 - target.y())));
      worst = std::max(worst, std::abs(img->at<float>(y, x) - expected));
    }
  }
  EXPECT_LT(worst, 1e-3) << "DN";
}

TEST(RenderAccuracyTest, EightBitSpotsAreCentredAndSaturateWhenBright) {
  // 8-bit, noise-free, PSF 1 px. Rounding to whole DN alone moves a spot's centroid by a few
  // thousandths of a pixel (0.005 here; the irradiance before the sensor is exact to 1e-5, see
  // above), so the bound is 0.01 px. A bright spot clips at 255 (the flat top a short exposure
  // avoids, section 6.4.3), which costs more because clipping happens after the pixels integrate.
  const CameraModel cam = TestCamera();
  const Vec2d target(171.37, 97.81);
  for (const double peak : {3.0, 40.0}) {
    Scene s;
    s.solids.push_back(MakeRectangle("wall", Vec3d(0, 0, 2000), Vec3d::UnitX(), Vec3d::UnitY(), 1e4, 1e4, Gray(0.1)));
    s.lighting.ambient = 1;
    s.lighting.directional.clear();
    const Vec3d centre((target.x() - cam.cx()) / cam.fx() * 2000, (target.y() - cam.cy()) / cam.fy() * 2000, 2000);
    s.laser_spots.push_back({centre, 3.0, peak, Vec3d(1, 1, 1)});
    RenderOptions o = NoiseFree(1.0);
    o.exposure_dn = 100;
    auto img8 = RenderScene(s, cam, Rigid3d::Identity(), o);
    ASSERT_TRUE(img8.ok());
    double max_v;
    cv::minMaxLoc(*img8, nullptr, &max_v);
    cv::Mat img;
    img8->convertTo(img, CV_32F);
    const Vec2d c = Centroid(img, target, 10, 16);
    if (peak < 5) {
      EXPECT_LT(max_v, 255);
      EXPECT_LT((c - target).norm(), 0.01);
    } else {
      EXPECT_EQ(max_v, 255);
      EXPECT_LT((c - target).norm(), 0.05);
    }
  }
}

}  // namespace
}  // namespace idi::sim
