#include "rmp/app/track_spec.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

namespace idi::rmp {
namespace {

TEST(TrackSpecTest, ParsesTheDesignFormat) {
  auto t = ParseTrackYaml(
      "tape_width_m: 0.05\n"
      "points_m: [[0, 0], [2, 0], [2, 1.5]]\n"
      "start: {x_m: -0.1, y_m: 0.0, yaw_rad: 0.05}\n"
      "speed_mps: 1.0\n"
      "gaps_m: [[0.5, 0.8]]\n",
      "t.yaml");
  ASSERT_TRUE(t.ok()) << t.status().ToString();
  EXPECT_EQ(t->points_m.size(), 3u);
  EXPECT_DOUBLE_EQ(t->Length(), 3.5);
  EXPECT_DOUBLE_EQ(t->speed_mps, 1.0);
  double x, y, yaw;
  t->StartPose(&x, &y, &yaw);
  EXPECT_DOUBLE_EQ(x, -0.1);
  EXPECT_DOUBLE_EQ(yaw, 0.05);
  ASSERT_EQ(t->gaps_m.size(), 1u);
}

TEST(TrackSpecTest, NamesTheFileLineAndKeyOfMistakes) {
  auto unknown = ParseTrackYaml("points_m: [[0, 0], [1, 0]]\ntape_widht_m: 0.05\n", "t.yaml");
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.status().message().find("t.yaml:2"), std::string::npos);
  EXPECT_NE(unknown.status().message().find("tape_widht_m"), std::string::npos);
  // points_m twice appended a second track to the first.
  auto twice = ParseTrackYaml("points_m: [[0, 0], [1, 0]]\npoints_m: [[5, 5], [6, 5]]\n", "t.yaml");
  ASSERT_FALSE(twice.ok());
  EXPECT_NE(twice.status().message().find("t.yaml:2: key 'points_m' given twice"), std::string::npos)
      << twice.status().message();
  auto one_point = ParseTrackYaml("points_m: [[0, 0]]\n", "t.yaml");
  ASSERT_FALSE(one_point.ok());
  EXPECT_NE(one_point.status().message().find("two points"), std::string::npos);
  auto bad_pair = ParseTrackYaml("points_m: [[0, 0], [1, x]]\n", "t.yaml");
  ASSERT_FALSE(bad_pair.ok());
  EXPECT_NE(bad_pair.status().message().find("points_m[1]"), std::string::npos);
  auto gap = ParseTrackYaml("points_m: [[0, 0], [1, 0]]\ngaps_m: [[0.5, 2.0]]\n", "t.yaml");
  ASSERT_FALSE(gap.ok());
  EXPECT_NE(gap.status().message().find("gaps_m[0]"), std::string::npos);
  EXPECT_FALSE(ParseTrackYaml("[", "t.yaml").ok());
  EXPECT_EQ(LoadTrackFile("/nonexistent/track.yaml").status().code(), StatusCode::kNotFound);
}

// Tracks that were taken silently and gave a run that could not start (a start 50 m away, a yaw of
// 1e300 rad, no tape at all, 2 mm of tape), or a start key whose second value replaced the first.
TEST(TrackSpecTest, RefusesTracksThatCannotBeDrivenNamingTheKey) {
  const std::string line = "points_m: [[0, 0], [1, 0]]\n";
  for (const auto& [text, what] : std::vector<std::pair<std::string, std::string>>{
           {line + "start: {x_m: 0, x_m: 0.5, yaw_rad: 0}\n", "t.yaml:2: key 'start.x_m' given twice"},
           {line + "start: {x_m: 50, y_m: 0, yaw_rad: 0}\n", "t.yaml:2: start (50, 0) is 50 m from"},
           {line + "start: {x_m: 0, y_m: 0, yaw_rad: 1e300}\n", "t.yaml:2: start.yaw_rad 1e+300 must be within"},
           {line + "start: {x_m: 0, y_m: 0, yaw_rad: -13}\n", "t.yaml:2: start.yaw_rad -13 must be within"},
           {line + "start: {x_m: 0, y_m: 0, yaw_rad: .inf}\n", "t.yaml:2: start.yaw_rad is not a finite number"},
           {line + "gaps_m: [[0, 0.6], [0.5, 1.0]]\n", "t.yaml: gaps_m cover the whole track"},
           {line + "gaps_m: [[0, 1.0]]\n", "t.yaml: gaps_m cover the whole track"},
           {line + "gaps_m: [[0, 0.998]]\n", "t.yaml: gaps_m cover the whole track (1 m) but 0.002 m"},
           {"points_m: [[0, 0], [0.002, 0]]\n", "t.yaml: points_m: the track is 0.002 m long"},
           {"tape_width_m: 0.3\npoints_m: [[0, 0], [0.2, 0]]\n", "t.yaml: points_m: the track is 0.2 m long"}}) {
    const auto t = ParseTrackYaml(text, "t.yaml");
    if (t.ok()) {
      ADD_FAILURE() << "accepted: " << text;
      continue;
    }
    EXPECT_EQ(t.status().code(), StatusCode::kInvalidArgument) << text;
    EXPECT_NE(t.status().message().find(what), std::string::npos) << text << ": " << t.status().message();
  }
  // Within the limits: a start 0.9 m behind the first point, turned by 2 pi, and a gap leaving tape.
  EXPECT_TRUE(ParseTrackYaml(line + "start: {x_m: -0.9, y_m: 0, yaw_rad: 6.2832}\ngaps_m: [[0, 0.9]]\n", "t").ok());
  EXPECT_TRUE(ParseTrackYaml("points_m: [[0, 0], [0.1, 0]]\n", "t").ok());
}

TEST(TrackSpecTest, SplitsTheTapeAtGaps) {
  const auto stretches = TapedStretches({{0, 0}, {2, 0}, {2, 2}}, {{1.0, 1.5}, {2.5, 3.0}});
  ASSERT_EQ(stretches.size(), 3u);
  EXPECT_NEAR(stretches[0].back().x(), 1.0, 1e-12);
  EXPECT_NEAR(stretches[1].front().x(), 1.5, 1e-12);
  EXPECT_EQ(stretches[1].size(), 3u);  // through the corner
  EXPECT_NEAR(stretches[1].back().y(), 0.5, 1e-12);
  EXPECT_NEAR(stretches[2].front().y(), 1.0, 1e-12);
  auto scene = BuildTrackScene(*ParseTrackYaml("points_m: [[0, 0], [2, 0], [2, 2]]\ngaps_m: [[1.0, 1.5]]\n", "t"));
  ASSERT_TRUE(scene.ok());
  EXPECT_EQ(scene->solids.size(), 3u);  // floor and two pieces of tape
}

// The twin laid a track it could not turn as one straight chord from its first to its last point
// (0.5 m of tape for a 10 m track, and the run "completed").
TEST(TrackSpecTest, RefusesTurnsTheTwinCannotLay) {
  auto sharp = BuildTrackScene(*ParseTrackYaml("points_m: [[0, 0], [5, 0], [0, 0.5]]\n", "sharp.yaml"));
  ASSERT_FALSE(sharp.ok());
  EXPECT_EQ(sharp.status().code(), StatusCode::kInvalidArgument);
  const std::string m = sharp.status().message();
  EXPECT_NE(m.find("sharp.yaml"), std::string::npos) << m;
  EXPECT_NE(m.find("points_m[1] (5, 0)"), std::string::npos) << m;
  EXPECT_NE(m.find("at most 150 deg"), std::string::npos) << m;
  auto back_and_forth =
      BuildTrackScene(*ParseTrackYaml("points_m: [[0, 0], [3, 0], [0.0001, 0.0001], [3, 0]]\n", "zz.yaml"));
  ASSERT_FALSE(back_and_forth.ok());
  EXPECT_NE(back_and_forth.status().message().find("points_m[1] (3, 0)"), std::string::npos)
      << back_and_forth.status().message();
  // Two allowed right-angle turns 2 cm apart: the 5 cm tape cannot turn twice on that segment.
  auto short_leg = BuildTrackScene(*ParseTrackYaml("points_m: [[0, 0], [2, 0], [2, 0.02], [0, 0.02]]\n", "u.yaml"));
  ASSERT_FALSE(short_leg.ok());
  const std::string s = short_leg.status().message();
  EXPECT_NE(s.find("u.yaml: the segment from points_m[1] (2, 0) to points_m[2] (2, 0.02)"), std::string::npos) << s;
  // A turn of 150 deg is laid.
  const double x = 2.0 - 2.0 * std::cos(std::numbers::pi / 6), y = 2.0 * std::sin(std::numbers::pi / 6) + 1e-3;
  auto at_limit = BuildTrackScene(
      *ParseTrackYaml("points_m: [[0, 0], [2, 0], [" + std::to_string(x) + ", " + std::to_string(y) + "]]\n", "t"));
  EXPECT_TRUE(at_limit.ok()) << at_limit.status().ToString();
}

// Distance from p to the polyline.
double DistanceToLine(const std::vector<Vec2d>& line, const Vec2d& p) {
  double best = 1e9;
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    const Vec2d d = line[i + 1] - line[i];
    const double f = std::clamp((p - line[i]).dot(d) / d.squaredNorm(), 0.0, 1.0);
    best = std::min(best, (line[i] + f * d - p).norm());
  }
  return best;
}

