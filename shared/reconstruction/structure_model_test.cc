#include "shared/reconstruction/structure_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "tests/support/wireframe_views.h"

namespace idi {
namespace {

// Two model points, A and B, and views whose features put both on one confirmed image line.
struct TwoPointScene {
  std::vector<ViewFeatures> features;
  std::vector<Rigid3d> poses;
  CameraModel camera;
  Correspondences correspondences;
};

Vec2d ProjectPinhole(const CameraModel& camera, const Rigid3d& cam_from_world, const Vec3d& world) {
  const Vec3d c = cam_from_world * world;
  return Vec2d(camera.params[0] * c.x() / c.z() + camera.params[2],
               camera.params[1] * c.y() / c.z() + camera.params[3]);
}

TwoPointScene SceneWithLineThroughBoth(const Vec3d& a, const Vec3d& b, const std::vector<Vec3d>& centres) {
  TwoPointScene s;
  s.camera.params = {1240, 1240, 319.5, 239.5, 0, 0, 0, 0, 0};
  PointTrack ta, tb;
  ta.xyz = a;
  tb.xyz = b;
  for (std::size_t v = 0; v < centres.size(); ++v) {
    const Rigid3d pose = test::LookAt(centres[v], 0.5 * (a + b));
    ViewFeatures f;
    const Vec2d pa = ProjectPinhole(s.camera, pose, a), pb = ProjectPinhole(s.camera, pose, b);
    f.points.push_back(ViewPoint{pa, 0.1, {0}});
    f.points.push_back(ViewPoint{pb, 0.1, {0}});
    ViewLine line;
    line.line = Line2Through(pa, pb);
    line.end1 = pa;
    line.end2 = pb;
    line.points = {0, 1};
    f.lines.push_back(line);
    s.features.push_back(f);
    s.poses.push_back(pose);
    ta.observations.push_back({static_cast<int>(v), 0});
    tb.observations.push_back({static_cast<int>(v), 1});
  }
  s.correspondences.points = {ta, tb};
  return s;
}

std::vector<CorrespondenceView> ViewsOf(const TwoPointScene& s) {
  std::vector<CorrespondenceView> views;
  for (std::size_t v = 0; v < s.features.size(); ++v) views.push_back({&s.features[v], &s.camera, s.poses[v]});
  return views;
}

// A bracket's leg top runs from A to a corner X that no view found; B, the foot's far corner, lies in the
// plane through that edge that leans 45 deg towards the cameras. Cameras in that plane see B's image on
// the image line along A-X, so the line seems to join A and B. Two such views, from stations 450 mm
// apart, vote for an edge A-B that is not there; they see it from the same direction about its axis.
TEST(StructureModelTest, AnEdgeSeenOnlyFromOnePlaneThroughItIsAnAccidentAndIsRefused) {
  const Vec3d a(0, 0, 100);
  const Vec3d along_leg(1, 0, 0), towards_cameras = Vec3d(0, -1, 1).normalized();
  const Vec3d b = a + 60.0 * along_leg - 60.0 * towards_cameras;  // beyond X = a + 60 along_leg, lower down
  const std::vector<Vec3d> in_plane = {a - 200.0 * along_leg + 1100.0 * towards_cameras,
                                       a + 250.0 * along_leg + 1100.0 * towards_cameras};
  const TwoPointScene accident = SceneWithLineThroughBoth(a, b, in_plane);
  const StructureModel refused = BuildModel(accident.correspondences, ViewsOf(accident));
  EXPECT_TRUE(refused.edges.empty()) << "two views in one plane with the edge confirm nothing about it";

  // The same votes, counted without the spread test: the edge is made (what the model did before).
  ModelOptions no_spread;
  no_spread.min_edge_spread_deg = 0;
  ASSERT_EQ(BuildModel(accident.correspondences, ViewsOf(accident), no_spread).edges.size(), 1u);

  // A true edge seen from a second station 60 deg round the table: kept.
  const Vec3d other_station = a + Vec3d(550, -550 * std::cos(DegToRad(60.0)), 0) +
                              Vec3d(0, 0, 780);  // about 1 m away, 45 deg up, another azimuth
  const TwoPointScene seen_twice = SceneWithLineThroughBoth(a, b, {in_plane[0], other_station});
  const StructureModel kept = BuildModel(seen_twice.correspondences, ViewsOf(seen_twice));
  ASSERT_EQ(kept.edges.size(), 1u);
  EXPECT_EQ(kept.edges[0], std::make_pair(0, 1));
}

// Both cameras of one station, 2.5 degrees apart about a vertical edge (a 45 mm baseline at 1 m): the
// edge is kept; at 1.5 deg it is not.
TEST(StructureModelTest, TheSpreadThresholdIsTheAngleAboutTheEdge) {
  const Vec3d a(0, 0, 0), b(0, 0, 80);
  for (const auto& [deg, expected] : {std::pair{2.5, 1u}, std::pair{1.5, 0u}}) {
    const double h = DegToRad(deg);
    const TwoPointScene s =
        SceneWithLineThroughBoth(a, b, {Vec3d(1000, 0, 700), Vec3d(1000 * std::cos(h), 1000 * std::sin(h), 700)});
    EXPECT_EQ(BuildModel(s.correspondences, ViewsOf(s)).edges.size(), expected) << deg << " deg apart";
  }
}

TEST(StructureModelTest, OptionsOutOfRangeAreRefusedByName) {
  EXPECT_TRUE(ModelOptions{}.Check().ok());
  ModelOptions o;
  o.min_views_for_edge = 0;
  EXPECT_NE(o.Check().message().find("min_views_for_edge"), std::string::npos) << o.Check().message();
  o = {};
  o.segment_margin_px = std::nan("");
  EXPECT_NE(o.Check().message().find("segment_margin_px"), std::string::npos) << o.Check().message();
  o = {};
  o.min_edge_spread_deg = -1;
  EXPECT_NE(o.Check().message().find("min_edge_spread_deg"), std::string::npos) << o.Check().message();
  o.min_edge_spread_deg = std::nan("");
  EXPECT_FALSE(o.Check().ok());
  o.min_edge_spread_deg = 0;
  EXPECT_TRUE(o.Check().ok());
}

}  // namespace
}  // namespace idi
