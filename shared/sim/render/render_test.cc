#include "shared/sim/render/render.h"

#include <gtest/gtest.h>

#include "shared/sim/render/shapes.h"

namespace idi::sim {
namespace {

TEST(RenderTest, BoxOnWallRenders) {
  Scene scene;
  scene.solids.push_back(MakeRectangle("wall", Vec3d(0, 0, 5000), Vec3d::UnitX(), Vec3d::UnitY(), 5000, 5000, Gray(0.5)));
  scene.solids.push_back(MakeBox("box", Translation(0.0, 0.0, 3000.0) * RotX(-1.2) * RotZ(0.4), Vec3d(400, 300, 200), Gray(0.8)));
  CameraModel cam;
  RenderOptions opt;
  GroundTruth truth;
  auto img = RenderScene(scene, cam, Rigid3d::Identity(), opt, &truth);
  ASSERT_TRUE(img.ok()) << img.status().ToString();
  EXPECT_EQ(img->rows, 480);
  EXPECT_EQ(img->cols, 640);
  EXPECT_FALSE(truth.lines.empty());
}

// An exposure or a laser spot so bright that a pixel's value overflows a float is refused (the
// infinite pixel plus its shot noise was NaN, stored as 0: saturated pixels came out black).
TEST(RenderTest, ExposuresThatOverflowAFloatAreRefused) {
  Scene scene;
  scene.solids.push_back(
      MakeRectangle("wall", Vec3d(0, 0, 5000), Vec3d::UnitX(), Vec3d::UnitY(), 5000, 5000, Gray(0.5)));
  RenderOptions opt;
  opt.exposure_dn = 1e39;
  EXPECT_EQ(RenderScene(scene, CameraModel{}, Rigid3d::Identity(), opt).status().code(), StatusCode::kInvalidArgument);
  scene.laser_spots.push_back({Vec3d(0, 0, 5000), 3.0, 1e39, Vec3d::Ones()});
  EXPECT_EQ(RenderScene(scene, CameraModel{}, Rigid3d::Identity(), {}).status().code(), StatusCode::kInvalidArgument);
}

// Pixels are integrated independently, so any number of threads gives the very same image (textured
// floor and wall, a box with edges crossing tile rows, lens distortion, a laser spot, colour).
TEST(RenderTest, ThreadCountDoesNotChangeTheImage) {
  Scene scene;
  Material floor = Gray(0.4);
  floor.texture.tile_size = 300;
  floor.texture.grout_width = 6;
  floor.texture.tile_jitter = 0.2;
  floor.texture.noise_amplitude = 0.1;
  floor.texture.noise_scale = 120;
  scene.solids.push_back(MakeRectangle("floor", Vec3d(0, 600, 4000), Vec3d::UnitX(), Vec3d::UnitZ(), 4000, 4000, floor));
  Material wall = Rgb(0.5, 0.6, 0.4);
  wall.texture.noise_amplitude = 0.2;
  wall.texture.noise_scale = 400;
  scene.solids.push_back(MakeRectangle("wall", Vec3d(0, 0, 7000), Vec3d::UnitX(), Vec3d::UnitY(), 6000, 6000, wall));
  scene.solids.push_back(
      MakeBox("box", Translation(0.0, 200.0, 3000.0) * RotX(-1.2) * RotZ(0.4), Vec3d(500, 400, 300), Gray(0.8)));
  scene.laser_spots.push_back({Vec3d(300, 0, 7000), 8.0, 4.0});
  CameraModel cam;
  cam.params[kK1] = -0.15;
  for (const bool color : {false, true}) {
    RenderOptions one;
    one.color = color;
    one.threads = 1;
    RenderOptions three = one;
    three.threads = 3;
    auto a = RenderIrradiance(scene, cam, Rigid3d::Identity(), one);
    auto b = RenderIrradiance(scene, cam, Rigid3d::Identity(), three);
    ASSERT_TRUE(a.ok() && b.ok());
    ASSERT_EQ(a->size(), b->size());
    EXPECT_EQ(cv::norm(*a, *b, cv::NORM_INF), 0.0) << (color ? "colour" : "gray");
    auto c = RenderScene(scene, cam, Rigid3d::Identity(), one);
    auto d = RenderScene(scene, cam, Rigid3d::Identity(), three);
    ASSERT_TRUE(c.ok() && d.ok());
    EXPECT_EQ(cv::norm(*c, *d, cv::NORM_INF), 0.0);
  }
  RenderOptions bad;
  bad.threads = -1;
  EXPECT_FALSE(RenderScene(scene, cam, Rigid3d::Identity(), bad).ok());
}

}  // namespace
}  // namespace idi::sim
