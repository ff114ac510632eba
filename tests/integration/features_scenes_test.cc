// The vision front end on the twin's object scenes (issue 4's corner statistics, features_bench section
// D): boxes, prisms and L-brackets on a table before a wall, rendered with the default noise and blur,
// 12 scenes seen from 1.2 m, each with 3 draws of the sensor noise. Guards the rates measured there; the
// goal (99 % found, under 2 % spurious) is reached for spurious points at sigma_b 1, not yet for the rest.
//
// The rates are pooled over noise draws because one draw is too few: over 9 draws of the same 12 scenes
// the spurious points of a row ranged from 3 to 8 (no clutter) and from 2 to 14 (sigma_b 2), and a limit
// set from one draw passed or failed with the draw, not with the code.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "shared/features/features.h"
#include "shared/sim/render/render.h"
#include "tests/support/object_scenes.h"
#include "tests/support/wireframe_views.h"

namespace idi {
namespace {

// The corners of features_bench D's rows without distortion: 12 scenes each, without or with clutter (a
// textured table, wall and faces), PSF sigma_b 1 or 2, each scene with the noise draws 0, 1 and 2 of
// features_bench --draws (seed 900 + scene + 1000 x draw).
test::CornerScore ScoreScenes(bool clutter, const FeatureOptions& options, double blur = 1.0) {
  CameraModel cam;
  cam.width = 640;
  cam.height = 480;
  cam.params = {700, 700, 319.5, 239.5, 0, 0, 0, 0, 0};
  auto det = FeatureDetector::Create(options, std::nullopt);
  EXPECT_TRUE(det.ok());
  test::CornerScore score;
  if (!det.ok()) return score;
  std::mt19937 rng(clutter * 10 + static_cast<unsigned>(blur));  // as features_bench D seeds its rows
  for (int k = 0; k < 12; ++k) {
    const sim::Scene scene = test::RandomObjectScene(rng, clutter);
    const double az = 0.3 * (k % 5) - 0.6;
    const Rigid3d cam_from_world = test::LookAt(Vec3d(1100 * std::sin(az), -1100 * std::cos(az), 950), Vec3d(0, 0, 60));
    for (std::uint64_t draw = 0; draw < 3; ++draw) {
      sim::RenderOptions o;
      o.psf_sigma_px = blur;
      o.seed = 900 + static_cast<std::uint64_t>(k) + 1000 * draw;
      sim::GroundTruth truth;
      auto img = sim::RenderScene(scene, cam, cam_from_world, o, &truth);
      EXPECT_TRUE(img.ok()) << img.status().ToString();
      if (!img.ok()) continue;
      auto r = det->Detect(*img);
      EXPECT_TRUE(r.ok()) << r.status().ToString();
      if (!r.ok()) continue;
      const auto same_pixel = [](const Vec2d& px) { return px; };  // no distortion
      score.Add(test::ScoreCorners(truth, *r, same_pixel, blur));
    }
  }
  return score;
}

sim::TruthLine Line(int id, const Vec2d& a, const Vec2d& b, double contrast_dn = 40) {
  sim::TruthLine l;
  l.id = id;
  l.p1_px = a;
  l.p2_px = b;
  l.length_px = (b - a).norm();
  l.contrast_dn = contrast_dn;
  return l;
}

// The benchmark's "resolvable" (features_bench D's second table): a line needs 20 px that keep more than
// 2 sigma_b + 1 px from every other edge of >= 10 DN.
TEST(FeatureScenesTest, AnEdgeBesideAnotherIsResolvableOnlyWhereTheyPartByMoreThanTheBlur) {
  const sim::TruthLine edge = Line(1, Vec2d(100, 100), Vec2d(100, 160));
  // A parallel edge 2.5 px away over the whole length: one ridge at sigma_b 1 (clearance 3 px).
  EXPECT_FALSE(test::Resolvable(edge, {edge, Line(2, Vec2d(102.5, 100), Vec2d(102.5, 160))}, 1.0));
  // 4 px away it is apart at sigma_b 1, not at sigma_b 2 (clearance 5 px).
  const std::vector<sim::TruthLine> four_px = {edge, Line(2, Vec2d(104, 100), Vec2d(104, 160))};
  EXPECT_TRUE(test::Resolvable(edge, four_px, 1.0));
  EXPECT_FALSE(test::Resolvable(edge, four_px, 2.0));
  // A faint edge beside it does not count (under 10 DN).
  EXPECT_TRUE(test::Resolvable(edge, {edge, Line(2, Vec2d(101, 100), Vec2d(101, 160), 6)}, 1.0));
  // A right-angled corner: only the first 3 px are near the other leg.
  EXPECT_TRUE(test::Resolvable(edge, {edge, Line(2, Vec2d(100, 100), Vec2d(160, 100))}, 1.0));
  // A 6 deg wedge of 40 px legs: the legs part by 3 px only 29 px from the corner, leaving 11 px.
  const double tan6 = std::tan(6.0 * 3.14159265358979323846 / 180);
  const sim::TruthLine leg = Line(1, Vec2d(100, 100), Vec2d(100, 140));
  EXPECT_FALSE(test::Resolvable(leg, {leg, Line(2, Vec2d(100, 100), Vec2d(100 + 40 * tan6, 140))}, 1.0));
  // The same angle as a bend (legs on either side of the vertex) keeps them apart.
  EXPECT_TRUE(test::Resolvable(leg, {leg, Line(2, Vec2d(100, 100), Vec2d(100 + 40 * tan6, 60))}, 1.0));
  // A leg ending at a right-angled corner is near the other leg for its first 3 px (samples at 0-3 px):
  // from 4 to 23 px it is clear over 19 px, not enough; to 24 px, over 20 px.
  const sim::TruthLine foot = Line(2, Vec2d(100, 100), Vec2d(160, 100));
  const sim::TruthLine leg23 = Line(1, Vec2d(100, 100), Vec2d(100, 123));
  const sim::TruthLine leg24 = Line(1, Vec2d(100, 100), Vec2d(100, 124));
  EXPECT_FALSE(test::Resolvable(leg23, {leg23, foot}, 1.0));
  EXPECT_TRUE(test::Resolvable(leg24, {leg24, foot}, 1.0));
  // Shorter than 20 px: never.
  const sim::TruthLine stub = Line(1, Vec2d(100, 100), Vec2d(100, 118));
  EXPECT_FALSE(test::Resolvable(stub, {stub}, 1.0));
}

std::string Misses(const test::CornerScore& s) {
  return std::to_string(s.found) + " of " + std::to_string(s.total) +
         "; missed: " + std::to_string(s.miss_line_not_found) + " with a line not found, " +
         std::to_string(s.miss_segment_short) + " with a segment short of the corner, " + std::to_string(s.miss_other) +
         " other";
}

TEST(FeatureScenesTest, CornersOfObjectScenesAreFoundWithFewSpuriousPoints) {
  for (const bool clutter : {false, true}) {
    const test::CornerScore score = ScoreScenes(clutter, FeatureOptions{});
    ASSERT_GT(score.total, 450);
    const double found = static_cast<double>(score.found) / score.total;
    const double spurious = static_cast<double>(score.spurious) / score.points;
    std::printf("clutter %d: %d of %d corners found, %d of %d points spurious\n",
                clutter,
                score.found,
                score.total,
                score.spurious,
                score.points);
    // Measured over draws 0-2: without clutter 729 of 783 (0.931) found, 16 of 815 points (0.020)
    // spurious; with clutter 693 of 765 (0.906) and 10 of 777 (0.013). Over draws 3-5 and 6-8: found 0.932
    // and 0.932, 0.907 and 0.907; spurious 0.015 and 0.016, 0.017 and 0.022. (With draw 0 alone, as
    // before: 245 of 261 and 233 of 255 found, 3 of 273 and 2 of 258 spurious.)
    EXPECT_GE(found, clutter ? 0.89 : 0.915) << "clutter " << clutter << ": " << Misses(score);
    EXPECT_LE(spurious, 0.03) << "clutter " << clutter << ": " << score.spurious << " of " << score.points;
  }
}

// With clutter and a PSF of sigma_b 2 the segments stop further short of their corners; extensions that
// grow with the edge's blur (EmplOptions::min_extension_blur_sigmas) still meet there.
TEST(FeatureScenesTest, BlurredCornersAreFoundByExtensionsThatGrowWithTheBlur) {
  const test::CornerScore score = ScoreScenes(true, FeatureOptions{}, 2.0);
  ASSERT_GT(score.total, 450);
  const double found = static_cast<double>(score.found) / score.total;
  const double spurious = static_cast<double>(score.spurious) / score.points;
  std::printf(
      "%d of %d corners found, %d of %d points spurious\n", score.found, score.total, score.spurious, score.points);
  // Measured over draws 0-2: 664 of 768 (0.865) found, 12 of 732 points (0.016) spurious; over draws 3-5
  // and 6-8: 0.862 and 0.858 found, 0.034 and 0.034 spurious: the 2 % goal is not met at sigma_b 2 (9
  // draws: 0.028). With extensions of at least 5 px only (before the nearest-peak stations, draw 0):
  // 213 of 256 (0.832) found.
  EXPECT_GE(found, 0.845) << Misses(score);
  EXPECT_LE(spurious, 0.045) << score.spurious << " of " << score.points;
}

// A straight edge between two junctions bends at both ends (its last pixels are pulled towards the
// other edges); a run too short to be split in two was taken for an arc and dropped. The curve test
// without the run's ends keeps those edges: switching it off loses corners on the same scenes.
TEST(FeatureScenesTest, ShortEdgesBetweenJunctionsAreLinesNotCurves) {
  FeatureOptions whole_run;
  whole_run.empl.curve_end_trim_px = 0;
  ASSERT_GT(FeatureOptions{}.empl.curve_end_trim_px, 0);
  const test::CornerScore trimmed = ScoreScenes(true, FeatureOptions{});
  const test::CornerScore whole = ScoreScenes(true, whole_run);
  std::printf("trimmed %d, whole run %d of %d corners found\n", trimmed.found, whole.found, trimmed.total);
  // Measured over draws 0-2: 693 and 682 of 765; draws 3-5: 694 and 686; 6-8: 694 and 682 (the trimmed
  // test finds 8-12 more; 5 more with another seeding of the sensor's generator). One draw alone gave 1 to
  // 5 more, too few to tell the two apart.
  EXPECT_GE(trimmed.found, whole.found + 4) << "trimmed " << Misses(trimmed) << "; whole run " << Misses(whole);
}

}  // namespace
}  // namespace idi