// A gap ending 1 cm before a corner leaves an end segment too short to turn: the tape is still laid
// along the centre line (that segment on its own), not as a chord across the corners.
TEST(TrackSpecTest, GapsEndingNearACornerStillFollowTheCentreLine) {
  const std::vector<Vec2d> line = {{0, 0}, {2, 0}, {2, 2}, {0, 2}};
  for (const char* gaps : {"[[0.5, 1.99]]", "[[0.5, 1.99], [2.01, 5.0]]", "[[3.0, 3.99]]"}) {
    SCOPED_TRACE(gaps);
    auto track = ParseTrackYaml(std::string("points_m: [[0, 0], [2, 0], [2, 2], [0, 2]]\ngaps_m: ") + gaps + "\n", "t");
    ASSERT_TRUE(track.ok()) << track.status().ToString();
    auto scene = BuildTrackScene(*track);
    ASSERT_TRUE(scene.ok()) << scene.status().ToString();
    double to_end = 1e9;  // the tape still reaches the end of the track
    for (const sim::Solid& solid : scene->solids) {
      if (solid.name == "floor") continue;
      for (const sim::Face& face : solid.faces) {
        for (std::size_t i = 0; i < face.vertices.size(); ++i) {
          const Vec2d a = solid.vertices[face.vertices[i]].head<2>();
          const Vec2d b = solid.vertices[face.vertices[(i + 1) % face.vertices.size()]].head<2>();
          to_end = std::min(to_end, (a - line.back()).norm());
          // Along every edge: at most half the width from the centre line (sqrt(2) times at a mitred corner).
          for (double f = 0.0; f <= 1.0; f += 0.05) {
            EXPECT_LE(DistanceToLine(line, a + f * (b - a)), 0.025 * std::sqrt(2.0) + 1e-9) << solid.name;
          }
        }
      }
    }
    EXPECT_NEAR(to_end, 0.025, 1e-9);
  }
}

