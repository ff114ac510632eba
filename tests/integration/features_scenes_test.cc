// The vision front end on the twin's object scenes (issue 4's corner statistics, features_bench section
// D): boxes, prisms and L-brackets on a table before a wall, rendered with the default noise and blur,
// 12 scenes seen from 1.2 m. Guards the rates measured there; the goal (99 % found, under 2 %
// spurious) is not reached yet.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "shared/features/features.h"
#include "shared/sim/render/render.h"
#include "tests/support/object_scenes.h"
#include "tests/support/wireframe_views.h"

namespace idi {
namespace {

TEST(FeatureScenesTest, CornersOfObjectScenesAreFoundWithFewSpuriousPoints) {
  CameraModel cam;
  cam.width = 640;
  cam.height = 480;
  cam.params = {700, 700, 319.5, 239.5, 0, 0, 0, 0, 0};
  auto det = FeatureDetector::Create(FeatureOptions{}, std::nullopt);
  ASSERT_TRUE(det.ok());
  std::mt19937 rng(1);  // features_bench D, first row (no clutter, no distortion, sigma_b 1)
  test::CornerScore score;
  for (int k = 0; k < 12; ++k) {
    const sim::Scene scene = test::RandomObjectScene(rng, false);
    const double az = 0.3 * (k % 5) - 0.6;
    const Rigid3d cam_from_world = test::LookAt(Vec3d(1100 * std::sin(az), -1100 * std::cos(az), 950), Vec3d(0, 0, 60));
    sim::RenderOptions o;
    o.seed = 900 + static_cast<std::uint64_t>(k);
    sim::GroundTruth truth;
    auto img = sim::RenderScene(scene, cam, cam_from_world, o, &truth);
    ASSERT_TRUE(img.ok()) << img.status().ToString();
    auto r = det->Detect(*img);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    score.Add(test::ScoreCorners(truth, *r, [](const Vec2d& px) { return px; }));
  }
  ASSERT_GT(score.total, 150);
  const double found = static_cast<double>(score.found) / score.total;
  const double spurious = static_cast<double>(score.spurious) / score.points;
  // Measured: 163 of 196 (0.832) found, 18 of 216 points (0.083) spurious. Before the bent-run split
  // (empl.cc, curved()), 158 (0.806) and 24 of 216 (0.111).
  EXPECT_GE(found, 0.82) << score.found << " of " << score.total << "; missed: " << score.miss_line_not_found
                         << " with a line not found, " << score.miss_segment_short
                         << " with a segment short of the corner, " << score.miss_other << " other";
  EXPECT_LE(spurious, 0.10) << score.spurious << " of " << score.points;
}

}  // namespace
}  // namespace idi
