// EMPL lines on closed-form edges: exact without noise at any angle and sub-pixel phase, at the
// Cramér-Rao bound with noise, with a covariance that predicts the error; alternating contrast along
// a chessboard line makes one line.
#include "shared/features/empl.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "shared/features/analytic_images.h"

namespace idi {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Signed offset error of `line` against the true (normal, offset) at point `at`, and angle error.
void LineErrors(const EmplLine& line, const Vec2d& n, double d, const Vec2d& at, double* offset_err, double* angle_err) {
  const Vec2d foot_true = at - n * (n.dot(at) - d);  // point of the true line near `at`
  *offset_err = line.SignedDistance(foot_true) * (line.normal.dot(n) > 0 ? 1 : -1);
  double da = std::atan2(line.normal.y(), line.normal.x()) - std::atan2(n.y(), n.x());
  da = std::remainder(da, kPi);
  *angle_err = da;
}

// Offset error of `line` at its segment's middle against the true (normal, offset), and the variance of
// that offset that the line's own covariance predicts.
void OffsetAtMiddle(const EmplLine& line, const Vec2d& n, double d, double* offset_err, double* predicted_var) {
  const Vec2d mid = 0.5 * (line.p1 + line.p2);
  double angle_err;
  LineErrors(line, n, d, mid, offset_err, &angle_err);
  const Vec2d nd(-line.normal.y(), line.normal.x());
  const Eigen::Vector2d j(nd.dot(mid), -1.0);
  *predicted_var = j.dot(line.covariance * j);
}

// The offset error at the middle of the line of edge (n, d) (the line within 1 px of it) over `trials`
// copies of `clean` with noise: its mean and RMS, and how many lines matched.
struct OffsetErrors {
  double mean = 0, rms = 0;
  int found = 0;
};
OffsetErrors OffsetErrorsOver(const FeatureOptions& options,
                              const cv::Mat& clean,
                              double noise,
                              std::uint64_t seed,
                              int trials,
                              const Vec2d& n,
                              double d) {
  OffsetErrors out;
  auto detector = FeatureDetector::Create(options);
  EXPECT_TRUE(detector.ok());
  if (!detector.ok()) return out;
  double sum = 0, sum2 = 0;
  for (int t = 0; t < trials; ++t) {
    const auto r = detector->Detect(analytic::Quantize(clean, noise, seed + static_cast<std::uint64_t>(t)));
    EXPECT_TRUE(r.ok());
    if (!r.ok()) continue;
    for (const EmplLine& l : r->lines) {
      double oe, var;
      OffsetAtMiddle(l, n, d, &oe, &var);
      if (std::fabs(oe) < 1.0) {
        sum += oe;
        sum2 += oe * oe;
        ++out.found;
      }
    }
  }
  out.mean = sum / std::max(1, out.found);
  out.rms = std::sqrt(sum2 / std::max(1, out.found));
  return out;
}

TEST(EmplTest, NoiseFreeEdgesAreExactAtAnyAngleAndPhase) {
  for (double deg : {0.0, 7.0, 30.0, 45.0, 61.0, 90.0, 112.0, 135.0, 171.0}) {
    for (double phase : {0.0, 0.25, 0.5}) {
      const Vec2d n(std::cos(deg * kPi / 180), std::sin(deg * kPi / 180));
      const Vec2d c(48.0 + phase, 40.0 + phase);
      const double d = n.dot(c);
      const cv::Mat img = analytic::EdgeImage(96, 80, n, d, 60, 120, 1.0);
      const auto r = DetectFeatures(img);
      ASSERT_TRUE(r.ok());
      ASSERT_EQ(r->lines.size(), 1u) << deg << " " << phase;
      double oe, ae;
      LineErrors(r->lines[0], n, d, c, &oe, &ae);
      EXPECT_LT(std::fabs(oe), 0.003) << deg << " deg, phase " << phase;
      EXPECT_LT(std::fabs(ae), 2e-4) << deg << " deg, phase " << phase;
      EXPECT_NEAR(r->lines[0].contrast, 120, 2.0);
      EXPECT_NEAR(r->lines[0].blur_sigma_px, std::sqrt(1.0 + 1.0 / 12), 0.08);
    }
  }
}

TEST(EmplTest, NoisyEdgeReachesTheBoundAndItsCovarianceIsHonest) {
  const double contrast = 150, noise = 10, blur = 1.0;  // A / sigma_n = 15
  const double deg = 17.0;
  const Vec2d n(std::cos(deg * kPi / 180), std::sin(deg * kPi / 180));
  const Vec2d c(64.3, 48.6);
  const double d = n.dot(c);
  const cv::Mat clean = analytic::EdgeImage(128, 96, n, d, 50, contrast, blur);
  double sum2 = 0, sum = 0, pred = 0, len = 0;
  const int trials = 24;
  auto detector = FeatureDetector::Create(FeatureOptions{});
  ASSERT_TRUE(detector.ok());
  for (int t = 0; t < trials; ++t) {
    const cv::Mat img = analytic::Quantize(clean, noise, 100 + static_cast<std::uint64_t>(t));
    const auto r = detector->Detect(img);
    ASSERT_TRUE(r.ok());
    ASSERT_EQ(r->lines.size(), 1u);
    const EmplLine& l = r->lines[0];
    double oe, var;
    OffsetAtMiddle(l, n, d, &oe, &var);
    sum += oe;
    sum2 += oe * oe;
    pred += var;
    len += l.length_px;
  }
  const double rms = std::sqrt(sum2 / trials);
  const double bound = OffsetBoundPx(contrast, noise, blur, len / trials);
  // 24 trials: the RMS is known to about +-15 %, hence the margins.
  EXPECT_LT(rms, 1.6 * bound) << "rms " << rms << " bound " << bound;
  EXPECT_LT(std::fabs(sum / trials), 3 * bound / std::sqrt(trials) + 0.005);
  const double predicted = std::sqrt(pred / trials);
  EXPECT_GT(predicted, 0.7 * bound);
  EXPECT_LT(predicted, 1.5 * bound);
}

// With photometric_flat_band the photometric fit takes the flat image beside the edge into its band (up
// to 2 half-widths + 2 px each side): the background and contrast of a chunk are then fixed by pixels the edge does not
// move, and the offset gets nearly all the information the bound counts. With the band at +-4 px only (2 sigma + 1.5),
// the fit's own predicted error was 1.32 times the bound on this edge.
TEST(EmplTest, PhotometricBandTakesTheFlatImageBesideTheEdge) {
  const double contrast = 150, noise = 10, blur = 1.0;
  const Vec2d n(std::cos(0.3), std::sin(0.3));
  const Vec2d c(64.3, 48.6);
  const double d = n.dot(c);
  const cv::Mat clean = analytic::EdgeImage(128, 96, n, d, 50, contrast, blur);
  FeatureOptions o;
  o.empl.photometric_flat_band = true;
  auto detector = FeatureDetector::Create(o);
  ASSERT_TRUE(detector.ok());
  double sum2 = 0, pred = 0, len = 0;
  const int trials = 60;
  for (int t = 0; t < trials; ++t) {
    const auto r = detector->Detect(analytic::Quantize(clean, noise, 500 + static_cast<std::uint64_t>(t)));
    ASSERT_TRUE(r.ok());
    ASSERT_EQ(r->lines.size(), 1u);
    const EmplLine& l = r->lines[0];
    double oe, var;
    OffsetAtMiddle(l, n, d, &oe, &var);
    sum2 += oe * oe;
    pred += var;
    len += l.length_px;
  }
  const double bound = OffsetBoundPx(contrast, noise, blur, len / trials);
  const double predicted = std::sqrt(pred / trials), rms = std::sqrt(sum2 / trials);
  std::printf("offset at the middle: RMS %.4f px, predicted %.4f px, bound %.4f px\n", rms, predicted, bound);
  EXPECT_LT(predicted, 1.2 * bound);
  // 60 trials: the RMS is known to about +-10 %.
  EXPECT_LT(rms, 1.3 * bound);
  EXPECT_GT(rms, 0.75 * predicted);
  EXPECT_LT(rms, 1.3 * predicted);
}

// The flat band is only as good as the flat image it takes in. Here one side of the edge is textured
// from 6 px on (a fixed pattern between 0 and 12 grey levels, 13 px along and 7 px across, at
// A/sigma_n = 27): taken into the band it moves that side's background and the edge with it, by the
// same amount in every image (-0.026 px, 2.6 times the RMS noise). The texture test
// (EmplOptions::flat_band_max_texture_ratio) sees the smoothed gradient vary more there than the
// noise explains and leaves that side's flat band out (+0.001 px).
TEST(EmplTest, FlatBandLeavesOutATexturedSide) {
  const double contrast = 80, noise = 3, blur = 1.0;
  const double amp = 12;  // the texture's peak (grey levels)
  const Vec2d n(std::cos(0.3), std::sin(0.3));
  const Vec2d c(64.3, 48.6);
  const double d = n.dot(c);
  cv::Mat clean = analytic::EdgeImage(128, 96, n, d, 60, contrast, blur);
  const Vec2d along(-n.y(), n.x());
  for (int y = 0; y < clean.rows; ++y) {
    for (int x = 0; x < clean.cols; ++x) {
      const double across = n.dot(Vec2d(x, y)) - d, t = along.dot(Vec2d(x, y));
      if (across > 6.0) {
        const double in = std::min(1.0, (across - 6.0) / 3.0), fade = in * in * (3 - 2 * in);
        clean.at<float>(y, x) += static_cast<float>(
            amp * fade * (0.5 + 0.5 * std::cos(2 * kPi * t / 13.0) * std::cos(2 * kPi * across / 7.0)));
      }
    }
  }
  FeatureOptions o;
  o.empl.photometric_flat_band = true;
  const OffsetErrors tested = OffsetErrorsOver(o, clean, noise, 1300, 30, n, d);
  o.empl.flat_band_max_texture_ratio = 0;
  const OffsetErrors untested = OffsetErrorsOver(o, clean, noise, 1300, 30, n, d);
  std::printf("offset error at the middle: texture test on: mean %+.4f RMS %.4f px; off: mean %+.4f RMS %.4f px\n",
              tested.mean,
              tested.rms,
              untested.mean,
              untested.rms);
  EXPECT_EQ(tested.found, 30);
  EXPECT_EQ(untested.found, 30);
  EXPECT_GT(FeatureOptions{}.empl.flat_band_max_texture_ratio, 0);
  // The RMS is about 0.010 px, so the mean of 30 is known to 0.002 px.
  EXPECT_LT(std::fabs(tested.mean), 0.008);
  EXPECT_GT(std::fabs(untested.mean), 0.018);  // the case is one the test is needed for
}

// A face's shading ramps across the edge (1 grey level per pixel here), and a second, parallel edge
// 9 px away stops the flat band on that side short, so the band is lopsided. With a constant background
// per chunk the fit then moves the edge towards the short side (+0.041 px at A/sigma_n = 25, four times
// the noise's RMS); with the background's slope across the edge as a third linear parameter of each
// chunk (photometric_ramp) the offset is as unbiased as on a flat face.
TEST(EmplTest, PhotometricRampKeepsAnEdgeOnAShadedFaceUnbiased) {
  const double contrast = 100, noise = 4, blur = 1.0, slope = 1.0;
  const Vec2d n(std::cos(0.3), std::sin(0.3));
  const Vec2d c(64.3, 48.6);
  const double d = n.dot(c);
  cv::Mat clean =
      analytic::EdgeImage(128, 96, n, d, 50, contrast, blur) + analytic::EdgeImage(128, 96, n, d + 9.0, 0, 40, blur);
  for (int y = 0; y < clean.rows; ++y) {
    for (int x = 0; x < clean.cols; ++x) {
      clean.at<float>(y, x) += static_cast<float>(slope * (n.dot(Vec2d(x, y)) - d));
    }
  }
  auto mean_offset = [&](bool ramp) {
    FeatureOptions o;
    o.empl.photometric_flat_band = true;
    o.empl.photometric_ramp = ramp;
    // The line of this edge, not the second one's.
    const OffsetErrors e = OffsetErrorsOver(o, clean, noise, 900, 30, n, d);
    EXPECT_EQ(e.found, 30);
    return e.mean;
  };
  const double with_ramp = mean_offset(true), without = mean_offset(false);
  std::printf("mean offset error: with the ramp %+.4f px, without %+.4f px\n", with_ramp, without);
  // The RMS is about 0.010 px, so the mean of 30 is known to 0.002 px.
  EXPECT_LT(std::fabs(with_ramp), 0.006);
  EXPECT_GT(std::fabs(without), 0.02);  // the case is one that needs the ramp
}

// A bright strip 5 px wide (a bracket's plate seen edge-on) blurred by sigma_b 1.5: each edge's
// photometric window of +-half reaches across the strip into the other edge, whose opposite step the
// one-step model cannot explain. Without photometric_stop_at_other_edge both lines are pulled half a
// pixel towards the middle; with it each window stops short of the other edge's blur and the pull is
// five times smaller. (What is left comes from the other edge's tail within the window's least reach,
// ceil(sigma) px, which a one-step model cannot tell from its own step.)
TEST(EmplTest, ThinStripKeepsItsTwoEdgesApart) {
  const double width = 5.0, contrast = 80, noise = 3, blur = 1.5;
  const Vec2d n(std::cos(0.2), std::sin(0.2));
  const Vec2d c(64.3, 48.6);
  const double d = n.dot(c);
  const cv::Mat clean = analytic::EdgeImage(128, 96, n, d, 50, contrast, blur) +
                        analytic::EdgeImage(128, 96, n, d + width, 0, -contrast, blur);
  auto errors = [&](bool stop, double offset) {
    FeatureOptions o;
    o.empl.photometric_stop_at_other_edge = stop;
    return OffsetErrorsOver(o, clean, noise, 700, 30, n, offset);
  };
  const OffsetErrors near_on = errors(true, d), far_on = errors(true, d + width);
  const OffsetErrors near_off = errors(false, d), far_off = errors(false, d + width);
  std::printf(
      "strip edges, mean offset error (found of 30): stopping at the other edge %+.4f (%d), %+.4f (%d) px; "
      "not stopping %+.4f (%d), %+.4f (%d) px\n",
      near_on.mean,
      near_on.found,
      far_on.mean,
      far_on.found,
      near_off.mean,
      near_off.found,
      far_off.mean,
      far_off.found);
  EXPECT_TRUE(FeatureOptions{}.empl.photometric_stop_at_other_edge);
  EXPECT_EQ(near_on.found, 30);
  EXPECT_EQ(far_on.found, 30);
  // The offsets are given along n, so the near edge pulled inwards has a positive error, the far one
  // a negative error.
  EXPECT_GT(near_off.mean, 0.4);
  EXPECT_LT(far_off.mean, -0.4);
  EXPECT_LT(std::fabs(near_on.mean), 0.12);
  EXPECT_LT(std::fabs(far_on.mean), 0.12);
}

TEST(EmplTest, GradientOnlyFitIsUsableWhenThePhotometricStepIsOff) {
  FeatureOptions o;
  o.empl.photometric_refinement = false;
  const Vec2d n(std::cos(0.3), std::sin(0.3));
  const double d = n.dot(Vec2d(48.2, 40.7));
  const auto r = DetectFeatures(analytic::EdgeImage(96, 80, n, d, 60, 120, 1.0), o);
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->lines.size(), 1u);
  double oe, ae;
  LineErrors(r->lines[0], n, d, Vec2d(48.2, 40.7), &oe, &ae);
  EXPECT_LT(std::fabs(oe), 0.03);
  EXPECT_LT(r->lines[0].fit_rms_px, 0.05);
  EXPECT_GT(r->lines[0].covariance(1, 1), 0);
}

