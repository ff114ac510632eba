#include "rmp/perception/tape_geometry.h"

#include <gtest/gtest.h>

#include <cmath>

#include "shared/util/units.h"

namespace idi::rmp {
namespace {

// The two edges of a tape of width w along a->b (tape_side known: left edge has the tape on its right).
std::vector<GroundEdge> TapeEdges(const Vec2d& a, const Vec2d& b, double w, bool known_sides = true) {
  const Vec2d u = (b - a).normalized(), n(-u.y(), u.x());
  GroundEdge left{a + 0.5 * w * n, b + 0.5 * w * n, known_sides ? -1 : 0, {true, true}};
  GroundEdge right{a - 0.5 * w * n, b - 0.5 * w * n, known_sides ? +1 : 0, {true, true}};
  return {left, right};
}

TEST(TapeGeometryTest, PairsTheTwoEdgesOfATapeIntoItsMidline) {
  TapeGeometryOptions o;
  const auto edges = TapeEdges({0.5, 0.1}, {2.5, 0.1}, 0.05);
  const auto strips = PairTapeEdges(edges, o);
  ASSERT_EQ(strips.size(), 1u);
  EXPECT_NEAR(strips[0].a.y(), 0.1, 1e-9);
  EXPECT_NEAR(strips[0].b.y(), 0.1, 1e-9);
  EXPECT_NEAR(std::abs(strips[0].b.x() - strips[0].a.x()), 2.0, 1e-9);
}

TEST(TapeGeometryTest, DoesNotPairEdgesOfTheWrongWidthOrPolarity) {
  TapeGeometryOptions o;
  EXPECT_TRUE(PairTapeEdges(TapeEdges({0, 0}, {2, 0}, 0.10), o).empty());  // twice as wide
  // The floor between two tapes 5 cm apart: the edges face away from each other.
  auto edges = TapeEdges({0, 0}, {2, 0}, 0.05);
  edges[0].tape_side = +1;
  edges[1].tape_side = -1;
  EXPECT_TRUE(PairTapeEdges(edges, o).empty());
  // Not parallel.
  std::vector<GroundEdge> skew = {{{0, 0}, {2, 0}, 0, {true, true}}, {{0, 0.05}, {2, 0.3}, 0, {true, true}}};
  EXPECT_TRUE(PairTapeEdges(skew, o).empty());
}

TEST(TapeGeometryTest, JoinsTheLegsOfACornerAtTheCentreLineVertex) {
  TapeGeometryOptions o;
  const double w = 0.05;
  // Leg A along x to the corner at (2, 0), leg B along y; edges end at the inner/outer corners.
  std::vector<GroundEdge> edges = {
      {{0.5, 0.025}, {1.975, 0.025}, -1, {false, true}},  // inner edge of A (left)
      {{0.5, -0.025}, {2.025, -0.025}, +1, {false, true}},  // outer edge of A
      {{1.975, 0.025}, {1.975, 1.5}, -1, {true, false}},    // inner edge of B
      {{2.025, -0.025}, {2.025, 1.5}, +1, {true, false}},   // outer edge of B
  };
  const auto strips = PairTapeEdges(edges, o);
  ASSERT_EQ(strips.size(), 2u);
  const auto pieces = ChainCentreSegments(strips, o);
  ASSERT_EQ(pieces.size(), 1u);
  ASSERT_EQ(pieces[0].points_m.size(), 3u);
  EXPECT_NEAR((pieces[0].points_m[1] - Vec2d(2.0, 0.0)).norm(), 0.0, 1e-9);
  EXPECT_FALSE(pieces[0].end_seen[0]);
  EXPECT_FALSE(pieces[0].end_seen[1]);
  (void)w;
}

TEST(TapeGeometryTest, MarksATapeEndSeenInsideTheImages) {
  TapeGeometryOptions o;
  auto edges = TapeEdges({0.5, 0}, {1.8, 0}, 0.05);
  edges[0].end_inside = {false, true};
  edges[1].end_inside = {false, true};
  const auto pieces = ChainCentreSegments(PairTapeEdges(edges, o), o);
  ASSERT_EQ(pieces.size(), 1u);
  const bool forward = pieces[0].points_m.back().x() > pieces[0].points_m.front().x();
  EXPECT_TRUE(pieces[0].end_seen[forward ? 1 : 0]);
  EXPECT_FALSE(pieces[0].end_seen[forward ? 0 : 1]);
}

TEST(TapeGeometryTest, KeepsPiecesAcrossAGapApart) {
  TapeGeometryOptions o;
  auto edges = TapeEdges({0.5, 0}, {1.5, 0}, 0.05);
  const auto far = TapeEdges({2.0, 0}, {3.0, 0}, 0.05);
  edges.insert(edges.end(), far.begin(), far.end());
  EXPECT_EQ(ChainCentreSegments(PairTapeEdges(edges, o), o).size(), 2u);
}

TEST(TapeGeometryTest, ChainsACurveOfShortSegments) {
  TapeGeometryOptions o;
  std::vector<GroundEdge> edges;
  Vec2d p(0.5, 0.0);
  double heading = 0.0;
  for (int i = 0; i < 8; ++i) {
    const Vec2d q = p + 0.15 * Vec2d(std::cos(heading), std::sin(heading));
    const auto e = TapeEdges(p, q, 0.05);
    edges.insert(edges.end(), e.begin(), e.end());
    p = q;
    heading += 15.0 * kPi / 180.0;
  }
  const auto pieces = ChainCentreSegments(PairTapeEdges(edges, o), o);
  ASSERT_EQ(pieces.size(), 1u);
  EXPECT_EQ(pieces[0].points_m.size(), 9u);
}

TEST(TapeGeometryTest, ChecksOptions) {
  TapeGeometryOptions o;
  EXPECT_TRUE(o.Check().ok());
  o.tape_width_m = -1;
  EXPECT_FALSE(o.Check().ok());
  // 0 sent exactly collinear strips to the corner construction: 0/0, a NaN vertex, the piece dropped.
  o = {};
  o.collinear_deg = 0;
  EXPECT_NE(o.Check().message().find("collinear_deg"), std::string::npos);
}

// Narrow tape keeps a tolerance below its width (the default 20 mm would refuse 19 mm tape); wide tape
// keeps the tolerance it had.
TEST(TapeGeometryTest, SettingTheWidthCapsTheTolerance) {
  TapeGeometryOptions o;
  o.SetTapeWidth(0.019);
  EXPECT_DOUBLE_EQ(o.tape_width_m, 0.019);
  EXPECT_DOUBLE_EQ(o.width_tolerance_m, 0.0095);
  EXPECT_TRUE(o.Check().ok());
  TapeGeometryOptions wide;
  wide.SetTapeWidth(0.1);
  EXPECT_DOUBLE_EQ(wide.width_tolerance_m, TapeGeometryOptions{}.width_tolerance_m);
}

}  // namespace
}  // namespace idi::rmp
