// ShadeBatch (several points per instruction where the CPU has AVX2) against Shade (one point at a
// time): the same radiance to the last bit (and ShadeBatchLuma the same float luma), for a textured floor under an
// illumination gradient seen by the rmp rig's camera, with and without lens distortion, in colour, for batch sizes that
// are and are not multiples of four, and where the noise lattice's coordinates are too large for the vector path (it
// must then hand the points to Shade). On a CPU without AVX2 both are Shade and the test checks only that the batch
// covers every point.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "shared/sim/render/raster_internal.h"
#include "shared/sim/render/shapes.h"

namespace idi::sim::internal {
namespace {

Scene FloorScene(double noise_scale_m, bool gradient) {
  Scene scene;
  Material floor{Vec3d(0.42, 0.35, 0.27), {}};
  floor.texture.noise_amplitude = 0.15;
  floor.texture.noise_scale = noise_scale_m;
  floor.texture.noise_octaves = 6;
  floor.texture.seed = 11;
  scene.solids.push_back(MakeRectangle("floor", Vec3d(2, 0, 0), Vec3d::UnitX(), Vec3d::UnitY(), 10, 10, floor));
  if (gradient) {
    scene.lighting.gradient.origin = Vec3d(1.5, 0, 0);
    scene.lighting.gradient.gradient = Vec3d(-0.15, 0.1, 0);
  }
  return scene;
}

// 1.2 m above the floor, looking along +x, 55 deg down (the rmp rig).
Rigid3d RigPose() {
  const double c = std::cos(55.0 * M_PI / 180), s = std::sin(55.0 * M_PI / 180);
  Mat3d world_from_cam;
  world_from_cam.col(0) = Vec3d(0, -1, 0);
  world_from_cam.col(1) = Vec3d(-s, 0, -c);
  world_from_cam.col(2) = Vec3d(c, 0, -s);
  Rigid3d t;
  t.rotation = world_from_cam.transpose();
  t.translation = -(t.rotation * Vec3d(0, 0, 1.2));
  return t;
}

const Surface& FloorSurface(const Prepared& prep) {
  for (const Surface& s : prep.surfaces) {
    if (s.mesh >= 0 && prep.meshes[static_cast<std::size_t>(s.mesh)].name == "floor") return s;
  }
  ADD_FAILURE() << "no floor surface";
  return prep.surfaces.front();
}

// Compares the batch with Shade at `n` points per call over the whole image; footprint 0 keeps every
// octave (no fading), so that the finest lattice coordinates are reached.
void ExpectSameAsShade(const Scene& scene, bool distorted, int n, double footprint_scale) {
  CameraModel cam;
  cam.params = {320.0, 320.0, 319.5, 239.5, 0, 0, 0, 0, 0};
  if (distorted) cam.params[kK1] = -0.1;
  RenderOptions options;
  options.color = true;
  auto prep = Prepare(scene, cam, RigPose(), options, 4);
  ASSERT_TRUE(prep.ok()) << prep.status().message();
  const Surface& floor = FloorSurface(*prep);
  ASSERT_NE(floor.texture, nullptr);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> px(0, 640), py(0, 480), foot(0.3, 3.0);
  std::vector<double> xs(static_cast<std::size_t>(n)), ys(xs.size()), fs(xs.size());
  std::vector<Vec3d> batch(xs.size());
  std::vector<float> luma(xs.size());
  int compared = 0;
  for (int call = 0; call < 400; ++call) {
    for (std::size_t k = 0; k < xs.size(); ++k) {
      // Neighbouring pixels of one row, as the rasterizer hands them over, from a random start.
      xs[k] = (k == 0 ? px(rng) : xs[k - 1] + 1);
      ys[k] = (k == 0 ? py(rng) : ys[k - 1]);
      fs[k] = footprint_scale * foot(rng);
    }
    ShadeBatch(*prep, floor, xs.data(), ys.data(), fs.data(), n, batch.data());
    ShadeBatchLuma(*prep, floor, xs.data(), ys.data(), fs.data(), n, luma.data());
    for (std::size_t k = 0; k < xs.size(); ++k) {
      const Vec3d one = Shade(*prep, floor, xs[k], ys[k], fs[k]);
      ASSERT_EQ(batch[k].x(), one.x()) << "point " << k << " of call " << call << " at (" << xs[k] << ", " << ys[k]
                                       << ")";
      ASSERT_EQ(batch[k].y(), one.y());
      ASSERT_EQ(batch[k].z(), one.z());
      ASSERT_EQ(luma[k], static_cast<float>(Luma(one)));
      ++compared;
    }
  }
  EXPECT_EQ(compared, 400 * n);
}

TEST(ShadingTest, BatchIsShadeToTheLastBit) {
  for (const bool gradient : {false, true}) {
    for (const bool distorted : {false, true}) {
      for (const int n : {4, 7, 8, 21}) {
        SCOPED_TRACE(::testing::Message() << "gradient " << gradient << ", distorted " << distorted << ", n " << n);
        ExpectSameAsShade(FloorScene(0.2, gradient), distorted, n, 1.0);
      }
    }
  }
}

TEST(ShadingTest, BatchKeepsEveryOctaveWithoutFading) { ExpectSameAsShade(FloorScene(0.2, true), false, 8, 0.0); }

TEST(ShadingTest, BatchHandsHugeLatticeCoordinatesToShade) {
  // A 1e-9 m coarsest wavelength: lattice coordinates beyond 2^30 on most of the floor, which 32-bit
  // vector indices cannot hold.
  ExpectSameAsShade(FloorScene(1e-9, false), false, 8, 0.0);
}

}  // namespace
}  // namespace idi::sim::internal
