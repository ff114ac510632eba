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

}  // namespace
}  // namespace idi::sim
