#include "rmp/track/track_model.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "rmp/track/synthetic_observation.h"
#include "shared/util/units.h"

namespace idi::rmp {
namespace {

// A wide view ahead of the vehicle: 0 .. 3 m forward, +-1.5 m.
std::vector<std::vector<Vec2d>> WideView() { return {{{-0.05, -1.5}, {3.0, -1.5}, {3.0, 1.5}, {-0.05, 1.5}}}; }

TEST(TrackModelTest, StartsAtTheVehicleAndFollowsItsHeading) {
  SyntheticTrack track{{{0, 0}, {5, 0}}, {}};
  TrackModel model;
  const Pose2 pose{0, 0, 0};
  auto stats = model.Update(SyntheticObservation(track, pose, WideView(), 0), pose);
  ASSERT_TRUE(stats.ok());
  EXPECT_TRUE(stats->initialised);
  const TrackAhead ahead = model.Ahead();
  ASSERT_TRUE(ahead.valid());
  EXPECT_NEAR(ahead.points.front().x(), 0.0, 0.02);
  EXPECT_GT(ahead.points.back().x(), 2.8);
  EXPECT_FALSE(ahead.end_known);
}

TEST(TrackModelTest, RejectsNonFiniteInput) {
  TrackModel model;
  TrackObservation obs;
  obs.pieces.push_back({{{0, 0}, {std::nan(""), 1}}, {false, false}, 0.005});
  EXPECT_FALSE(model.Update(obs, Pose2{}).ok());
  EXPECT_FALSE(model.Update(TrackObservation{}, Pose2{0, std::nan(""), 0}).ok());
  // A point no camera sees (a bad triangulation 10 km away: densified, it was a million samples) and a
  // footprint with a NaN vertex (an open polygon).
  TrackObservation far;
  far.pieces.push_back({{{0.5, 0}, {1e4, 0}}, {false, false}, 0.005});
  const Status f = model.Update(far, Pose2{}).status();
  EXPECT_EQ(f.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(f.message().find("more than 100 m"), std::string::npos) << f.message();
  TrackObservation open;
  open.pieces.push_back({{{0.5, 0}, {1.0, 0}}, {false, false}, 0.005});
  open.footprints_m.push_back({{0.3, -1}, {3, -1}, {3, std::nan("")}, {0.3, 1}});
  EXPECT_NE(model.Update(open, Pose2{}).status().message().find("non-finite vertex"), std::string::npos);
  EXPECT_FALSE(model.initialised());
  TrackModelOptions o;
  o.keep_behind_m = INFINITY;  // never pruned: the model grew for the whole drive
  EXPECT_FALSE(o.Check().ok());
}

// Drives the vehicle along the true track (straight, heading +x) in 2 cm steps, observing every step.
void DriveStraight(TrackModel* model, const SyntheticTrack& track, double from_x, double to_x, double odom_bias = 0) {
  for (double x = from_x; x <= to_x + 1e-9; x += 0.02) {
    const Pose2 truth{x, 0, 0};
    const Pose2 odom{x, odom_bias, 0};
    ASSERT_TRUE(model->Update(SyntheticObservation(track, truth, WideView(), static_cast<int64_t>(x * 1e9)), odom).ok());
  }
}

TEST(TrackModelTest, BridgesAGapSeenFromBothSides) {
  SyntheticTrack track{{{0, 0}, {8, 0}}, {{2.0, 2.8}}};
  TrackModel model;
  DriveStraight(&model, track, 0.0, 1.0);
  const TrackAhead ahead = model.Ahead();
  ASSERT_TRUE(ahead.valid());
  // The model runs across the gap to the tape beyond it, the stretch in between marked as a gap.
  EXPECT_GT(ahead.points.back().x(), 3.9);
  int gaps = 0;
  for (std::size_t i = 0; i < ahead.points.size(); ++i) {
    if (ahead.gap[i]) {
      ++gaps;
      EXPECT_GT(ahead.points[i].x(), 1.95);
      EXPECT_LT(ahead.points[i].x(), 2.85);
    }
    EXPECT_NEAR(ahead.points[i].y(), 0.0, 1e-9);
  }
  EXPECT_GT(gaps, 50);
  EXPECT_FALSE(ahead.end_known);
}

TEST(TrackModelTest, ConfirmsTheEndOnlyWithClearGroundBeyondIt) {
  SyntheticTrack track{{{0, 0}, {3, 0}}, {}};
  TrackModel model;
  // From x = 0 the view reaches 3 m: the end is seen, but no ground beyond it.
  DriveStraight(&model, track, 0.0, 0.0);
  EXPECT_FALSE(model.end_known());
  // Closer, the cameras see more than end_confirm_m beyond the end without tape: it is the end.
  DriveStraight(&model, track, 0.02, 1.8);
  EXPECT_TRUE(model.end_known());
  const TrackAhead ahead = model.Ahead();
  EXPECT_TRUE(ahead.end_known);
  EXPECT_NEAR(ahead.points.back().x(), 3.0, 0.02);
}

TEST(TrackModelTest, ConfirmsTheEndWhenTapeCrossesBeyondIt) {
  // A loop's last leg ends 0.5 m short of its first leg, which crosses the ray beyond the end: that
  // tape cannot continue the track (it runs across it), so it does not hold up the end.
  SyntheticTrack track{{{0, 0}, {3, 0}}, {}};
  SyntheticTrack crossing{{{3.5, -2}, {3.5, 2}}, {}};
  // The same tape turned along the track does: it may be the track beyond a gap.
  SyntheticTrack in_line{{{3.5, 0}, {5.5, 0}}, {}};
  for (const bool across : {true, false}) {
    TrackModel model;
    for (double x = 0; x <= 1.8 + 1e-9; x += 0.02) {
      const Pose2 pose{x, 0, 0};
      const int64_t t_ns = static_cast<int64_t>(x * 1e9);
      TrackObservation obs = SyntheticObservation(track, pose, WideView(), t_ns);
      const TrackObservation more = SyntheticObservation(across ? crossing : in_line, pose, WideView(), t_ns);
      obs.pieces.insert(obs.pieces.end(), more.pieces.begin(), more.pieces.end());
      ASSERT_TRUE(model.Update(obs, pose).ok());
    }
    SCOPED_TRACE(across ? "crossing tape" : "tape in line");
    EXPECT_EQ(model.end_known(), across);
    if (across) {
      for (const TrackSample& s : model.samples()) EXPECT_LT(s.xy.x(), 3.05);
    }
  }
}

TEST(TrackModelTest, IgnoresOtherTapeBesideTheTrack) {
  // A second tape 0.5 m to the left (the loop coming back) never joins the track.
  SyntheticTrack track{{{0, 0}, {6, 0}}, {}};
  SyntheticTrack other{{{6, 0.5}, {0, 0.5}}, {}};
  TrackModel model;
  for (double x = 0; x <= 1.0; x += 0.02) {
    const Pose2 pose{x, 0, 0};
    TrackObservation obs = SyntheticObservation(track, pose, WideView(), 0);
    const TrackObservation more = SyntheticObservation(other, pose, WideView(), 0);
    obs.pieces.insert(obs.pieces.end(), more.pieces.begin(), more.pieces.end());
    ASSERT_TRUE(model.Update(obs, pose).ok());
  }
  for (const TrackSample& s : model.samples()) EXPECT_NEAR(s.xy.y(), 0.0, 1e-9);
}

TEST(TrackModelTest, FollowsTheNewestViewWhenOdometryDrifts) {
  // Odometry drifts 3 cm sideways: the track ahead in the model moves with the newest observation,
  // so relative to the vehicle it stays where the cameras see it.
  SyntheticTrack track{{{0, 0}, {8, 0}}, {}};
  TrackModel model;
  DriveStraight(&model, track, 0.0, 0.5, 0.0);
  DriveStraight(&model, track, 0.52, 1.0, 0.03);
  const TrackAhead ahead = model.Ahead(2.0, 0.0);
  ASSERT_TRUE(ahead.valid());
  for (const Vec2d& p : ahead.points) EXPECT_NEAR(p.y(), 0.03, 0.005);
}

TEST(TrackModelTest, DropsAnExtensionTheCamerasNoLongerSee) {
  TrackModel model;
  SyntheticTrack long_track{{{0, 0}, {3, 0}}, {}};
  const Pose2 pose{0, 0, 0};
  ASSERT_TRUE(model.Update(SyntheticObservation(long_track, pose, WideView(), 0), pose).ok());
  // The tape really ends at 2 m (the first view was wrong beyond it): after a few frames the model
  // ends there too.
  SyntheticTrack short_track{{{0, 0}, {2, 0}}, {}};
  for (int i = 1; i < 8; ++i) ASSERT_TRUE(model.Update(SyntheticObservation(short_track, pose, WideView(), i), pose).ok());
  EXPECT_NEAR(model.samples().back().xy.x(), 2.0, 0.02);
}

TEST(TrackModelTest, KeepsTheNextLegOfAnAcuteCornerWhenOnlyItsTipIsInView) {
  // A 120 deg left corner at (2, 0). From the approach the cameras see the next leg's first metre or
  // so; 3 cm before the vertex only the corner's tip (a few cm of each leg, less than evidence_span_m)
  // is inside the view, too short for perception to report: blank views there are no evidence
  // against the leg.
  const double c = std::cos(2 * kPi / 3), s = std::sin(2 * kPi / 3);
  SyntheticTrack track{{{0, 0}, {2, 0}, {2 + 2 * c, 2 * s}}, {}};
  TrackModel model;
  DriveStraight(&model, track, 0.0, 1.9);
  const Vec2d d2(c, s);
  auto leg_known = [&] {  // how far the model runs along the next leg
    double known = 0;
    for (const TrackSample& t : model.samples()) {
      const Vec2d r = t.xy - Vec2d(2, 0);
      if (std::abs(d2.x() * r.y() - d2.y() * r.x()) < 0.02) known = std::max(known, r.dot(d2));
    }
    return known;
  };
  ASSERT_GT(leg_known(), 1.0);
  const Pose2 at_tip{1.97, 0, 0};
  for (int i = 0; i < 10; ++i) {
    TrackObservation blank;
    blank.timestamp_ns = static_cast<int64_t>(3e9) + i;
    blank.footprints_m = WideView();
    ASSERT_TRUE(model.Update(blank, at_tip).ok());
  }
  EXPECT_GT(leg_known(), 1.0);
}

TEST(TrackModelTest, StillCutsTrackContradictedWellInsideTheView) {
  // The same blank views with the whole next leg in view (a view from further back) do cut it.
  const double c = std::cos(2 * kPi / 3), s = std::sin(2 * kPi / 3);
  SyntheticTrack track{{{0, 0}, {2, 0}, {2 + 2 * c, 2 * s}}, {}};
  TrackModel model;
  DriveStraight(&model, track, 0.0, 0.5);
  for (int i = 0; i < 10; ++i) {
    TrackObservation blank;
    blank.timestamp_ns = static_cast<int64_t>(3e9) + i;
    blank.footprints_m = WideView();
    ASSERT_TRUE(model.Update(blank, Pose2{0.5, 0, 0}).ok());
  }
  for (const TrackSample& t : model.samples()) EXPECT_LT(t.xy.x(), 0.75);
}

// Perception lists a piece's points in either direction. Here the tape past a covered stretch is
// missed in one view (the model's stretch there is dropped, so the model ends where the gap does), and
// the next view lists it from its far end: it overlaps the model only at the model's last sample, whose
// direction is that of the step into it. It must join the model the right way round: in the closed loop
// a piece joined backwards made the model run to the tape's far end and back, and the vehicle turned
// round at the gap's far end (5 of 60 noise seeds of ClosedLoopTest's one-metre gap).
TEST(TrackModelTest, APieceListedFromItsFarEndJoinsTheModelTheRightWayRound) {
  SyntheticTrack track{{{0, 0}, {5, 0}}, {{1.2, 2.2}}};
  TrackModel model;
  DriveStraight(&model, track, 0.0, 0.4);
  ASSERT_GT(model.samples().back().xy.x(), 3.0) << "the model bridged the gap";
  const Pose2 pose{0.42, 0, 0};
  for (int i = 0; i < 20 && model.samples().back().xy.x() > 2.3; ++i) {
    TrackObservation near = SyntheticObservation(track, pose, WideView(), static_cast<int64_t>(1e9) + i);
    std::erase_if(near.pieces, [](const CentreLinePiece& p) { return p.points_m.front().x() > 1.0; });
    ASSERT_EQ(near.pieces.size(), 1u);
    ASSERT_TRUE(model.Update(near, pose).ok());
  }
  const double end_after_miss = model.samples().back().xy.x();
  EXPECT_LT(end_after_miss, 2.3) << "the stretch past the gap that this view contradicts is dropped";
  TrackObservation both = SyntheticObservation(track, pose, WideView(), static_cast<int64_t>(1.1e9));
  ASSERT_EQ(both.pieces.size(), 2u);
  for (CentreLinePiece& p : both.pieces) {
    if (p.points_m.front().x() < p.points_m.back().x()) {
      std::reverse(p.points_m.begin(), p.points_m.end());
      std::swap(p.end_seen[0], p.end_seen[1]);
    }
  }
  ASSERT_TRUE(model.Update(both, pose).ok());
  const std::vector<TrackSample>& s = model.samples();
  ASSERT_GE(s.size(), 2u);
  int backwards = 0;
  for (std::size_t i = 1; i < s.size(); ++i) backwards += s[i].xy.x() < s[i - 1].xy.x() - 0.005;
  EXPECT_EQ(backwards, 0) << "the model steps back along the track";
  EXPECT_GT(s.back().xy.x(), 3.0) << "the tape past the gap is joined again (the model ended at " << end_after_miss
                                  << " m after the miss)";
}

}  // namespace
}  // namespace idi::rmp
