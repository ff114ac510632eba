// The vision front end on the twin's object scenes (issue 4's corner statistics, features_bench section
// D): boxes, prisms and L-brackets on a table before a wall, rendered with the default noise and blur,
// 12 scenes seen from 1.2 m. Guards the rates measured there; the goal (99 % found, under 2 %
// spurious) is reached for spurious points without clutter and at sigma_b 2, not yet for the rest.
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
// textured table, wall and faces), PSF sigma_b 1 or 2.
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
    sim::RenderOptions o;
    o.psf_sigma_px = blur;
    o.seed = 900 + static_cast<std::uint64_t>(k);
    sim::GroundTruth truth;
    auto img = sim::RenderScene(scene, cam, cam_from_world, o, &truth);
    EXPECT_TRUE(img.ok()) << img.status().ToString();
    if (!img.ok()) continue;
    auto r = det->Detect(*img);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    if (!r.ok()) continue;
    score.Add(test::ScoreCorners(truth, *r, [](const Vec2d& px) { return px; }));
  }
  return score;
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
    ASSERT_GT(score.total, 150);
    const double found = static_cast<double>(score.found) / score.total;
    const double spurious = static_cast<double>(score.spurious) / score.points;
    std::printf("clutter %d: %d of %d corners found, %d of %d points spurious\n",
                clutter,
                score.found,
                score.total,
                score.spurious,
                score.points);
    // Measured without clutter: 241 of 261 (0.923) found, 4 of 267 points (0.015) spurious; with clutter
    // 227 of 255 (0.890) and 7 of 256 (0.027). Before each station took the gradient peak nearest the
    // line (EmplOptions::peak_proximity_sigma_px) and a noise floor instead of 0.3 of the line's median
    // strength: 236 and 226 found. Without the curve test's end trim (EmplOptions::curve_end_trim_px = 0)
    // 235 and 222 found then; with 4 px extensions, 231 and 222. Before the scenes kept their solids apart
    // (tests/support/object_scenes.cc) the points where solids cut each other counted as spurious: 9 %.
    EXPECT_GE(found, clutter ? 0.88 : 0.91) << "clutter " << clutter << ": " << Misses(score);
    EXPECT_LE(spurious, clutter ? 0.035 : 0.025)
        << "clutter " << clutter << ": " << score.spurious << " of " << score.points;
  }
}

// With clutter and a PSF of sigma_b 2 the segments stop further short of their corners; extensions that
// grow with the edge's blur (EmplOptions::min_extension_blur_sigmas) still meet there.
TEST(FeatureScenesTest, BlurredCornersAreFoundByExtensionsThatGrowWithTheBlur) {
  const test::CornerScore score = ScoreScenes(true, FeatureOptions{}, 2.0);
  ASSERT_GT(score.total, 150);
  const double found = static_cast<double>(score.found) / score.total;
  const double spurious = static_cast<double>(score.spurious) / score.points;
  std::printf(
      "%d of %d corners found, %d of %d points spurious\n", score.found, score.total, score.spurious, score.points);
  // Measured: 224 of 256 (0.875) found, 2 of 242 points spurious; with extensions of at least 5 px only
  // (before the nearest-peak stations), 213 (0.832) found.
  EXPECT_GE(found, 0.86) << Misses(score);
  EXPECT_LE(spurious, 0.02) << score.spurious << " of " << score.points;
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
  // Measured: 227 and 223 of 255 (before the nearest-peak stations 226 and 222).
  EXPECT_GE(trimmed.found, whole.found + 3) << "trimmed " << Misses(trimmed) << "; whole run " << Misses(whole);
}

}  // namespace
}  // namespace idi
