// Ground truth: which edges are seen, where, and how they meet; spots; ray casting; JSON.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <nlohmann/json.hpp>

#include "shared/sim/render/render.h"
#include "shared/sim/render/shapes.h"
#include "shared/util/units.h"

namespace idi::sim {
namespace {

// A camera at `centre` looking at `target`, world z up.
Rigid3d LookAt(const Vec3d& centre, const Vec3d& target) {
  const Vec3d z = (target - centre).normalized();
  const Vec3d x = z.cross(Vec3d::UnitZ()).normalized();
  const Vec3d y = z.cross(x);
  Rigid3d world_from_cam;
  world_from_cam.rotation.col(0) = x;
  world_from_cam.rotation.col(1) = y;
  world_from_cam.rotation.col(2) = z;
  world_from_cam.translation = centre;
  return world_from_cam.Inverse();
}

Scene BoxScene() {
  Scene s;
  s.solids.push_back(MakeRectangle("wall", Vec3d(0, 3000, 0), Vec3d::UnitX(), Vec3d::UnitZ(), 4000, 4000, Gray(0.3)));
  s.solids.push_back(MakeBox("box", Translation(0.0, 0.0, 0.0) * RotZ(0.6), Vec3d(300, 200, 150), Gray(0.8)));
  s.lighting.directional = {{Vec3d(0.3, -0.5, 1.0), 0.6}};
  return s;
}

double DistanceToLine(const TruthLine& l, const Vec2d& p) { return std::abs(l.normal.dot(p) - l.offset); }

TEST(GroundTruthTest, BoxShowsNineEdgesMeetingInOneYThreeArrowsAndThreeLs) {
  const Scene scene = BoxScene();
  CameraModel cam;
  // From here the top and two sides are seen.
  const Rigid3d cam_from_world = LookAt(Vec3d(700, -600, 800), Vec3d(0, 0, 75));
  GroundTruth truth;
  auto img = RenderScene(scene, cam, cam_from_world, RenderOptions(), &truth);
  ASSERT_TRUE(img.ok()) << img.status().ToString();
  int box_lines = 0;
  for (const TruthLine& l : truth.lines) {
    EXPECT_LT(DistanceToLine(l, l.p1_px), 1e-6);
    EXPECT_LT(DistanceToLine(l, l.p2_px), 1e-6);
    if (l.object != "box") continue;
    ++box_lines;
    EXPECT_EQ(l.kind, "edge");
    EXPECT_GT(std::abs(l.contrast_dn), 1.0);
    // An unoccluded edge ends at its projected vertices.
    const Vec3d a = cam_from_world * l.p1_world, b = cam_from_world * l.p2_world;
    EXPECT_LT((ProjectToPixel(cam.params.data(), a) - l.p1_px).norm(), 1e-6);
    EXPECT_LT((ProjectToPixel(cam.params.data(), b) - l.p2_px).norm(), 1e-6);
  }
  EXPECT_EQ(box_lines, 9);
  std::map<std::string, int> types;
  for (const TruthJunction& j : truth.junctions) {
    if (j.object == "box" && j.is_vertex) ++types[j.type];
  }
  // Seven vertices are seen: the near top corner (Y, three edges inside the outline), three outline
  // corners where a third edge comes in (arrow) and three outline corners with two edges (L); the
  // degrees add up to twice the nine edges (3 + 3*3 + 3*2 = 18).
  EXPECT_EQ(types["Y"], 1);
  EXPECT_EQ(types["arrow"], 3);
  EXPECT_EQ(types["L"], 3);
  // The junction is the projected vertex, and each of its lines passes through it.
  for (const TruthJunction& j : truth.junctions) {
    for (const int id : j.lines) EXPECT_LT(DistanceToLine(truth.lines[static_cast<std::size_t>(id)], j.xy_px), 1e-6);
  }
}

TEST(GroundTruthTest, OccludedEdgeEndsInATJunction) {
  Scene scene = BoxScene();
  // A second, taller box in front hides part of the first box's top front edge.
  scene.solids.push_back(MakeBox("front", Translation(-40.0, -450.0, 0.0), Vec3d(60, 60, 400), Gray(0.55)));
  CameraModel cam;
  const Rigid3d cam_from_world = LookAt(Vec3d(0, -1400, 500), Vec3d(0, 0, 100));
  GroundTruth truth;
  ASSERT_TRUE(RenderScene(scene, cam, cam_from_world, RenderOptions(), &truth).ok());
  int t_junctions = 0;
  for (const TruthJunction& j : truth.junctions) {
    if (j.is_vertex) continue;
    ASSERT_EQ(j.lines.size(), 2u);
    const TruthLine& occluded = truth.lines[static_cast<std::size_t>(j.lines[0])];
    const TruthLine& occluder = truth.lines[static_cast<std::size_t>(j.lines[1])];
    EXPECT_LT(DistanceToLine(occluded, j.xy_px), 1e-6);
    EXPECT_LT(DistanceToLine(occluder, j.xy_px), 1e-6);
    if (j.type == "T" && occluded.object == "box" && occluder.object == "front") ++t_junctions;
  }
  // The front box's two vertical silhouettes each cut the back box's visible edges.
  EXPECT_GE(t_junctions, 2);
}

TEST(GroundTruthTest, CylinderSilhouettesAreTheAnalyticTangentsAndMatchThePixels) {
  Scene s;
  s.solids.push_back(MakeRectangle("wall", Vec3d(0, 0, 3000), Vec3d::UnitX(), Vec3d::UnitY(), 5000, 5000, Gray(0.2)));
  Cylinder c;
  c.name = "can";
  c.base_center = Vec3d(30, 400, 1500);  // axis along -y (up in the image)
  c.axis = Vec3d(0.05, -1, 0.1).normalized();
  c.radius = 120;
  c.height = 700;
  c.side = c.top = c.bottom = Gray(0.8);
  s.cylinders.push_back(c);
  s.lighting.ambient = 1;
  s.lighting.directional.clear();
  CameraModel cam;
  RenderOptions o;
  o.sensor.noise = false;
  GroundTruth truth;
  auto img = RenderIrradiance(s, cam, Rigid3d::Identity(), o, &truth);
  ASSERT_TRUE(img.ok());
  std::vector<TruthLine> sil;
  for (const TruthLine& l : truth.lines) {
    if (l.kind == "silhouette") sil.push_back(l);
  }
  ASSERT_EQ(sil.size(), 2u);
  // Analytic: the tangent plane through the camera centre touches the cylinder along a generator.
  const Vec3d a = c.axis, rel = -c.base_center;  // camera at the origin
  const Vec3d v = rel - rel.dot(a) * a;
  const double phi = std::acos(c.radius / v.norm());
  const Vec3d e1 = v.normalized(), e2 = a.cross(e1);
  double worst_truth = 0, worst_pixels = 0;
  for (const double sgn : {-1.0, 1.0}) {
    const Vec3d foot = c.base_center + c.radius * (std::cos(phi) * e1 + sgn * std::sin(phi) * e2);
    const Vec2d p1 = ProjectToPixel(cam.params.data(), foot);
    const Vec2d p2 = ProjectToPixel(cam.params.data(), Vec3d(foot + c.height * a));
    double d = 1e9;
    for (const TruthLine& l : sil) d = std::min(d, std::max(DistanceToLine(l, p1), DistanceToLine(l, p2)));
    worst_truth = std::max(worst_truth, d);
  }
  EXPECT_LT(worst_truth, 1e-6);
  // Pixels: the area method along rows (cylinder 0.8, wall 0.2, both uniform under ambient light).
  for (const TruthLine& l : sil) {
    const double ymin = std::min(l.p1_px.y(), l.p2_px.y()) + 15, ymax = std::max(l.p1_px.y(), l.p2_px.y()) - 15;
    for (int r = static_cast<int>(ymin); r < ymax; ++r) {
      const double xe = (l.offset - l.normal.y() * r) / l.normal.x();
      const int c0 = static_cast<int>(std::lround(xe)) - 8, c1 = c0 + 16;
      double sum = 0;
      for (int x = c0; x <= c1; ++x) sum += img->at<float>(r, x);
      const bool cyl_left = img->at<float>(r, c0) > img->at<float>(r, c1);
      const double left = cyl_left ? 160 : 40, right = cyl_left ? 40 : 160;
      const double meas = (sum - right * (c1 + 0.5) + left * (c0 - 0.5)) / (left - right);
      worst_pixels = std::max(worst_pixels, std::abs(meas - xe));
    }
  }
  EXPECT_LT(worst_pixels, 0.005);
}

TEST(GroundTruthTest, SpotBehindAnObjectIsNotVisible) {
  Scene s = BoxScene();
  CameraModel cam;
  const Rigid3d cam_from_world = LookAt(Vec3d(0, -1500, 75), Vec3d(0, 3000, 75));
  // One spot on the wall straight behind the box, one beside it.
  s.laser_spots.push_back({Vec3d(0, 3000, 75), 5, 5, Vec3d(1, 0, 0)});
  s.laser_spots.push_back({Vec3d(1200, 3000, 75), 5, 5, Vec3d(1, 0, 0)});
  GroundTruth truth;
  ASSERT_TRUE(RenderScene(s, cam, cam_from_world, RenderOptions(), &truth).ok());
  ASSERT_EQ(truth.spots.size(), 2u);
  EXPECT_FALSE(truth.spots[0].visible);
  EXPECT_TRUE(truth.spots[1].visible);
}

TEST(GroundTruthTest, JsonHasEveryLineJunctionAndSpot) {
  Scene s = BoxScene();
  s.laser_spots.push_back({Vec3d(600, 3000, 300), 5, 5, Vec3d(1, 0, 0)});
  CameraModel cam;
  GroundTruth truth;
  ASSERT_TRUE(RenderScene(s, cam, LookAt(Vec3d(500, -900, 700), Vec3d(0, 0, 75)), RenderOptions(), &truth).ok());
  const auto j = nlohmann::json::parse(GroundTruthToJson(truth));
  EXPECT_EQ(j["width"], 640);
  EXPECT_EQ(j["lines"].size(), truth.lines.size());
  EXPECT_EQ(j["junctions"].size(), truth.junctions.size());
  EXPECT_EQ(j["spots"].size(), 1u);
  EXPECT_EQ(j["camera"]["cam_from_world"].size(), 12u);
  EXPECT_DOUBLE_EQ(j["lines"][0]["p1"][0].get<double>(), truth.lines[0].p1_px.x());
}

TEST(CastRayTest, HitsTheFirstSurface) {
  Scene s = BoxScene();
  Cylinder c;
  c.name = "post";
  c.base_center = Vec3d(1000, 0, 0);
  c.radius = 50;
  c.height = 500;
  s.cylinders.push_back(c);
  // Down onto the box top (z = 150).
  auto hit = CastRay(s, Vec3d(10, 10, 1000), Vec3d(0, 0, -1));
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->object, "box");
  EXPECT_NEAR(hit->point.z(), 150, 1e-9);
  EXPECT_NEAR(hit->normal.z(), 1, 1e-12);
  // Sideways into the cylinder.
  hit = CastRay(s, Vec3d(1000, -500, 100), Vec3d(0, 1, 0));
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->object, "post");
  EXPECT_NEAR(hit->point.y(), -50, 1e-9);
  // Past everything onto the wall, and into nothing.
  hit = CastRay(s, Vec3d(2000, 0, 100), Vec3d(0, 1, 0));
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->object, "wall");
  EXPECT_NEAR(hit->distance, 3000, 1e-9);
  EXPECT_FALSE(CastRay(s, Vec3d(0, 0, 5000), Vec3d(0, 0, 1)).has_value());
}

}  // namespace
}  // namespace idi::sim
