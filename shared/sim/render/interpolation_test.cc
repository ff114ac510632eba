// The interpolated shading of covered tiles (RenderOptions::shading_tolerance_dn) against shading every
// pixel exactly (tolerance 0), on the vehicle's view of a taped floor: the same image to within the
// tolerance, the same 8-bit image to within one grey level, the same tape edges.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include <cmath>
#include <vector>

#include "shared/sim/render/render.h"
#include "shared/sim/render/shapes.h"

namespace idi::sim {
namespace {

// The tolerance the tests interpolate with (the default, 0, shades every pixel exactly).
constexpr double kTolerance = 0.25;

// A textured floor (m) with a straight tape along +x and a curved one, as the rmp twin lays them.
Scene GroundScene(bool gradient) {
  Scene scene;
  Material floor = Gray(0.35);
  floor.texture.noise_amplitude = 0.15;
  floor.texture.noise_scale = 0.2;
  floor.texture.seed = 3;
  scene.solids.push_back(MakeRectangle("floor", Vec3d(2, 0, 0), Vec3d::UnitX(), Vec3d::UnitY(), 10, 10, floor));
  auto straight = MakeTapeStrip("tape0", {{0.5, 0.0}, {4.0, 0.0}}, 0.05, 0.0, Gray(0.85));
  std::vector<Vec2d> arc;
  for (int k = 0; k <= 12; ++k) arc.emplace_back(1.2 + 0.1 * k, -0.4 - 0.3 * std::sin(0.2 * k));
  auto curve = MakeTapeStrip("tape1", arc, 0.05, 0.0, Gray(0.85));
  EXPECT_TRUE(straight.ok() && curve.ok());
  scene.solids.push_back(*straight);
  scene.solids.push_back(*curve);
  if (gradient) {
    scene.lighting.gradient.origin = Vec3d(1.5, 0, 0);
    scene.lighting.gradient.gradient = Vec3d(-0.15, 0.1, 0);
  }
  return scene;
}

// The rmp rig's camera: 1.2 m above the floor at the origin, looking along +x, 55 deg down.
Rigid3d CamFromWorld(double y_m) {
  const double c = std::cos(55.0 * M_PI / 180), s = std::sin(55.0 * M_PI / 180);
  Mat3d world_from_cam;
  world_from_cam.col(0) = Vec3d(0, -1, 0);
  world_from_cam.col(1) = Vec3d(-s, 0, -c);
  world_from_cam.col(2) = Vec3d(c, 0, -s);
  Rigid3d t;
  t.rotation = world_from_cam.transpose();
  t.translation = -(t.rotation * Vec3d(0, y_m, 1.2));
  return t;
}

CameraModel RigCamera(bool distorted) {
  CameraModel cam;
  cam.params = {320.0, 320.0, 319.5, 239.5, 0, 0, 0, 0, 0};
  // Barrel distortion the model holds over the whole 90 deg image (k1 = -0.1 folds back before the
  // corners at this focal length, and such a camera is refused).
  if (distorted) cam.params[kK1] = -0.05;
  return cam;
}

// Sub-pixel position of the strongest step along row `r` within [c0, c1): where the profile crosses
// the level halfway between the two sides (3 px either side of the steepest pixel pair).
double EdgeInRow(const cv::Mat& img, int r, int c0, int c1) {
  int best = -1;
  double best_g = 0;
  for (int c = c0; c + 1 < c1; ++c) {
    const double g = std::abs(img.at<float>(r, c + 1) - img.at<float>(r, c));
    if (g > best_g) {
      best_g = g;
      best = c;
    }
  }
  if (best_g < 10) return -1;  // no edge here
  const double mid = 0.5 * (img.at<float>(r, best - 3) + img.at<float>(r, best + 4));
  for (int c = best - 2; c <= best + 2; ++c) {
    const double a = img.at<float>(r, c) - mid, b = img.at<float>(r, c + 1) - mid;
    if ((a <= 0) != (b <= 0)) return c + a / (a - b);
  }
  return -1;
}

TEST(InterpolationTest, InterpolatedShadingMatchesExactShading) {
  for (const bool distorted : {false, true}) {
    for (const bool gradient : {false, true}) {
      SCOPED_TRACE(testing::Message() << "distorted " << distorted << " gradient " << gradient);
      const Scene scene = GroundScene(gradient);
      const CameraModel cam = RigCamera(distorted);
      RenderOptions fast;
      fast.sensor.noise = false;
      fast.vignetting = 0.3;
      fast.shading_tolerance_dn = kTolerance;
      RenderOptions exact = fast;
      exact.shading_tolerance_dn = 0;
      for (const double y_m : {0.0, 0.15}) {
        auto a = RenderIrradiance(scene, cam, CamFromWorld(y_m), fast);
        auto b = RenderIrradiance(scene, cam, CamFromWorld(y_m), exact);
        ASSERT_TRUE(a.ok() && b.ok());
        const double max_diff = cv::norm(*a, *b, cv::NORM_INF);
        EXPECT_LE(max_diff, fast.shading_tolerance_dn);
        EXPECT_GT(max_diff, 0.0) << "the interpolation was never used";
        // Tape edges where the tapes cross image rows.
        int edges = 0;
        for (int r = 20; r < 300; r += 20) {
          for (const auto& [c0, c1] : {std::pair{150, 320}, std::pair{320, 500}}) {
            const double ea = EdgeInRow(*a, r, c0, c1), eb = EdgeInRow(*b, r, c0, c1);
            EXPECT_NEAR(ea, eb, 0.005) << "row " << r << " from column " << c0;
            if (ea > 0) ++edges;
          }
        }
        EXPECT_GE(edges, 8);
        // The 8-bit images.
        auto c = RenderScene(scene, cam, CamFromWorld(y_m), fast);
        auto d = RenderScene(scene, cam, CamFromWorld(y_m), exact);
        ASSERT_TRUE(c.ok() && d.ok());
        EXPECT_LE(cv::norm(*c, *d, cv::NORM_INF), 1.0);
      }
    }
  }
}

TEST(InterpolationTest, TilesWithGroutAndSpotlightsAreShadedPerPixel) {
  Scene scene = GroundScene(false);
  scene.solids[0].materials[0].texture.tile_size = 0.3;
  scene.solids[0].materials[0].texture.grout_width = 0.006;
  RenderOptions fast;
  fast.sensor.noise = false;
  fast.shading_tolerance_dn = kTolerance;
  RenderOptions exact = fast;
  exact.shading_tolerance_dn = 0;
  auto a = RenderIrradiance(scene, RigCamera(false), CamFromWorld(0), fast);
  auto b = RenderIrradiance(scene, RigCamera(false), CamFromWorld(0), exact);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(cv::norm(*a, *b, cv::NORM_INF), 0.0);
  scene = GroundScene(false);
  SpotLight spot;
  spot.position = Vec3d(2, 0, 2);
  spot.reference_distance = 2;
  scene.lighting.spotlights.push_back(spot);
  a = RenderIrradiance(scene, RigCamera(false), CamFromWorld(0), fast);
  b = RenderIrradiance(scene, RigCamera(false), CamFromWorld(0), exact);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(cv::norm(*a, *b, cv::NORM_INF), 0.0);
}

TEST(InterpolationTest, ToleranceIsChecked) {
  RenderOptions o;
  o.shading_tolerance_dn = -0.1;
  EXPECT_NE(o.Check().message().find("shading_tolerance_dn"), std::string::npos);
  o.shading_tolerance_dn = 2;
  EXPECT_FALSE(o.Check().ok());
}

}  // namespace
}  // namespace idi::sim
