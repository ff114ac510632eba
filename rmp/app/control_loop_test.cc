// The closed loop in the twin on short tracks with small images (fast), with the faults: a
// frozen camera, dropped frames, silence from the RMP, a bus-off, a low battery, a covered stretch,
// a track that ends - and in every run the vehicle never drives on stale data.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "rmp/app/replay_run.h"
#include "rmp/app/sim_run.h"
#include "shared/replay/drive_log.h"

namespace idi::rmp {
namespace {

namespace fs = std::filesystem;

struct SentFrame {
  int64_t t_ns, source_ns;
  int velocity, turn;
  bool status_fresh;
};

struct Observed {
  std::vector<SentFrame> sent;  // every command frame the driver put on the bus
  std::vector<TickRecord> ticks;
};

SimRunOptions SmallRun(const std::string& track_yaml, Observed* seen) {
  SimRunOptions o;
  o.config = DefaultRmpConfig();
  for (RigCamera* c : {&o.config.rig.left, &o.config.rig.right}) {
    c->intrinsics.width = 320;
    c->intrinsics.height = 240;
    c->intrinsics.params = {160.0, 160.0, 159.5, 119.5, 0, 0, 0, 0, 0};
  }
  o.config.perception.max_range_m = 3.0;
  o.config.sim.camera_rate_hz = 12.5;
  o.config.sim.scene.floor_noise = 0.0;
  auto t = ParseTrackYaml(track_yaml, "test-track");
  EXPECT_TRUE(t.ok()) << t.status().ToString();
  o.track = *t;
  o.on_tick = [seen](const TickRecord& rec, SimWorld&, const ControlLoop& loop) {
    seen->ticks.push_back(rec);
    const auto& recent = loop.driver()->recent_sent();
    if (recent.empty()) return;
    const RmpSentCommand& s = recent.back();
    if (!seen->sent.empty() && seen->sent.back().t_ns == s.timestamp_ns) return;
    seen->sent.push_back({s.timestamp_ns,
                          s.source_timestamp_ns,
                          s.frame.velocity_counts,
                          s.frame.turn_counts,
                          loop.driver()->health().status_fresh});
  };
  return o;
}

// The safety invariant: a command that moves the vehicle is computed from perception at most 0.2 s
// old (the source time is the stereo pair's exposure) and sent while the RMP's status is fresh.
void ExpectNeverDroveOnStaleData(const Observed& seen, double max_age_s = 0.2) {
  int moving = 0;
  for (const SentFrame& f : seen.sent) {
    if (f.velocity == 0 && f.turn == 0) continue;
    ++moving;
    ASSERT_GE(f.source_ns, 0) << "t=" << f.t_ns;
    EXPECT_LE(static_cast<double>(f.t_ns - f.source_ns) * 1e-9, max_age_s + 1e-9) << "t=" << f.t_ns;
    EXPECT_TRUE(f.status_fresh) << "t=" << f.t_ns;
  }
  EXPECT_GT(moving, 0);
}

// The last time a frame that moves the vehicle went out.
double LastMovingSend(const Observed& seen) {
  double last = -1;
  for (const SentFrame& f : seen.sent) {
    if (f.velocity != 0 || f.turn != 0) last = static_cast<double>(f.t_ns) * 1e-9;
  }
  return last;
}

constexpr const char* kStraight = "tape_width_m: 0.05\nspeed_mps: 0.5\npoints_m: [[0, 0], [2.2, 0]]\n";

TEST(ClosedLoopTest, FollowsAShortTrackAndStopsAtItsEnd) {
  Observed seen;
  auto res =
      RunSimulation(SmallRun("tape_width_m: 0.05\nspeed_mps: 0.5\npoints_m: [[0, 0], [1.6, 0], [1.6, 0.9]]\n", &seen));
  ASSERT_TRUE(res.ok()) << res.status().ToString();
  const RunReport& r = res->report;
  EXPECT_TRUE(r.completed) << r.ToJson().dump();
  EXPECT_LT(r.end_distance_m, 0.1);
  EXPECT_LT(r.lateral_error_rms_m, 0.02);
  EXPECT_LT(r.lateral_error_max_m, 0.06);
  EXPECT_EQ(r.track_visible_fraction, 1.0);
  EXPECT_GT(r.frames, 20u);
  EXPECT_GT(r.commands_nonzero, 50u);
  EXPECT_NEAR(r.distance_m, 2.5, 0.15);
  ExpectNeverDroveOnStaleData(seen);
  // Commands at a steady 50 Hz.
  for (std::size_t i = 1; i < seen.sent.size(); ++i) EXPECT_EQ(seen.sent[i].t_ns - seen.sent[i - 1].t_ns, 20'000'000);
}

TEST(ClosedLoopTest, AFrozenCameraStopsTheVehicle) {
  Observed seen;
  SimRunOptions o = SmallRun(kStraight, &seen);
  o.config.sim.faults.frozen_camera = "left";
  o.config.sim.faults.frozen_from_s = 1.5;
  o.config.sim.faults.frozen_to_s = 100;
  o.max_time_s = 4.0;
  auto res = RunSimulation(o);
  ASSERT_TRUE(res.ok()) << res.status().ToString();
  EXPECT_FALSE(res->report.completed);
  EXPECT_GT(res->report.frozen_frames, 0u);
  EXPECT_GT(res->report.decisions.at("perception-stale"), 0u);
  // The last good pair was exposed before 1.5 s: nothing moves the vehicle 0.2 s after that.
  EXPECT_LE(LastMovingSend(seen), 1.5 + 0.2 + 1e-6);
  EXPECT_GT(LastMovingSend(seen), 1.0);
  ExpectNeverDroveOnStaleData(seen);
}

// Each camera drops 30 % of its frames, so about half the pairs are incomplete and the vehicle often
// stands waiting for fresh perception: over noise seeds 1-40 the 3.6 m run finished in 10.4-21.4 s. (With
// each late pair restarting the finish hold at the end, seeds 2-4 took 26-35 s.)
TEST(ClosedLoopTest, DroppedFramesNeverLetItDriveOnStaleData) {
  for (uint64_t seed = 1; seed <= 4; ++seed) {
    SCOPED_TRACE("sim.seed " + std::to_string(seed));
    Observed seen;
    SimRunOptions o = SmallRun(kStraight, &seen);
    o.config.sim.camera_rate_hz = 15;
    o.config.sim.faults.drop_probability = 0.3;
    o.config.sim.seed = seed;
    o.max_time_s = 30.0;
    auto res = RunSimulation(o);
    ASSERT_TRUE(res.ok()) << res.status().ToString();
    EXPECT_GT(res->report.dropped_frames, 5u);
    EXPECT_TRUE(res->report.completed) << res->report.ToJson().dump();
    // The finish hold (1 s of 20 ms ticks) ran once, unbroken: 51 or 52 ticks by where the ticks fall
    // (52 in seeds 104, 403 and 503); a hold restarted by a late pair adds a tick or more per restart.
    EXPECT_LE(res->report.decisions.at("at-end"), 52u) << "the finish hold ran once, unbroken";
    ExpectNeverDroveOnStaleData(seen);
  }
}

TEST(ClosedLoopTest, SilenceFromTheRmpCommandsZeroUntilItSpeaksAgain) {
  Observed seen;
  SimRunOptions o = SmallRun(kStraight, &seen);
  o.config.sim.faults.rmp_silent_from_s = 1.5;
  o.config.sim.faults.rmp_silent_to_s = 2.2;
  o.max_time_s = 15.0;
  auto res = RunSimulation(o);
  ASSERT_TRUE(res.ok()) << res.status().ToString();
  EXPECT_GT(res->report.decisions.at("rmp-status-stale"), 0u);
  for (const SentFrame& f : seen.sent) {
    const double t = static_cast<double>(f.t_ns) * 1e-9;
    // Status times out 0.1 s after the last cycle; from then until it is heard again: zero.
    if (t > 1.5 + 0.1 + 0.021 && t < 2.2) {
      EXPECT_EQ(f.velocity, 0) << t;
      EXPECT_EQ(f.turn, 0) << t;
    }
  }
  EXPECT_TRUE(res->report.completed) << res->report.ToJson().dump();
  ExpectNeverDroveOnStaleData(seen);
}

// The RMP keeps sending its status (so the status is fresh) but not the wheel integrators: the
// odometry stops, and a pose that old must not move the vehicle.
TEST(ClosedLoopTest, MissingWheelIntegratorsCommandZeroUntilTheyComeBack) {
  Observed seen;
  SimRunOptions o = SmallRun(kStraight, &seen);
  o.config.sim.faults.integrators_missing_from_s = 1.5;
  o.config.sim.faults.integrators_missing_to_s = 2.2;
  o.max_time_s = 15.0;
  auto res = RunSimulation(o);
  ASSERT_TRUE(res.ok()) << res.status().ToString();
  EXPECT_GT(res->report.decisions.at("odometry-stale"), 0u);
  int in_window = 0;
  for (const SentFrame& f : seen.sent) {
    const double t = static_cast<double>(f.t_ns) * 1e-9;
    // The odometry's last update is at most one 10 ms status cycle before 1.5 s; 0.1 s later, and one
    // 20 ms tick for the decision to reach the bus: zero until the integrators are heard again.
    if (t > 1.5 + 0.1 + 0.021 && t < 2.2) {
      ++in_window;
      EXPECT_TRUE(f.status_fresh) << t << ": the status itself never stopped";
      EXPECT_EQ(f.velocity, 0) << t;
      EXPECT_EQ(f.turn, 0) << t;
    }
  }
  EXPECT_GT(in_window, 20);
  // Pairs exposed while the odometry had no pose are not fused into the track model (before, they were
  // placed at the last pose heard, however old).
  int fused_blind = 0;
  for (const TickRecord& r : seen.ticks) {
    const double exposure = static_cast<double>(r.perception_exposure_ns) * 1e-9;
    if (r.perceived && exposure > 1.5 + 0.1 + 0.011 && exposure < 2.2) ++fused_blind;
  }
  EXPECT_EQ(fused_blind, 0);
  EXPECT_GT(res->stats.pairs_without_pose, 3u);
  EXPECT_EQ(res->report.ToJson().at("pairs_without_pose").get<uint64_t>(), res->stats.pairs_without_pose);
  EXPECT_TRUE(res->report.completed) << res->report.ToJson().dump();
  ExpectNeverDroveOnStaleData(seen);
}

// The cameras' clock glitches once: both frames of one capture are stamped 10 s ahead. That pair is
// not perceived, and it does not hold back the pairs after it (before, every pair was refused until the
// clock reached the glitch's stamp, and the vehicle stood for 10 s).
TEST(ClosedLoopTest, APairStampedAheadOfTheClockIsNotUsedAndHoldsNothingBack) {
  Observed seen;
  SimRunOptions o = SmallRun(kStraight, &seen);
  o.config.sim.faults.stamp_glitch_at_s = 1.5;
  o.config.sim.faults.stamp_glitch_s = 10.0;
  o.max_time_s = 9.0;
  auto res = RunSimulation(o);
  ASSERT_TRUE(res.ok()) << res.status().ToString();
  EXPECT_EQ(res->stats.pairs_from_the_future, 1u);
  EXPECT_EQ(res->report.ToJson().at("pairs_from_the_future").get<uint64_t>(), 1u);
  for (const TickRecord& r : seen.ticks) {
    if (r.perceived) {
      EXPECT_LE(r.perception_exposure_ns, r.t_ns) << "a pair from the future was perceived";
    }
  }
  EXPECT_TRUE(res->report.completed) << res->report.ToJson().dump();
  EXPECT_EQ(res->report.decisions.count("perception-stale") ? res->report.decisions.at("perception-stale") : 0u, 0u);
  ExpectNeverDroveOnStaleData(seen);
}

// control.max_run_s bounds a run: the twin stops there when no --max-time-s is given.
TEST(ClosedLoopTest, MaxRunSEndsTheRun) {
  Observed seen;
  SimRunOptions o = SmallRun(kStraight, &seen);
  o.config.control.max_run_s = 2.0;
  auto res = RunSimulation(o);
  ASSERT_TRUE(res.ok()) << res.status().ToString();
  EXPECT_EQ(res->report.end, "time-limit");
  EXPECT_FALSE(res->report.completed);
  ASSERT_FALSE(seen.ticks.empty());
  EXPECT_LT(static_cast<double>(seen.ticks.back().t_ns) * 1e-9, 2.2);
}

TEST(ClosedLoopTest, ABusOffStopsItAndItRecovers) {
  Observed seen;
  SimRunOptions o = SmallRun(kStraight, &seen);
  o.config.sim.faults.bus_off_at_s = 1.5;
  o.config.sim.faults.bus_off_duration_s = 0.4;
  o.max_time_s = 15.0;
  auto res = RunSimulation(o);
  ASSERT_TRUE(res.ok()) << res.status().ToString();
  EXPECT_GT(res->report.decisions.at("bus-off") + res->report.decisions.at("rmp-status-stale"), 0u);
  EXPECT_TRUE(res->report.completed) << res->report.ToJson().dump();
  ExpectNeverDroveOnStaleData(seen);
}

TEST(ClosedLoopTest, ALowBatteryStopsTheVehicle) {
  Observed seen;
  SimRunOptions o = SmallRun(kStraight, &seen);
  o.config.sim.faults.battery_drop_at_s = 1.5;
  o.config.sim.faults.battery_drop_v = 15.0;  // 76 V -> 61 V, below the 66 V limit
  o.max_time_s = 4.0;
  auto res = RunSimulation(o);
  ASSERT_TRUE(res.ok()) << res.status().ToString();
  EXPECT_FALSE(res->report.completed);
  EXPECT_GT(res->report.decisions.at("low-battery"), 0u);
  EXPECT_LE(LastMovingSend(seen), 1.5 + 0.2);
}

// Over several noise seeds. When the tape past the gap could join the track model backwards (see
// TrackModelTest.APieceListedFromItsFarEndJoinsTheModelTheRightWayRound), the vehicle turned round at the
// gap's far end in 5 of seeds 1-60, seed 7 among them. In seed 104 a wrong stereo match in the first
// frame pulled the ground plane to a 9 deg pitch, which then held (GroundPlaneTest.AWrongLineMatch-
// ListedFirstDoesNotCaptureThePlane): the tape past the gap was never seen and the vehicle stood
// "track-lost" before the gap.
TEST(ClosedLoopTest, BridgesATrackCoveredForOneMetre) {
  for (const uint64_t seed : {1u, 2u, 3u, 4u, 5u, 6u, 7u, 8u, 104u}) {
    SCOPED_TRACE("sim.seed " + std::to_string(seed));
    Observed seen;
    SimRunOptions o = SmallRun("tape_width_m: 0.05\nspeed_mps: 0.5\npoints_m: [[0, 0], [3.6, 0]]\n", &seen);
    o.config.sim.faults.covered_m = {{1.2, 2.2}};
    o.config.sim.seed = seed;
    auto res = RunSimulation(o);
    ASSERT_TRUE(res.ok()) << res.status().ToString();
    EXPECT_TRUE(res->report.completed) << res->report.ToJson().dump();
    EXPECT_LT(res->report.end_distance_m, 0.5);
    EXPECT_LT(res->report.lateral_error_max_m, 0.06);
    ExpectNeverDroveOnStaleData(seen);
  }
}

TEST(ClosedLoopTest, TurnsAnAcuteCornerOnTheSpot) {
  // A 135 deg right corner: at the vertex the next leg lies behind the cameras' footprint. The vehicle
  // stops there, turns on the spot towards the leg it saw on the approach, re-acquires it and drives
  // it to the end - never on stale perception.
  // Seeds 23 and 31 are noise draws where fusion made a blip at the vertex while the vehicle pivoted
  // there, and the pivot reversed (PlannerCornerPivotTest.ABlipAtTheVertexIsNotTheNextLeg).
  for (const uint64_t seed : {1u, 23u, 31u}) {
    SCOPED_TRACE("sim.seed " + std::to_string(seed));
    Observed seen;
    SimRunOptions o =
        SmallRun("tape_width_m: 0.05\nspeed_mps: 0.5\npoints_m: [[0, 0], [1.8, 0], [0.5272, -1.2728]]\n", &seen);
    o.config.sim.seed = seed;
    auto res = RunSimulation(o);
    ASSERT_TRUE(res.ok()) << res.status().ToString();
    const RunReport& r = res->report;
    EXPECT_TRUE(r.completed) << r.ToJson().dump();
    EXPECT_LT(r.end_distance_m, 0.1);
    EXPECT_LT(r.lateral_error_max_m, 0.06);
    EXPECT_EQ(r.decisions.count("track-lost"), 0u) << r.ToJson().dump();
    bool pivoted = false;
    for (const TickRecord& t : seen.ticks) {
      if (t.plan.state != PlanState::kCornerPivot || t.decision != Decision::kDrive) continue;
      pivoted = true;
      EXPECT_LT(t.speed_mps, 0.1);  // on the spot (braking the last mm at most)
    }
    EXPECT_TRUE(pivoted);
    ExpectNeverDroveOnStaleData(seen);
  }
}

TEST(ClosedLoopTest, ReplayingARecordingReproducesItsCommands) {
  const fs::path dir = fs::temp_directory_path() / ("idi_rmp_replay_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  Observed seen;
  SimRunOptions o = SmallRun("tape_width_m: 0.05\nspeed_mps: 0.5\npoints_m: [[0, 0], [1.0, 0], [1.0, 0.6]]\n", &seen);
  o.record_dir = (dir / "log").string();
  // The replay rebuilds the pipeline from the configuration saved in the log.
  o.config_text =
      "rig:\n  width_px: 320\n  height_px: 240\n  left: {fx_px: 160, fy_px: 160, cx_px: 159.5, cy_px: 119.5}\n"
      "  right: {fx_px: 160, fy_px: 160, cx_px: 159.5, cy_px: 119.5}\nperception: {max_range_m: 3.0}\n";
  auto res = RunSimulation(o);
  ASSERT_TRUE(res.ok()) << res.status().ToString();
  ASSERT_TRUE(res->output_status.ok()) << res->output_status.ToString();  // the recording was written
  ASSERT_TRUE(res->report.completed);
  auto rep = RunReplay({o.record_dir, (dir / "replay.log").string()});
  ASSERT_TRUE(rep.ok()) << rep.status().ToString();
  EXPECT_GT(rep->ticks_compared, 100u);
  EXPECT_EQ(rep->ticks_matching, rep->ticks_compared);
  EXPECT_GT(rep->can_frames_compared, 100u);
  EXPECT_EQ(rep->can_frames_matching, rep->can_frames_compared);
  EXPECT_TRUE(rep->report.completed);
  EXPECT_EQ(rep->report.frames, res->report.frames);
  EXPECT_TRUE(fs::exists(dir / "replay.log"));
  EXPECT_EQ(rep->ticks_resynced, 0u);  // the twin's schedule and its frames' stamps agree to the ns
  {
    // On the vehicle the first frame is stamped a few microseconds after the clock reading that starts
    // the driver's schedule: the replay starts at the first tick, not at the first frame.
    const fs::path can = fs::path(o.record_dir) / replay::kDriveLogCanFile;
    std::ifstream in(can);
    std::stringstream text;
    std::string line;
    bool shifted = false;
    while (std::getline(in, line)) {
      if (!shifted && line.size() > 19 && line[0] == '(' && line[11] == '.' && line[18] == ')') {
        const long long us = std::stoll(line.substr(1, 10)) * 1000000LL + std::stoll(line.substr(12, 6)) + 5;
        char stamp[32];
        std::snprintf(stamp, sizeof(stamp), "(%010lld.%06lld)", us / 1000000LL, us % 1000000LL);
        line = stamp + line.substr(19);
        shifted = true;
      }
      text << line << "\n";
    }
    ASSERT_TRUE(shifted);
    in.close();
    std::ofstream(can) << text.str();
    auto late = RunReplay({o.record_dir, (dir / "replay_late.log").string()});
    ASSERT_TRUE(late.ok()) << late.status().ToString();
    EXPECT_EQ(late->ticks_matching, late->ticks_compared);
    EXPECT_EQ(late->ticks_compared, rep->ticks_compared);
    EXPECT_GE(late->can_frames_matching + 1, late->can_frames_compared);  // the moved frame, 5 us off
  }
  // Metadata of the wrong type in recording.json: refused naming the key, not a JSON exception.
  const fs::path rec = fs::path(o.record_dir) / "recording.json";
  nlohmann::json j;
  std::ifstream(rec) >> j;
  j["meta"]["cruise_speed_mps"] = "0.5";
  std::ofstream(rec) << j.dump();
  auto bad = RunReplay({o.record_dir, (dir / "replay2.log").string()});
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("meta.cruise_speed_mps must be a number"), std::string::npos)
      << bad.status().message();
  fs::remove_all(dir);
}

}  // namespace
}  // namespace idi::rmp