// After a gap ending 1 cm before a corner the end segment is laid on its own; the piece left then starts
// square at that corner, and its first segment (2 cm, between opposite turns: enough for the track as a
// whole) is too short for the turn at its other end. It is laid on its own too.
TEST(TrackSpecTest, PeelsEndSegmentsUntilTheRestLays) {
  const std::vector<Vec2d> line = {{0, 0}, {1, 0}, {1, 0.02}, {2, 0.02}};
  for (const char* gaps : {"[[0.5, 0.99]]", "[[1.03, 1.5]]"}) {
    SCOPED_TRACE(gaps);
    auto track = ParseTrackYaml(
        std::string("tape_width_m: 0.05\npoints_m: [[0, 0], [1, 0], [1, 0.02], [2, 0.02]]\ngaps_m: ") + gaps + "\n",
        "jog.yaml");
    ASSERT_TRUE(track.ok()) << track.status().ToString();
    auto scene = BuildTrackScene(*track);
    ASSERT_TRUE(scene.ok()) << scene.status().ToString();
    EXPECT_EQ(scene->solids.size(), 5u);  // floor, the stretch before or after the gap, and three pieces
    for (const sim::Solid& solid : scene->solids) {
      if (solid.name == "floor") continue;
      for (const Vec3d& v : solid.vertices) {
        EXPECT_LE(DistanceToLine(line, v.head<2>()), 0.025 * std::sqrt(2.0) + 1e-9) << solid.name;
      }
    }
  }
}