TEST(EmplTest, ConfirmedEndsAndExtensions) {
  // A vertical edge only in rows 20..69 (an L-corner's vertical side: quadrant x > 40, y > 20).
  const cv::Mat img = analytic::CornerImage(96, 90, 40.0, 20.0, 40, 160, 1.0);
  const auto r = DetectFeatures(img);
  ASSERT_TRUE(r.ok());
  const EmplLine* vertical = nullptr;
  for (const EmplLine& l : r->lines) {
    if (std::fabs(l.normal.x()) > 0.99) vertical = &l;
  }
  ASSERT_NE(vertical, nullptr);
  const double top = std::min(vertical->p1.y(), vertical->p2.y());
  const double bottom = std::max(vertical->p1.y(), vertical->p2.y());
  EXPECT_NEAR(top, 20.0, 3.0);
  EXPECT_GT(bottom, 85.0);
  const double ext = (vertical->extension1 - vertical->p1).norm();
  EXPECT_NEAR(ext, ExtensionLength(EmplOptions{}, vertical->length_px), 1e-9);
  EXPECT_NEAR(vertical->Direction().norm(), 1.0, 1e-12);
}

TEST(EmplTest, ChessboardLinesWithAlternatingContrastAreOneLineEach) {
  // 6 x 5 squares of 24 px: 7 vertical and 6 horizontal grid lines, inner ones alternate contrast.
  const cv::Mat img = analytic::Quantize(
      analytic::ChessboardImage(200, 170, 20.4, 22.7, 24.0, 6, 5, 40, 200, 120, 1.0), 2.0, 5);
  const auto r = DetectFeatures(img);
  ASSERT_TRUE(r.ok());
  int vertical = 0, horizontal = 0, alternating = 0;
  for (const EmplLine& l : r->lines) {
    if (l.length_px < 100) continue;
    if (std::fabs(l.normal.x()) > 0.999) ++vertical;
    if (std::fabs(l.normal.y()) > 0.999) ++horizontal;
    alternating += l.alternating ? 1 : 0;
  }
  EXPECT_EQ(vertical, 7);
  EXPECT_EQ(horizontal, 6);
  EXPECT_GE(alternating, 5 + 4);
}

