#include "rmp/app/track_spec.h"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace idi::rmp
