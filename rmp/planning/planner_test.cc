#include "rmp/planning/planner.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <functional>

#include "rmp/track/synthetic_observation.h"
#include "rmp/track/track_model.h"
#include "rmp/vehicle/camera_rig.h"
#include "shared/sim/vehicle/vehicle_twin.h"
#include "shared/util/units.h"

namespace idi::rmp {
namespace {

constexpr int64_t kMs = 1'000'000;

// Footprints of two cameras looking ahead and down from above the axle (1.2 m high, 55 deg down,
// 0.3 m apart, wide lenses): they see the ground from just behind the axle to ~4 m ahead.
std::vector<std::vector<Vec2d>> RigFootprints() {
  std::vector<std::vector<Vec2d>> out;
  for (double side : {1.0, -1.0}) {
    RigCamera cam;
    cam.intrinsics.params = {320, 320, 319.5, 239.5, 0, 0, 0, 0, 0};
    cam.vehicle_from_camera = LookAheadCameraPose(0.0, side * 0.15, 1.2, 0.0, 55.0 * kPi / 180);
    out.push_back(GroundFootprint(cam, 32.0, 4.0));
  }
  return out;
}

struct LoopResult {
  double rms = 0, max = 0;
  double end_distance = 1e9;  // from the track's last point when stopped
  double visible_fraction = 0;
  double max_yaw_rate = 0, max_speed = 0;
  double max_speed_step = 0;
  bool stopped = false;
  double time_s = 0;
};

double ArcLengthOfClosest(const std::vector<Vec2d>& line, const Vec2d& p, double* dist) {
  double best = 1e300, best_s = 0, s = 0;
  for (std::size_t i = 1; i < line.size(); ++i) {
    const Vec2d a = line[i - 1], d = line[i] - a;
    const double t = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
    const double e = (a + t * d - p).norm();
    if (e < best) {
      best = e;
      best_s = s + t * d.norm();
    }
    s += d.norm();
  }
  *dist = best;
  return best_s;
}

// Closed loop: the vehicle twin, odometry from its wheel encoders and gyro, the ideal perception at
// 15 Hz (40 ms processing latency), the track model and the planner at 50 Hz.
LoopResult RunLoop(const SyntheticTrack& track, double cruise, double max_time_s = 60) {
  sim::VehicleTwinOptions vo;
  const Vec2d d0 = (track.centre_m[1] - track.centre_m[0]).normalized();
  vo.start_x_m = track.centre_m[0].x();
  vo.start_y_m = track.centre_m[0].y();
  vo.start_yaw_rad = std::atan2(d0.y(), d0.x());
  vo.left_wheel_scale_error = 0.003;
  vo.right_wheel_scale_error = -0.002;
  vo.slip_noise_m_per_sqrt_m = 0.001;
  sim::VehicleTwin twin(vo);
  PlannerOptions po;
  po.cruise_speed_mps = cruise;
  Planner planner(po);
  TrackModel model;
  const auto footprints = RigFootprints();
  std::mt19937_64 rng(7);
  SyntheticObservationOptions so;
  so.noise_m = 0.002;

  // Odometry from the encoders (differential drive) and the history of it for late observations.
  Pose2 odom{};
  double last_l = 0, last_r = 0;
  std::deque<std::pair<int64_t, Pose2>> history;
  struct Pending {
    int64_t apply_ns, capture_ns;
    TrackObservation obs;
  };
  std::deque<Pending> pending;
  LoopResult r;
  double sum2 = 0;
  int n = 0, frames = 0, visible = 0;
  double track_len = PolylineLength(track.centre_m);
  int64_t stopped_since = -1;
  double last_cmd_v = 0;
  for (int64_t t = 0; t < static_cast<int64_t>(max_time_s * 1000) * kMs; t += 20 * kMs) {
    twin.AdvanceTo(t);
    const sim::VehicleSensors& sens = twin.sensors();
    const double dl = sens.left_wheel_m - last_l, dr = sens.right_wheel_m - last_r;
    last_l = sens.left_wheel_m;
    last_r = sens.right_wheel_m;
    const double ds = 0.5 * (dl + dr), dyaw = (dr - dl) / vo.wheel_separation_m;
    odom = odom * Pose2{ds * std::cos(0.5 * dyaw), ds * std::sin(0.5 * dyaw), dyaw};
    history.emplace_back(t, odom);
    while (history.size() > 50) history.pop_front();
    const sim::VehicleTruth& truth = twin.truth();
    const Pose2 world_from_vehicle{truth.x_m, truth.y_m, truth.yaw_rad};
    if (t % (66 * kMs) < 20 * kMs) {  // ~15 Hz camera
      pending.push_back({t + 40 * kMs, t, SyntheticObservation(track, world_from_vehicle, footprints, t, so, &rng)});
      // Visibility of the coming track (truth) while following.
      double dist = 0;
      const double s_now = ArcLengthOfClosest(track.centre_m, world_from_vehicle.translation(), &dist);
      if (track_len - s_now > 0.15) {
        ++frames;
        const auto obs = pending.back().obs;
        double ahead_visible = 0;
        for (const auto& piece : obs.pieces) {
          for (std::size_t i = 1; i < piece.points_m.size(); ++i) {
            const Vec2d mid = world_from_vehicle * (0.5 * (piece.points_m[i] + piece.points_m[i - 1]));
            double dd = 0;
            if (ArcLengthOfClosest(track.centre_m, mid, &dd) > s_now) ahead_visible += (piece.points_m[i] - piece.points_m[i - 1]).norm();
          }
        }
        if (ahead_visible >= 0.05) ++visible;
      }
    }
    while (!pending.empty() && pending.front().apply_ns <= t) {
      Pose2 at_capture = odom;
      for (const auto& [ht, hp] : history) {
        if (ht == pending.front().capture_ns) at_capture = hp;
      }
      EXPECT_TRUE(model.Update(pending.front().obs, at_capture).ok());
      pending.pop_front();
    }
    model.UpdateProgress(odom);
    PlannerInput in;
    in.now_ns = t;
    in.odom_from_vehicle = odom;
    in.speed_mps = 0.5 * (sens.left_wheel_mps + sens.right_wheel_mps);
    in.yaw_rate_rps = sens.yaw_rate_rps;
    in.track = model.Ahead(4.0);
    in.footprints_m = footprints;
    const PlanOutput out = planner.Plan(in);
    twin.Command(t, {out.speed_mps, out.yaw_rate_rps});
    planner.CommandSent(t, out.speed_mps, out.yaw_rate_rps);
    r.max_yaw_rate = std::max(r.max_yaw_rate, std::abs(out.yaw_rate_rps));
    r.max_speed = std::max(r.max_speed, out.speed_mps);
    r.max_speed_step = std::max(r.max_speed_step, out.speed_mps - last_cmd_v);
    last_cmd_v = out.speed_mps;
    double dist = 0;
    ArcLengthOfClosest(track.centre_m, world_from_vehicle.translation(), &dist);
    sum2 += dist * dist;
    ++n;
    r.max = std::max(r.max, dist);
    if (out.state == PlanState::kAtEnd && std::abs(truth.speed_mps) < 1e-3) {
      if (stopped_since < 0) stopped_since = t;
      if (t - stopped_since > 500 * kMs) {
        r.stopped = true;
        r.end_distance = (world_from_vehicle.translation() - track.centre_m.back()).norm();
        r.time_s = static_cast<double>(t) * 1e-9;
        break;
      }
    } else {
      stopped_since = -1;
    }
  }
  r.rms = std::sqrt(sum2 / std::max(1, n));
  r.visible_fraction = frames > 0 ? static_cast<double>(visible) / frames : 0.0;
  return r;
}

TEST(PlannerTest, StopsWithoutTrack) {
  Planner planner;
  PlannerInput in;
  const PlanOutput out = planner.Plan(in);
  EXPECT_TRUE(out.stopped());
  EXPECT_EQ(out.state, PlanState::kNoTrack);
}

TEST(PlannerTest, RejectsBadOptions) {
  PlannerOptions o;
  EXPECT_TRUE(o.Check().ok());
  o.max_yaw_rate_rps = 0;
  EXPECT_NE(o.Check().message().find("max_yaw_rate_rps"), std::string::npos);
  o = {};
  o.cruise_speed_mps = 5.0;
  EXPECT_NE(o.Check().message().find("cruise_speed_mps"), std::string::npos);
  // Values that hung the loop or made every tick "off track" (a latency in ms given as s).
  o = {};
  o.command_latency_s = 50;
  EXPECT_NE(o.Check().message().find("command_latency_s"), std::string::npos);
  o = {};
  o.response_time_constant_s = 3600;
  EXPECT_NE(o.Check().message().find("response_time_constant_s"), std::string::npos);
  o = {};
  o.max_corner_cut_m = 1e300;
  EXPECT_NE(o.Check().message().find("max_corner_cut_m"), std::string::npos);
  o = {};
  o.min_corner_turn_deg = NAN;
  EXPECT_NE(o.Check().message().find("min_corner_turn_deg"), std::string::npos);
  o = {};
  o.min_support = 0;
  EXPECT_NE(o.Check().message().find("min_support"), std::string::npos);
}

TEST(PlannerClosedLoopTest, FollowsAStraightTapeAndStopsAtItsEnd) {
  const LoopResult r = RunLoop({{{0, 0}, {4, 0}}, {}}, 0.5);
  EXPECT_TRUE(r.stopped);
  EXPECT_LT(r.end_distance, 0.1);
  EXPECT_LT(r.rms, 0.01);
  EXPECT_LT(r.max, 0.03);
  EXPECT_EQ(r.visible_fraction, 1.0);
  EXPECT_LE(r.max_speed, 0.5 + 1e-9);
}

TEST(PlannerClosedLoopTest, TurnsRightAngledCornersWithinTheErrorBudget) {
  for (double side : {1.0, -1.0}) {
    const LoopResult r = RunLoop({{{0, 0}, {2.5, 0}, {2.5, side * 2.5}}, {}}, 0.5);
    EXPECT_TRUE(r.stopped) << side;
    EXPECT_LT(r.end_distance, 0.1) << side;
    EXPECT_LT(r.rms, 0.02) << side;
    EXPECT_LT(r.max, 0.06) << side;
    EXPECT_EQ(r.visible_fraction, 1.0) << side;
    EXPECT_LE(r.max_yaw_rate, PlannerOptions{}.max_yaw_rate_rps + 1e-9);
  }
}

TEST(PlannerClosedLoopTest, TurnsA120DegreeCornerAndBridgesAGap) {
  const double c = std::cos(2 * kPi / 3), s = std::sin(2 * kPi / 3);
  const LoopResult r = RunLoop({{{0, 0}, {2.5, 0}, {2.5 + 2.5 * c, 2.5 * s}}, {{1.0, 1.5}}}, 0.5);
  EXPECT_TRUE(r.stopped);
  EXPECT_LT(r.end_distance, 0.1);
  EXPECT_LT(r.rms, 0.02);
  EXPECT_LT(r.max, 0.06);
  EXPECT_EQ(r.visible_fraction, 1.0);
}

TEST(PlannerClosedLoopTest, FollowsAnSCurveAtOneMetrePerSecond) {
  std::vector<Vec2d> pts = {{0, 0}, {1.5, 0}};
  double heading = 0;
  Vec2d p(1.5, 0);
  for (int i = 0; i < 12; ++i) {  // left arc of 12 x 15 deg segments of 0.15 m
    heading += kPi / 12;
    p += 0.15 * Vec2d(std::cos(heading), std::sin(heading));
    pts.push_back(p);
  }
  for (int i = 0; i < 12; ++i) {
    heading -= kPi / 12;
    p += 0.15 * Vec2d(std::cos(heading), std::sin(heading));
    pts.push_back(p);
  }
  pts.push_back(p + 1.5 * Vec2d(std::cos(heading), std::sin(heading)));
  const LoopResult r = RunLoop({pts, {}}, 1.0);
  EXPECT_TRUE(r.stopped);
  EXPECT_LT(r.end_distance, 0.1);
  EXPECT_LT(r.rms, 0.04);
  EXPECT_EQ(r.visible_fraction, 1.0);
}

// A 135 deg right corner at the origin as the track model would carry it after the approach: leg 1
// along +x up to the vertex, leg 2 from it at -135 deg, every point seen repeatedly (support 8) by
// observations up to `seen_ns`.
// With `stub`, the model has a 4.5 cm blip beyond the vertex (forward and to the left) from which the
// next leg starts, as fusion once made it while the vehicle pivoted there.
TrackAhead AcuteCornerAhead(int64_t seen_ns, bool stub = false) {
  TrackAhead t;
  const Vec2d d2(std::cos(-3 * kPi / 4), std::sin(-3 * kPi / 4));
  for (double x = -1.0; x < -1e-9; x += 0.01) t.points.emplace_back(x, 0.0);
  const Vec2d leg2_start = stub ? Vec2d(0.04, 0.02) : Vec2d(0.0, 0.0);
  if (stub) {
    for (double a = 0.0; a < 1.0 - 1e-9; a += 0.25) t.points.push_back(a * leg2_start);
  }
  for (double a = 0.0; a <= 1.5 + 1e-9; a += 0.01) t.points.push_back(leg2_start + a * d2);
  t.support.assign(t.points.size(), 8);
  t.gap.assign(t.points.size(), false);
  t.seen_ns.assign(t.points.size(), seen_ns);
  t.length_m = 2.5;
  return t;
}

// A right-angled right corner at (vertex_x, 0): leg 1 along +x from x = -1, leg 2 along -y for 2 m,
// seen repeatedly.
TrackAhead RightCornerAhead(double vertex_x) {
  TrackAhead t;
  for (double x = -1.0; x < vertex_x - 1e-9; x += 0.01) t.points.emplace_back(x, 0.0);
  for (double y = 0.0; y >= -2.0 - 1e-9; y -= 0.01) t.points.emplace_back(vertex_x, y);
  t.support.assign(t.points.size(), 8);
  t.gap.assign(t.points.size(), false);
  t.seen_ns.assign(t.points.size(), 0);
  t.length_m = vertex_x + 3.0;
  return t;
}

// The turn decided for a corner is kept while fusion moves its vertex by a centimetre or two (it did
// so only within one cm grid cell: at the zigzag's third corner a 1 cm shift near the vertex re-decided
// the turn, swapping the tight arc for the widest one too late, 11 cm off the tape); a corner that
// really moved is decided again.
TEST(PlannerTest, KeepsTheTurnDecidedForACornerWhileItsVertexJitters) {
  Planner planner;
  auto plan = [&](double vertex_x, double vehicle_x, const std::vector<std::vector<Vec2d>>& footprints) {
    PlannerInput in;
    in.odom_from_vehicle = {vehicle_x, 0.0, 0.0};
    in.speed_mps = 0.3;
    in.track = RightCornerAhead(vertex_x);
    in.footprints_m = footprints;
    return planner.Plan(in);
  };
  const PlanOutput first = plan(2.004, 0.5, RigFootprints());
  ASSERT_GT(first.corner_radius_m, 0.0);
  EXPECT_TRUE(first.corner_in_view);
  // Views that would no longer show the track through that turn (a footprint far off the track).
  const std::vector<std::vector<Vec2d>> elsewhere = {{{50, 50}, {51, 50}, {51, 51}, {50, 51}}};
  const PlanOutput jittered = plan(2.016, 1.6, elsewhere);
  EXPECT_DOUBLE_EQ(jittered.corner_radius_m, first.corner_radius_m);
  EXPECT_TRUE(jittered.corner_in_view) << "the decision made from afar holds";
  const PlanOutput moved = plan(2.3, 1.6, elsewhere);
  EXPECT_FALSE(moved.corner_in_view) << "a corner 30 cm away is a new corner, decided afresh";
}

struct PivotRun {
  std::vector<PlanState> states;
  Pose2 pose;
  double max_speed_in_pivot = 0.0;
  double max_speed_step_in_pivot = -1.0;  // largest increase of the commanded speed while pivoting
  double max_vertex_distance_in_pivot = 0.0;
  double turned_rad = 0.0;  // total |yaw change|
  int64_t end_ns = 0;
  bool was_active = false;
};

// Drives an ideal vehicle (it does what is commanded, at once) from 0.3 m before the vertex with the
// track of AcuteCornerAhead; `seen_at_yaw_deg`: once the vehicle has turned this far, the next leg is
// seen again (negative: never); `stuck`: the wheels slip, the vehicle never turns.
// `stub_at_yaw_deg`: once the vehicle has turned this far, the model has the blip of AcuteCornerAhead's
// `stub` (negative: never).
// `t0_ns`: the clock at the start (a later approach with the same planner).
PivotRun RunAcuteCorner(
    double seen_at_yaw_deg, bool stuck, Planner* planner, double stub_at_yaw_deg = -1.0, int64_t t0_ns = 0) {
  PivotRun r;
  r.pose = {-0.3, 0.0, 0.0};
  double v = 0.2, w = 0.0;
  int64_t seen_ns = t0_ns;
  for (int64_t t = t0_ns; t < t0_ns + 15'000 * kMs; t += 20 * kMs) {
    if (seen_at_yaw_deg >= 0 && std::abs(r.pose.yaw) * 180 / kPi >= seen_at_yaw_deg) seen_ns = t;
    PlannerInput in;
    in.now_ns = t;
    in.odom_from_vehicle = r.pose;
    in.speed_mps = v;
    in.yaw_rate_rps = w;
    in.track = AcuteCornerAhead(seen_ns, stub_at_yaw_deg >= 0 && std::abs(r.pose.yaw) * 180 / kPi >= stub_at_yaw_deg);
    const PlanOutput out = planner->Plan(in);
    planner->CommandSent(t, out.speed_mps, out.yaw_rate_rps);
    r.states.push_back(out.state);
    r.was_active = r.was_active || planner->corner_turn_active();
    if (out.state == PlanState::kCornerPivot) {
      r.max_speed_in_pivot = std::max(r.max_speed_in_pivot, out.speed_mps);
      r.max_speed_step_in_pivot = std::max(r.max_speed_step_in_pivot, out.speed_mps - v);
      r.max_vertex_distance_in_pivot = std::max(r.max_vertex_distance_in_pivot, r.pose.translation().norm());
    }
    r.end_ns = t;
    if (out.state == PlanState::kNoTrack) break;
    if (out.state == PlanState::kFollow && r.turned_rad > 2.0 && (r.pose.translation().norm() > 0.3)) break;
    v = out.speed_mps;
    w = stuck ? 0.0 : out.yaw_rate_rps;
    const double yaw_before = r.pose.yaw;
    r.pose = IntegrateUnicycle(r.pose, v, w, 0.02);
    r.turned_rad += std::abs(WrapAngle(r.pose.yaw - yaw_before));
  }
  return r;
}

bool Visited(const PivotRun& r, PlanState s) { return std::find(r.states.begin(), r.states.end(), s) != r.states.end(); }

TEST(PlannerCornerPivotTest, StopsAtTheVertexTurnsOnTheSpotAndFollowsTheReacquiredLeg) {
  Planner planner;
  const PivotRun r = RunAcuteCorner(60.0, false, &planner);
  EXPECT_TRUE(Visited(r, PlanState::kCornerApproach));
  EXPECT_TRUE(Visited(r, PlanState::kCornerPivot));
  EXPECT_FALSE(Visited(r, PlanState::kNoTrack)) << planner.corner_turn_failure();
  // On the spot: it arrives braking (the last mm at the deceleration limit), never speeds up while
  // turning and stays at the vertex.
  EXPECT_LT(r.max_speed_in_pivot, 0.1);
  EXPECT_LE(r.max_speed_step_in_pivot, 0.0);
  EXPECT_LT(r.max_vertex_distance_in_pivot, 0.03);
  EXPECT_FALSE(planner.corner_turn_active());
  EXPECT_TRUE(planner.corner_turn_failure().empty());
  // Now driving down the next leg, on it.
  EXPECT_EQ(r.states.back(), PlanState::kFollow);
  const Vec2d d2(std::cos(-3 * kPi / 4), std::sin(-3 * kPi / 4));
  EXPECT_GT(r.pose.translation().dot(d2), 0.3);
  EXPECT_LT(std::abs(d2.x() * r.pose.y - d2.y() * r.pose.x), 0.03);
  EXPECT_NEAR(WrapAngle(r.pose.yaw + 3 * kPi / 4), 0.0, 0.1);
}

// Mid-pivot the model gains a 4.5 cm blip beyond the vertex from which the next leg starts: the corner's
// legs are those beyond the blip, so the pivot goes on the same way round and ends on the next leg. (With
// the blip taken as the next leg, the corner became a 27 deg left bend, the pivot reversed and the
// manoeuvre failed "turned beyond the corner's angle".)
TEST(PlannerCornerPivotTest, ABlipAtTheVertexIsNotTheNextLeg) {
  Planner planner;
  const PivotRun r = RunAcuteCorner(60.0, false, &planner, 30.0);
  EXPECT_TRUE(Visited(r, PlanState::kCornerPivot));
  EXPECT_FALSE(Visited(r, PlanState::kNoTrack)) << planner.corner_turn_failure();
  EXPECT_TRUE(planner.corner_turn_failure().empty()) << planner.corner_turn_failure();
  EXPECT_EQ(r.states.back(), PlanState::kFollow);
  EXPECT_NEAR(WrapAngle(r.pose.yaw + 3 * kPi / 4), 0.0, 0.1);
  EXPECT_LT(r.turned_rad, 3 * kPi / 4 + DegToRad(PlannerOptions{}.pivot_extra_deg)) << "it never turned back";
}

TEST(PlannerCornerPivotTest, StopsWhenFacingTheRememberedLegWithoutSeeingIt) {
  Planner planner;
  const PivotRun r = RunAcuteCorner(-1.0, false, &planner);
  ASSERT_TRUE(r.was_active);
  EXPECT_EQ(r.states.back(), PlanState::kNoTrack);
  EXPECT_FALSE(planner.corner_turn_active());
  EXPECT_NE(planner.corner_turn_failure().find("without seeing it again"), std::string::npos);
  // It turned to face the leg (135 deg), not beyond the bound, and stayed at the vertex.
  EXPECT_NEAR(r.pose.yaw, -3 * kPi / 4, DegToRad(PlannerOptions{}.pivot_done_deg) + 0.02);
  EXPECT_LE(r.turned_rad, 3 * kPi / 4 + DegToRad(PlannerOptions{}.pivot_extra_deg));
  EXPECT_LT(r.pose.translation().norm(), 0.03);
}

// An ideal vehicle (it does what is commanded, at once) driven by `planner` in 20 ms ticks from t0_ns
// to t1_ns on the track `track_at(t)`; `on_plan` sees each output and returns false to stop there.
struct IdealVehicle {
  Pose2 pose;
  double v = 0.0, w = 0.0;
};
void DriveIdeal(Planner* planner,
                IdealVehicle* vehicle,
                int64_t t0_ns,
                int64_t t1_ns,
                const std::function<TrackAhead(int64_t)>& track_at,
                const std::function<bool(const PlanOutput&)>& on_plan) {
  for (int64_t t = t0_ns; t < t1_ns; t += 20 * kMs) {
    PlannerInput in;
    in.now_ns = t;
    in.odom_from_vehicle = vehicle->pose;
    in.speed_mps = vehicle->v;
    in.yaw_rate_rps = vehicle->w;
    in.track = track_at(t);
    const PlanOutput out = planner->Plan(in);
    planner->CommandSent(t, out.speed_mps, out.yaw_rate_rps);
    if (!on_plan(out)) return;
    vehicle->v = out.speed_mps;
    vehicle->w = out.yaw_rate_rps;
    vehicle->pose = IntegrateUnicycle(vehicle->pose, vehicle->v, vehicle->w, 0.02);
  }
}

// After a failed manoeuvre the vehicle stands at the vertex; once the track is seen again the ordinary
// rules hold there (the corner is not retried), and the vehicle is not held at the vertex for ever.
TEST(PlannerCornerPivotTest, AfterAFailedTurnTheTrackSeenAgainIsFollowed) {
  Planner planner;
  const PivotRun r = RunAcuteCorner(-1.0, false, &planner);
  ASSERT_EQ(r.states.back(), PlanState::kNoTrack);
  ASSERT_NE(planner.corner_turn_failure().find("without seeing it again"), std::string::npos);
  IdealVehicle vehicle{r.pose};
  double max_v = 0.0;
  DriveIdeal(
      &planner,
      &vehicle,
      r.end_ns + 20 * kMs,
      r.end_ns + 10'000 * kMs,
      [](int64_t t) { return AcuteCornerAhead(t); },  // seen again
      [&](const PlanOutput& out) {
        max_v = std::max(max_v, out.speed_mps);
        return true;
      });
  const Pose2& pose = vehicle.pose;
  EXPECT_FALSE(planner.corner_turn_active());
  EXPECT_GT(max_v, 0.05);
  const Vec2d d2(std::cos(-3 * kPi / 4), std::sin(-3 * kPi / 4));
  EXPECT_GT(pose.translation().dot(d2), 0.2) << "it went on down the next leg";
}

TEST(PlannerCornerPivotTest, GivesUpWhenTheTurnTakesTooLong) {
  Planner planner;
  const PivotRun r = RunAcuteCorner(-1.0, true, &planner);
  ASSERT_TRUE(r.was_active);
  EXPECT_EQ(r.states.back(), PlanState::kNoTrack);
  EXPECT_NE(planner.corner_turn_failure().find("pivot_timeout_s"), std::string::npos);
  EXPECT_LE(static_cast<double>(r.end_ns) * 1e-9, PlannerOptions{}.pivot_timeout_s + 2.0);
}

TEST(PlannerCornerPivotTest, DoesNotPivotOnANextLegSeenOnlyOnce) {
  Planner planner;
  PlannerInput in;
  in.odom_from_vehicle = {-0.1, 0.0, 0.0};
  in.track = AcuteCornerAhead(0);
  in.track.support.assign(in.track.support.size(), 1);
  for (int i = 0; i < 20; ++i) {
    in.now_ns = i * 20 * kMs;
    const PlanOutput out = planner.Plan(in);
    planner.CommandSent(in.now_ns, out.speed_mps, out.yaw_rate_rps);
    EXPECT_NE(out.state, PlanState::kCornerPivot);
    EXPECT_FALSE(planner.corner_turn_active());
  }
}

// A corner turned once is met again (the next lap of a closed track, the odometry's drift below 0.2 m):
// once the vehicle has left it behind, it is a new corner, approached and turned again. Before, the
// turned vertex was remembered for ever: the path was cut there and the vehicle stopped off track.
TEST(PlannerCornerPivotTest, ACornerMetAgainOnTheNextLapIsTurnedAgain) {
  Planner planner;
  const PivotRun first = RunAcuteCorner(60.0, false, &planner);
  ASSERT_FALSE(Visited(first, PlanState::kNoTrack)) << planner.corner_turn_failure();
  ASSERT_EQ(first.states.back(), PlanState::kFollow);
  // Down the next leg, away from the corner.
  const Vec2d d2(std::cos(-3 * kPi / 4), std::sin(-3 * kPi / 4));
  PlannerInput away;
  away.now_ns = first.end_ns + 20 * kMs;
  away.odom_from_vehicle = {1.2 * d2.x(), 1.2 * d2.y(), -3 * kPi / 4};
  away.speed_mps = 0.2;
  away.track = AcuteCornerAhead(0);
  EXPECT_EQ(planner.Plan(away).state, PlanState::kFollow);
  // The next lap: the same corner again.
  const PivotRun again = RunAcuteCorner(60.0, false, &planner, -1.0, away.now_ns + 60'000 * kMs);
  EXPECT_TRUE(Visited(again, PlanState::kCornerPivot));
  EXPECT_EQ(again.states.back(), PlanState::kFollow);
}

// A 165 deg corner: near the vertex the incoming leg lies inside the next leg's band (points of leg 1
// 10-19 cm back are within 5 cm of leg 2's line). Seeing only the incoming leg again during the pivot
// is not re-acquiring the next one (before, it was, and the pivot ended as if the next leg were seen).
TEST(PlannerCornerPivotTest, OnAVerySharpCornerTheIncomingLegIsNotTheNextLeg) {
  const Vec2d d2(std::cos(DegToRad(-165.0)), std::sin(DegToRad(-165.0)));
  auto track = [&](int64_t leg1_seen_ns) {
    TrackAhead t;
    for (double x = -1.0; x < -1e-9; x += 0.01) t.points.emplace_back(x, 0.0);
    const std::size_t leg1 = t.points.size();
    for (double a = 0.0; a <= 1.5 + 1e-9; a += 0.01) t.points.push_back(a * d2);
    t.support.assign(t.points.size(), 8);
    t.gap.assign(t.points.size(), false);
    t.seen_ns.assign(t.points.size(), 0);
    for (std::size_t i = 0; i < leg1; ++i) t.seen_ns[i] = leg1_seen_ns;
    t.length_m = 2.5;
    return t;
  };
  Planner planner;
  IdealVehicle vehicle{{-0.3, 0.0, 0.0}, 0.2, 0.0};
  bool pivoted = false;
  // The incoming leg seen at every tick, the next leg never again.
  DriveIdeal(&planner, &vehicle, 0, 15'000 * kMs, track, [&](const PlanOutput& out) {
    pivoted = pivoted || out.state == PlanState::kCornerPivot;
    return out.state != PlanState::kNoTrack;
  });
  EXPECT_TRUE(pivoted);
  EXPECT_NE(planner.corner_turn_failure().find("without seeing it again"), std::string::npos)
      << "failure: '" << planner.corner_turn_failure() << "'";
}

// An acute corner that is not turned on the spot (its next leg seen only once) ends the known track at
// its vertex: the vehicle stops there. Before, the corner's arc had radius 0 and no speed limit, so the
// vehicle reached the vertex at the uncertain-track speed, and the generic pivot then turned it on the
// spot without the manoeuvre's checks.
TEST(PlannerCornerPivotTest, StopsAtAnAcuteCornerItDoesNotTurn) {
  Planner planner;
  IdealVehicle vehicle{{-0.3, 0.0, 0.0}, 0.2, 0.0};
  bool pivoted = false;
  DriveIdeal(
      &planner,
      &vehicle,
      0,
      6'000 * kMs,
      [](int64_t) {
        TrackAhead t = AcuteCornerAhead(0);
        t.support.assign(t.support.size(), 1);
        return t;
      },
      [&](const PlanOutput& out) {
        pivoted = pivoted || out.state == PlanState::kPivot || out.state == PlanState::kCornerPivot;
        return true;
      });
  const Pose2& pose = vehicle.pose;
  const double v = vehicle.v;
  EXPECT_FALSE(pivoted);
  EXPECT_FALSE(planner.corner_turn_active());
  EXPECT_EQ(v, 0.0);
  EXPECT_LE(pose.x, 0.01) << "it stopped at the vertex, not beyond";
  EXPECT_GT(pose.x, -0.1) << "it drove up to the vertex";
  EXPECT_NEAR(pose.yaw, 0.0, DegToRad(5.0));
}

}  // namespace
}  // namespace idi::rmp