TEST(EmplTest, AShallowBendIsTwoLinesWithAPointNotACurve) {
  // Above a bent edge grey 100; below it a face of 60 on the left and one of 140 on the right, split
  // by the bisector, so the edge's contrast changes sign at the bend (as where an L-bracket's edge
  // runs on into another face's). One run fitted across the bend bends like an arc; it must come out
  // as two lines, each on its edge, meeting the bisector's line in one IDI point at the bend.
  // (At 16 deg both edges' segments stop 10 px short of the bend, beyond their extensions, and no point
  // forms: the "segment stops short" misses of features_bench D.)
  for (const double bend_deg : {12.0, 20.0}) {
    const double opening = kPi - bend_deg * kPi / 180;
    const Vec2d apex(80.3, 40.6);
    const cv::Mat faces =
        analytic::WedgeImage(160, 90, apex.x(), apex.y(), kPi / 2, opening, 100, 60, 1.0) +
        analytic::WedgeImage(160, 90, apex.x(), apex.y(), kPi / 2 - opening / 4, opening / 2, 0, 80, 1.0);
    const auto r = DetectFeatures(analytic::Quantize(faces, 1.0, 7));
    ASSERT_TRUE(r.ok());
    EXPECT_TRUE(r->curves.empty()) << bend_deg << " deg";
    for (const double side : {-1.0, 1.0}) {
      // The edge from the apex, rising by half the bend on each side (image y down).
      const double a = kPi / 2 + side * 0.5 * opening;
      const Vec2d dir(std::cos(a), std::sin(a)), n(-dir.y(), dir.x());
      int on_edge = 0;
      for (const EmplLine& l : r->lines) {
        if (std::fabs(l.normal.dot(n)) < std::cos(kPi / 180) || std::fabs(l.SignedDistance(apex + 40 * dir)) > 1)
          continue;
        ++on_edge;
        double oe, ae;
        LineErrors(l, n, n.dot(apex), apex + 40 * dir, &oe, &ae);
        EXPECT_LT(std::fabs(oe), 0.1) << bend_deg << " deg, side " << side;
      }
      EXPECT_EQ(on_edge, 1) << bend_deg << " deg, side " << side;
    }
    double nearest = 1e9;
    for (const IdiPoint& p : r->points) nearest = std::min(nearest, (p.xy - apex).norm());
    EXPECT_LT(nearest, 0.5) << bend_deg << " deg";
  }
}

}  // namespace
}  // namespace idi