// Turns and segments the tape does not lie on (in a gap) are not the twin's to lay: these tracks built
// before the check, and still do.
TEST(TrackSpecTest, ChecksOnlyTheTapedStretches) {
  // A turn sharper than 150 deg, in a gap.
  auto sharp = BuildTrackScene(*ParseTrackYaml("points_m: [[0, 0], [5, 0], [0, 0.5]]\ngaps_m: [[4.5, 5.5]]\n", "t"));
  EXPECT_TRUE(sharp.ok()) << sharp.status().ToString();
  // A segment too short for its two turns, in a gap.
  auto short_leg =
      BuildTrackScene(*ParseTrackYaml("points_m: [[0, 0], [2, 0], [2, 0.02], [0, 0.02]]\ngaps_m: [[1.9, 2.2]]\n", "t"));
  EXPECT_TRUE(short_leg.ok()) << short_leg.status().ToString();
  // Taped, with a gap elsewhere: still refused, naming the points.
  auto taped = BuildTrackScene(
      *ParseTrackYaml("points_m: [[0, 0], [2, 0], [2, 0.02], [0, 0.02]]\ngaps_m: [[0.5, 1.0]]\n", "u.yaml"));
  ASSERT_FALSE(taped.ok());
  EXPECT_NE(taped.status().message().find("u.yaml: the segment from points_m[1] (2, 0) to points_m[2] (2, 0.02)"),
            std::string::npos)
      << taped.status().message();
  auto sharp_taped =
      BuildTrackScene(*ParseTrackYaml("points_m: [[0, 0], [5, 0], [0, 0.5]]\ngaps_m: [[1, 2]]\n", "sharp.yaml"));
  ASSERT_FALSE(sharp_taped.ok());
  EXPECT_NE(sharp_taped.status().message().find("points_m[1] (5, 0)"), std::string::npos)
      << sharp_taped.status().message();
}

TEST(TrackSpecTest, TheProjectTracksAreLaid) {
  const char* src = std::getenv("IDI_SOURCE_DIR");
  const std::filesystem::path dir = std::filesystem::path(src != nullptr ? src : ".") / "rmp/app/tracks";
  if (!std::filesystem::is_directory(dir)) GTEST_SKIP() << "no " << dir;
  int n = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    auto track = LoadTrackFile(entry.path().string());
    ASSERT_TRUE(track.ok()) << track.status().ToString();
    auto scene = BuildTrackScene(*track);
    EXPECT_TRUE(scene.ok()) << scene.status().ToString();
    ++n;
  }
  EXPECT_GT(n, 5);
}

}  // namespace
}  // namespace idi::rmp