namespace idi {
namespace {

// In how many of `images` noisy copies of `clean` (white noise `noise` grey levels, seeds from `seed`,
// 8 bits) the detector with `options` gives an IDI point within `radius` px of `corner`.
int CornerFoundIn(const cv::Mat& clean,
                  double noise,
                  std::uint64_t seed,
                  int images,
                  const FeatureOptions& options,
                  const Vec2d& corner,
                  double radius) {
  int found = 0;
  for (int k = 0; k < images; ++k) {
    const auto r = DetectFeatures(analytic::Quantize(clean, noise, seed + static_cast<std::uint64_t>(k)), options);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    if (!r.ok()) continue;
    for (const IdiPoint& p : r->points) {
      if ((p.xy - corner).norm() < radius) {
        ++found;
        break;
      }
    }
  }
  return found;
}

// Where an edge ends at a junction its last stations fail the threshold over a few blur widths; at a
// blurred junction the confirmed segments stop more than the minimal 5 px short of it, and only
// extensions that grow with the edge's blur (EmplOptions::min_extension_blur_sigmas) still meet there.
TEST(EmplTest, ExtensionsGrowWithTheBlurSoBlurredCornersAreFound) {
  FeatureOptions scaled, fixed;
  fixed.empl.min_extension_blur_sigmas = 0;
  ASSERT_GT(scaled.empl.min_extension_blur_sigmas, 0);
  const Vec2d corner(50.3, 40.6);
  const double deg = 3.14159265358979323846 / 180;
  // An arrow junction of three faces: a weak edge (10 grey levels) beside two strong ones, sigma_b 2,
  // noise 3 grey levels. The strong edges' blur swamps the weak one's last stations.
  const cv::Mat clean =
      analytic::JunctionImage(120, 100, corner.x(), corner.y(), {0.0, 100 * deg, 200 * deg}, {60, 70, 130}, 2.0);
  constexpr int kImages = 20;
  const int found[2] = {CornerFoundIn(clean, 3.0, 700, kImages, scaled, corner, 2.0),
                        CornerFoundIn(clean, 3.0, 700, kImages, fixed, corner, 2.0)};
  std::printf("blurred junction found in %d of %d images with extensions of 3 blur sigmas, %d with 5 px\n",
              found[0],
              kImages,
              found[1]);
  // Measured: 17 and 13 of 20.
  EXPECT_GE(found[0], 16);
  EXPECT_LE(found[1], found[0] - 3) << "the case no longer needs the longer extensions";
}

// A bracket's face seen edge-on is a dark strip a few pixels wide: its strong edge runs inside the band
// of the weaker edge beside it. Each station must take the gradient peak nearest the line
// (EmplOptions::peak_proximity_sigma_px), not the strongest in the band, or the weak edge loses its
// stations to the strong one and stops short of the corner where it meets the face above.
TEST(EmplTest, AStrongEdgeBesideAWeakOneDoesNotTakeItsStations) {
  FeatureOptions nearest, strongest;
  strongest.empl.peak_proximity_sigma_px = 0;
  ASSERT_GT(nearest.empl.peak_proximity_sigma_px, 0);
  const Vec2d corner(60.3, 30.6);
  const double strip = 3.0;  // px
  // Above the corner's row a face at 125 grey levels; below it, left to right: a lit face, the dark strip, and a
  // grey face 40 grey levels above the strip (the weak edge, tilted 3 degrees). The strong edge's blur
  // still pulls the weak edge's fit about 0.6 px towards it (one blurred step per line is the model),
  // so the corner is only required within 2 px.
  const double tilt = std::tan(3.0 * 3.14159265358979323846 / 180);
  const auto level = [&](const Vec2d& q) {
    if (q.y() < corner.y()) return 125.0;
    const double x = q.x() - tilt * (q.y() - corner.y());
    return x < corner.x() - strip ? 140.0 : x < corner.x() ? 50.0 : 90.0;
  };
  const cv::Mat clean = analytic::AreaMeanImage(120, 100, level, 1.0);
  constexpr int kImages = 20;
  const int found[2] = {CornerFoundIn(clean, 2.0, 800, kImages, nearest, corner, 2.0),
                        CornerFoundIn(clean, 2.0, 800, kImages, strongest, corner, 2.0)};
  std::printf("corner beside a thin strip found in %d of %d images with the nearest peak, %d with the strongest\n",
              found[0],
              kImages,
              found[1]);
  // Measured: 20 and 0 of 20 (with the strongest peak the weak line is not found at all).
  EXPECT_GE(found[0], 18);
  EXPECT_LE(found[1], found[0] - 10);
}

// Lighting can make two faces' contrast fade along their edge. A station counts when its peak stands
// out of the gradient noise, not when it reaches a fraction of the line's typical strength: with 0.3
// of the median strength as the floor, this edge's confirmed segment stopped about 9 px short of its
// corner, beyond its extension, and the corner was found in 4 of 20 images (20 of 20 now).
TEST(EmplTest, AnEdgeWhoseContrastFadesStillReachesItsCorner) {
  const Vec2d corner(50.4, 20.7);
  // Above the corner a brighter face (25 grey levels); below it, the left face's contrast to the right
  // one (100) grows from 4 grey levels at the corner to 60 at 90 px below it.
  const auto level = [&](const Vec2d& q) {
    if (q.y() < corner.y()) return 125.0;
    if (q.x() >= corner.x()) return 100.0;
    return 104.0 + 56.0 * std::min(1.0, (q.y() - corner.y()) / 90.0);
  };
  const cv::Mat clean = analytic::AreaMeanImage(100, 100, level, 1.0);
  constexpr int kImages = 20;
  const int found = CornerFoundIn(clean, 1.5, 900, kImages, FeatureOptions{}, corner, 1.0);
  std::printf("corner at the faint end of an edge found in %d of %d images\n", found, kImages);
  EXPECT_GE(found, 18);
}

// A bright plate 9 px high from kWeakEdgeCorner to the right; below the corner's row, the face right of
// the weak edge is 12 grey levels above the one left of it.
const Vec2d kWeakEdgeCorner(40.4, 40.3);
cv::Mat WeakEdgeRunningOnFromAStrongOne() {
  const Vec2d corner = kWeakEdgeCorner;
  const auto level = [&](const Vec2d& q) {
    if (q.y() < corner.y()) return q.y() >= corner.y() - 9 && q.x() >= corner.x() && q.x() < 110 ? 180.0 : 80.0;
    return q.x() >= corner.x() ? 92.0 : 80.0;
  };
  return analytic::AreaMeanImage(120, 100, level, 1.0);
}

// A weak edge can run on from a strong collinear one: a plate's end, too short to be a line of its
// own, continues as the faint edge between two faces below it. With eq. 7.29's mean as the local
// level, the strong stretch raised the threshold over the next threshold_window_px of the weak edge,
// whose confirmed segment then stopped about 10 px short of the junction, beyond its 5 px extension; the
// median of the stations' band means (EmplOptions::threshold_median) does not see a short strong stretch.
// (The thresholds are compared without the gap test of IdiOptions::max_gap_px, which bridges such a gap
// on its own: the next test.)
TEST(EmplTest, AWeakEdgeRunningOnFromAStrongOneReachesTheJunction) {
  FeatureOptions median, mean;
  mean.empl.threshold_median = false;
  median.idi.max_gap_px = mean.idi.max_gap_px = 0;
  ASSERT_TRUE(median.empl.threshold_median);
  const Vec2d corner = kWeakEdgeCorner;
  const cv::Mat clean = WeakEdgeRunningOnFromAStrongOne();
  constexpr int kImages = 20;
  const int found[2] = {CornerFoundIn(clean, 1.5, 1000, kImages, median, corner, 1.0),
                        CornerFoundIn(clean, 1.5, 1000, kImages, mean, corner, 1.0)};
  std::printf(
      "junction of a weak edge running on from a strong one found in %d of %d images with the median level, "
      "%d with the mean\n",
      found[0],
      kImages,
      found[1]);
  // Measured: 20 and 0 of 20.
  EXPECT_GE(found[0], 18);
  EXPECT_LE(found[1], found[0] - 10);
}

// The same weak edge with the mean as the local level: its segment stops about 10 px short of the
// junction, and the gap test (IdiOptions::max_gap_px) finds the edge's gradient going on across the gap
// and keeps the junction; without it the junction is lost.
TEST(EmplTest, AGapThatCarriesTheEdgeIsBridged) {
  FeatureOptions gap, no_gap;
  gap.empl.threshold_median = no_gap.empl.threshold_median = false;
  no_gap.idi.max_gap_px = 0;
  ASSERT_GT(gap.idi.max_gap_px, 0);
  const Vec2d corner = kWeakEdgeCorner;
  const cv::Mat clean = WeakEdgeRunningOnFromAStrongOne();
  constexpr int kImages = 20;
  const int found[2] = {CornerFoundIn(clean, 1.5, 1000, kImages, gap, corner, 1.0),
                        CornerFoundIn(clean, 1.5, 1000, kImages, no_gap, corner, 1.0)};
  std::printf(
      "junction across a gap found in %d of %d images with the gap test, %d without\n", found[0], kImages, found[1]);
  // Measured: 19 and 0 of 20.
  EXPECT_GE(found[0], 17);
  EXPECT_LE(found[1], 3);
}

// A faint edge that really ends 10 px before a strong one (at a faint L-corner): nothing in the gap
// carries it, so its line does not reach the strong edge, and no point is made where the two lines
// cross. (With extensions long enough to reach it the point is made, and so it is when the gap test
// accepts every gap: the scene can show the failure.)
TEST(EmplTest, AGapWithoutTheEdgeIsNotBridged) {
  const Vec2d cross(50.4, 30.3);
  const auto level = [&](const Vec2d& q) {
    if (q.y() < cross.y()) return 60.0;  // the strong edge: y = 30.3, 120 DN
    if (q.y() < cross.y() + 10) return 180.0;
    return q.x() >= cross.x() ? 204.0 : 180.0;  // the faint edge x = 50.4 from y = 40.3 down, 24 DN
  };
  const cv::Mat clean = analytic::AreaMeanImage(100, 100, level, 1.0);
  // Every point beyond a segment's end is kept, so that the faint L-corner nearer the end does not
  // stand in for the gap test (IdiOptions::first_point_beyond_end would drop the crossing behind it).
  FeatureOptions options;
  options.idi.first_point_beyond_end = false;
  ASSERT_GT(options.idi.max_gap_px, 0);
  FeatureOptions long_extensions = options;
  long_extensions.idi.max_gap_px = 0;
  long_extensions.empl.min_extension_px = 14;
  int lines_seen = 0, crossings = 0, crossings_long = 0;
  for (int k = 0; k < 20; ++k) {
    const cv::Mat image = analytic::Quantize(clean, 1.5, 2000 + static_cast<std::uint64_t>(k));
    const auto r = DetectFeatures(image, options);
    const auto r_long = DetectFeatures(image, long_extensions);
    ASSERT_TRUE(r.ok() && r_long.ok());
    bool seen = false;
    for (const EmplLine& l : r->lines) {
      seen = seen || (std::abs(l.normal.x()) > 0.99 && std::abs(l.SignedDistance(Vec2d(cross.x(), 70))) < 1);
    }
    lines_seen += seen;
    for (const IdiPoint& p : r->points) crossings += (p.xy - cross).norm() < 3;
    for (const IdiPoint& p : r_long->points) crossings_long += (p.xy - cross).norm() < 3;
  }
  std::printf(
      "faint edge found in %d of 20 images; a point where it would cross the strong one in %d (%d with "
      "14 px extensions)\n",
      lines_seen,
      crossings,
      crossings_long);
  EXPECT_GE(lines_seen, 18);
  EXPECT_EQ(crossings, 0);
  EXPECT_GE(crossings_long, 15);
}

// An edge that steps between two levels 3 px apart every 20 px is not one straight edge. Fitted as one,
// the line runs between the levels with its points 1.4 px RMS from it; EmplOptions::max_fit_rms_px drops
// such a fit rather than report a line that lies on neither level. (Nothing is reported on this edge
// then: the 20 px pieces, a few of which came out beside the long line without the limit, are not
// searched again. Measured: 0 lines over 1 px RMS with the limit, 10 without, worst 1.45 px.)
TEST(EmplTest, AFitWhosePointsScatterOverTheBandIsNotALine) {
  FeatureOptions limited, unlimited;
  unlimited.empl.max_fit_rms_px = 0;
  ASSERT_GT(limited.empl.max_fit_rms_px, 0);
  const auto level = [](const Vec2d& q) {
    const double edge_y = 50.3 + (std::fmod(q.x(), 40.0) < 20.0 ? 1.5 : -1.5);
    return q.y() < edge_y ? 60.0 : 160.0;
  };
  const cv::Mat clean = analytic::AreaMeanImage(120, 100, level, 1.0);
  constexpr int kImages = 10;
  int scattered[2] = {0, 0};
  double worst_rms[2] = {0, 0};
  for (int k = 0; k < kImages; ++k) {
    const cv::Mat image = analytic::Quantize(clean, 2.0, 1100 + static_cast<std::uint64_t>(k));
    for (int which = 0; which < 2; ++which) {
      const auto r = DetectFeatures(image, which == 0 ? limited : unlimited);
      ASSERT_TRUE(r.ok()) << r.status().ToString();
      for (const EmplLine& l : r->lines) {
        worst_rms[which] = std::max(worst_rms[which], l.fit_rms_px);
        if (l.fit_rms_px > 1.0) ++scattered[which];
      }
    }
  }
  std::printf(
      "lines with points more than 1 px RMS from them: %d with the limit (worst %.2f px), %d without "
      "(worst %.2f px), in %d images\n",
      scattered[0],
      worst_rms[0],
      scattered[1],
      worst_rms[1],
      kImages);
  EXPECT_EQ(scattered[0], 0);
  EXPECT_LE(worst_rms[0], limited.empl.max_fit_rms_px);
  EXPECT_GE(scattered[1], kImages / 2);
}

}  // namespace
}  // namespace idi
