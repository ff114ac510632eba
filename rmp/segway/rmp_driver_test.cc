// The driver against the simulated RMP on the virtual bus, on simulated time.
#include "rmp/segway/rmp_driver.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <functional>

#include "rmp/segway/sim_rmp.h"
#include "shared/replay/can_log_bus.h"
#include "shared/util/atomic_file.h"

namespace idi::rmp {
namespace {

constexpr int64_t kDrvMs = 1'000'000;
constexpr double kPiD = 3.14159265358979323846;

struct DriverBench {
  explicit DriverBench(SimRmpOptions sim_options = {}, RmpDriverOptions driver_options = {},
                       sim::VirtualCanBusOptions bus_options = {})
      : bus(&clock, bus_options), rmp(&bus, sim_options), pc(bus.AddEndpoint("pc")) {
    auto d = RmpDriver::Create(pc, &clock, driver_options);
    EXPECT_TRUE(d.ok()) << d.status().ToString();
    driver = std::move(d).value();
    driver->SetBusRecovery([this] {
      bus.RestartEndpoint(pc);
      return Status::Ok();
    });
  }
  // Starts the driver and runs until it is running (or `limit`).
  void StartAndWait(int64_t limit_ns = 3000 * kDrvMs) {
    ASSERT_TRUE(driver->Start().ok());
    while (driver->health().state != RmpDriverState::kRunning && clock.NowNs() < limit_ns) {
      ASSERT_TRUE(driver->RunUntil(clock.NowNs() + 10 * kDrvMs).ok());
    }
    ASSERT_EQ(driver->health().state, RmpDriverState::kRunning) << driver->health().last_event;
  }
  // A control loop at 30 Hz (like a camera) until `until_ns`: each step commands `cmd(t)` computed
  // from data `age_ns` old (the age function may make it stale).
  void Control(int64_t until_ns, std::function<RmpMotionCommand(int64_t)> cmd) {
    while (clock.NowNs() < until_ns) {
      const int64_t t = clock.NowNs();
      (void)driver->SetCommand(cmd(t));
      ASSERT_TRUE(driver->RunUntil(std::min(until_ns, t + 33 * kDrvMs)).ok());
    }
  }
  void Fresh(int64_t until_ns, double v, double w, int64_t age_ns = 40 * kDrvMs) {
    Control(until_ns, [=](int64_t t) { return RmpMotionCommand{v, w, t - age_ns}; });
  }
  const RmpSentCommand* LastSent() const { return driver->recent_sent().empty() ? nullptr : &driver->recent_sent().back(); }

  hal::SimClock clock;
  sim::VirtualCanBus bus;
  SimRmp rmp;
  sim::VirtualCanEndpoint* pc;
  std::unique_ptr<RmpDriver> driver;
};

TEST(RmpDriverTest, ConnectsConfiguresResetsOdometryAndRuns) {
  DriverBench b;
  b.StartAndWait();
  const RmpDriverHealth& h = b.driver->health();
  EXPECT_TRUE(h.config_verified);
  EXPECT_EQ(h.odometry_reset, OdometryResetResult::kConfirmed);
  EXPECT_EQ(b.rmp.velocity_scale(), 1.0) << "boot scale 3/4 replaced by the configured 100 %";
  EXPECT_EQ(b.rmp.turn_scale(), 1.0);
  EXPECT_EQ(b.rmp.mode(), OperationalMode::kTractor);
  EXPECT_GE(b.rmp.counters().integrator_resets, 1u);
  EXPECT_GT(h.counters.config_frames, 10u);
  EXPECT_LT(b.clock.NowNs(), 1000 * kDrvMs) << "configuration takes a fraction of a second";
  EXPECT_EQ(h.inhibit, kRmpInhibitNoCommand) << DescribeRmpInhibits(h.inhibit);
  ASSERT_TRUE(b.driver->RunUntil(b.clock.NowNs() + 50 * kDrvMs).ok());
  EXPECT_TRUE(b.driver->odometry().initialized());
  EXPECT_EQ(b.driver->odometry().pose().x_m, 0.0);
  EXPECT_EQ(b.driver->status().mode.mode, OperationalMode::kTractor);
  EXPECT_NEAR(b.driver->status().mode.base_battery_v, 76.0, 0.3);
  EXPECT_EQ(b.driver->status().build.build_id, 0x0203);
  EXPECT_GT(b.driver->status().cu_status_ns, 0);
  EXPECT_TRUE(b.driver->status().cu_status.motors_enabled());
  // The events tell the story.
  std::string events;
  for (const std::string& e : b.driver->recent_events()) events += e + "\n";
  EXPECT_NE(events.find("connecting -> configuring"), std::string::npos) << events;
  EXPECT_NE(events.find("resetting odometry -> running (odometry confirmed)"), std::string::npos) << events;
}

TEST(RmpDriverTest, SendsAFrameEvery20MsAndTheRmpSeesNoTimingViolation) {
  DriverBench b;
  b.StartAndWait();
  const uint64_t sent0 = b.driver->health().counters.frames_sent;
  const int64_t t0 = b.clock.NowNs();
  b.Fresh(t0 + 10'000 * kDrvMs, 0.3, 0.0);
  const uint64_t sent = b.driver->health().counters.frames_sent - sent0;
  EXPECT_NEAR(static_cast<double>(sent), 500.0, 1.0) << "50 Hz for 10 s";
  const auto& recent = b.driver->recent_sent();
  for (std::size_t i = 1; i < recent.size(); ++i) {
    const int64_t dt = recent[i].timestamp_ns - recent[i - 1].timestamp_ns;
    EXPECT_GE(dt, 19 * kDrvMs);
    EXPECT_LE(dt, 21 * kDrvMs);
  }
  EXPECT_EQ(b.rmp.counters().commands_too_close, 0u);
  EXPECT_EQ(b.rmp.counters().command_gaps_too_long, 0u);
  EXPECT_EQ(b.driver->health().counters.late_ticks, 0u);
  EXPECT_EQ(b.driver->health().counters.send_errors, 0u);
}

TEST(RmpDriverTest, DrivesAsCommandedAndOdometryFollows) {
  DriverBench b;
  b.StartAndWait();
  const double x0 = b.rmp.vehicle().truth().x_m;
  b.Fresh(b.clock.NowNs() + 4000 * kDrvMs, 0.5, 0.0);
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.5, 0.005);
  EXPECT_NEAR(b.driver->status().echo_speed_mps, 0.5, 0.005);
  EXPECT_NEAR(b.driver->status().speeds.left_wheel_mps, 0.5, 0.005);
  const double travelled = b.rmp.vehicle().truth().x_m - x0;
  EXPECT_GT(travelled, 1.5);
  EXPECT_NEAR(b.driver->odometry().pose().x_m, travelled, 0.01 + 0.01 * travelled);
  EXPECT_NEAR(b.driver->odometry().pose().yaw_rad, 0.0, 1e-3);
  EXPECT_EQ(b.driver->health().counters.odometry_rejected, 0u);
  EXPECT_EQ(b.driver->health().counters.decode_errors, 0u);
  EXPECT_GT(b.driver->health().counters.complete_cycles, 300u);
}

TEST(RmpDriverTest, NeverSendsMotionFromStaleDataAndStopsTheVehicle) {
  DriverBench b;
  b.StartAndWait();
  const int64_t t0 = b.clock.NowNs();
  b.Fresh(t0 + 2000 * kDrvMs, 0.8, 0.2, 150 * kDrvMs);  // 150 ms old data: still fresh
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.8, 0.01);
  // The camera freezes: the control loop keeps sending, but from the same old frame.
  const int64_t frozen = b.clock.NowNs() - 50 * kDrvMs;
  int refused = 0;
  b.Control(t0 + 5000 * kDrvMs, [&](int64_t t) {
    const RmpMotionCommand c{0.8, 0.2, frozen};
    if (static_cast<double>(t - frozen) * 1e-9 > 0.2) ++refused;
    return c;
  });
  EXPECT_GT(refused, 50);
  EXPECT_GT(b.driver->health().counters.stale_commands_refused, 50u);
  EXPECT_TRUE(b.driver->health().inhibit & kRmpInhibitStaleCommand);
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.0, 1e-3);
  // Every frame that carried motion came from data at most 200 ms old.
  int motion = 0;
  for (const RmpSentCommand& s : b.driver->recent_sent()) {
    if (s.frame.velocity_counts == 0 && s.frame.turn_counts == 0) continue;
    ++motion;
    ASSERT_GE(s.source_timestamp_ns, 0);
    EXPECT_LE(s.timestamp_ns - s.source_timestamp_ns, 200 * kDrvMs);
  }
  EXPECT_GT(motion, 0);
  // The last 2.5 s were all zero.
  for (const RmpSentCommand& s : b.driver->recent_sent()) {
    if (s.timestamp_ns > frozen + 260 * kDrvMs) {
      EXPECT_EQ(s.frame.velocity_counts, 0);
      EXPECT_EQ(s.frame.turn_counts, 0);
    }
  }
  // A command whose data is already stale is refused at once.
  const Status st = b.driver->SetCommand({0.5, 0.0, b.clock.NowNs() - 300 * kDrvMs});
  EXPECT_EQ(st.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(st.message().find("old"), std::string::npos);
  EXPECT_EQ(b.driver->SetCommand({std::nan(""), 0.0, b.clock.NowNs()}).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(b.driver->SetCommand({0.1, 0.0, b.clock.NowNs() + 500 * kDrvMs}).code(), StatusCode::kInvalidArgument);
  // Fresh data again: it drives again.
  b.Fresh(b.clock.NowNs() + 2000 * kDrvMs, 0.4, 0.0);
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.4, 0.01);
}

TEST(RmpDriverTest, HeldCommandGoesStaleWhenTheControlLoopStops) {
  DriverBench b;
  b.StartAndWait();
  b.Fresh(b.clock.NowNs() + 1500 * kDrvMs, 0.6, 0.0);
  const int64_t last_source = b.clock.NowNs() - 40 * kDrvMs;  // roughly; the loop used t - 40 ms
  ASSERT_TRUE(b.driver->RunUntil(b.clock.NowNs() + 1000 * kDrvMs).ok());
  EXPECT_TRUE(b.driver->health().inhibit & kRmpInhibitStaleCommand);
  for (const RmpSentCommand& s : b.driver->recent_sent()) {
    if (s.timestamp_ns > last_source + 240 * kDrvMs) {
      EXPECT_EQ(s.frame.velocity_counts, 0);
    }
  }
}

TEST(RmpDriverTest, CommandsZeroWhenStatusStopsAndResumesWhenItReturns) {
  DriverBench b;
  b.StartAndWait();
  b.Fresh(b.clock.NowNs() + 1500 * kDrvMs, 0.5, 0.0);
  const int64_t silent_at = b.clock.NowNs();
  b.rmp.SetSilent(true);
  b.Fresh(silent_at + 1000 * kDrvMs, 0.5, 0.0);
  const RmpDriverHealth& h = b.driver->health();
  EXPECT_FALSE(h.status_fresh);
  EXPECT_TRUE(h.inhibit & kRmpInhibitStatusStale);
  EXPECT_EQ(h.counters.status_timeouts, 1u);
  // Zero from at most status_timeout (100 ms) + one period after the last status.
  for (const RmpSentCommand& s : b.driver->recent_sent()) {
    if (s.timestamp_ns > silent_at + 125 * kDrvMs) {
      EXPECT_EQ(s.frame.velocity_counts, 0) << "at " << s.timestamp_ns;
      EXPECT_TRUE(s.inhibit & kRmpInhibitStatusStale);
    }
  }
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.0, 0.05);
  b.rmp.SetSilent(false);
  b.Fresh(b.clock.NowNs() + 2000 * kDrvMs, 0.5, 0.0);
  EXPECT_TRUE(b.driver->health().motion_allowed());
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.5, 0.01);
}

// An RMP that reboots mid-run (silent for a second, then back with its boot velocity scale of 3/4, its
// boot mode and integrators at zero) is configured again before it moves: without that, every speed
// would be off by the scale the driver set at start-up and no longer holds.
TEST(RmpDriverTest, AnRmpThatRebootedIsConfiguredAgainBeforeItMoves) {
  DriverBench b;
  b.StartAndWait();
  b.Fresh(b.clock.NowNs() + 1500 * kDrvMs, 0.5, 0.0);
  ASSERT_DOUBLE_EQ(b.rmp.velocity_scale(), 1.0);
  const uint64_t config_frames = b.driver->health().counters.config_frames;
  b.rmp.SetSilent(true);
  b.rmp.Reboot();
  b.Fresh(b.clock.NowNs() + 1000 * kDrvMs, 0.5, 0.0);
  EXPECT_NE(b.driver->health().state, RmpDriverState::kRunning);
  EXPECT_EQ(b.driver->health().counters.reconfigurations, 1u);
  b.rmp.SetSilent(false);
  b.Fresh(b.clock.NowNs() + 2000 * kDrvMs, 0.5, 0.0);
  EXPECT_EQ(b.driver->health().state, RmpDriverState::kRunning) << b.driver->health().last_event;
  EXPECT_GT(b.driver->health().counters.config_frames, config_frames);
  EXPECT_DOUBLE_EQ(b.rmp.velocity_scale(), 1.0);
  EXPECT_EQ(b.rmp.mode(), RmpDriverOptions{}.operational_mode);
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.5, 0.01);  // at 3/4 scale it would be 0.375
  EXPECT_EQ(b.driver->health().counters.reconfigurations, 1u);
}

// The mode and battery frame (0x406) alone missing from the cycle: the battery can no longer be watched,
// so the vehicle stops until it is back.
TEST(RmpDriverTest, MissingModeFramesStopTheVehicle) {
  DriverBench b;
  b.StartAndWait();
  b.Fresh(b.clock.NowNs() + 1000 * kDrvMs, 0.5, 0.0);
  ASSERT_TRUE(b.driver->health().motion_allowed());
  b.rmp.SetModeFrameMissing(true);
  b.Fresh(b.clock.NowNs() + 1000 * kDrvMs, 0.5, 0.0);
  EXPECT_TRUE(b.driver->health().inhibit & kRmpInhibitStatusStale);
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.0, 0.05);
  b.rmp.SetModeFrameMissing(false);
  b.Fresh(b.clock.NowNs() + 2000 * kDrvMs, 0.5, 0.0);
  EXPECT_TRUE(b.driver->health().motion_allowed());
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.5, 0.01);
}

TEST(RmpDriverTest, BusOffInhibitsRecoversThroughTheHookAndResumes) {
  DriverBench b;
  b.StartAndWait();
  b.Fresh(b.clock.NowNs() + 1500 * kDrvMs, 0.5, 0.0);
  const int64_t off_at = b.clock.NowNs();
  b.bus.InjectBusOff(b.pc);  // stays off until the driver asks for a restart
  b.Fresh(off_at + 300 * kDrvMs, 0.5, 0.0);
  EXPECT_TRUE(b.driver->health().bus_off);
  EXPECT_TRUE(b.driver->health().inhibit & kRmpInhibitBusOff);
  EXPECT_GT(b.driver->health().counters.send_errors, 5u);
  // While off, the RMP hears nothing: its firmware holds 0.4 s, then ramps down.
  b.Fresh(off_at + 450 * kDrvMs, 0.5, 0.0);
  EXPECT_EQ(b.driver->health().counters.bus_restart_requests, 0u);
  EXPECT_TRUE(b.rmp.vehicle().command_timed_out()) << "the RMP's own timeout took over while the bus was off";
  b.Fresh(off_at + 2000 * kDrvMs, 0.5, 0.0);
  EXPECT_EQ(b.driver->health().counters.bus_off_events, 1u);
  EXPECT_GE(b.driver->health().counters.bus_restart_requests, 1u);
  EXPECT_FALSE(b.driver->health().bus_off);
  EXPECT_TRUE(b.driver->health().motion_allowed()) << DescribeRmpInhibits(b.driver->health().inhibit);
  b.Fresh(b.clock.NowNs() + 2000 * kDrvMs, 0.5, 0.0);
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.5, 0.01);
  // No frame sent while off carried motion.
  for (const RmpSentCommand& s : b.driver->recent_sent()) {
    if (s.inhibit & kRmpInhibitBusOff) {
      EXPECT_EQ(s.frame.velocity_counts, 0);
    }
  }
}

TEST(RmpDriverTest, LowBatteryAndFaultBitsCommandZero) {
  DriverBench b;
  b.StartAndWait();
  b.Fresh(b.clock.NowNs() + 1500 * kDrvMs, 0.5, 0.0);
  b.rmp.vehicle().SetBatteryDrop(12.0);  // 76 -> ~64 V, below the driver's 66 V
  b.Fresh(b.clock.NowNs() + 3000 * kDrvMs, 0.5, 0.0);
  EXPECT_TRUE(b.driver->health().low_battery);
  EXPECT_TRUE(b.driver->health().inhibit & kRmpInhibitLowBattery);
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.0, 1e-3);
  EXPECT_EQ(b.LastSent()->frame.velocity_counts, 0);
  b.rmp.vehicle().SetBatteryDrop(0.0);
  b.Fresh(b.clock.NowNs() + 1000 * kDrvMs, 0.5, 0.0);
  EXPECT_FALSE(b.driver->health().low_battery);
  EXPECT_NE(b.LastSent()->frame.velocity_counts, 0);

  b.rmp.SetInjectedStatusBits(0, kRmpStatus2EStopOpen << 8);
  b.Fresh(b.clock.NowNs() + 500 * kDrvMs, 0.5, 0.0);
  EXPECT_TRUE(b.driver->health().rmp_fault);
  EXPECT_TRUE(b.driver->health().inhibit & kRmpInhibitRmpFault);
  EXPECT_EQ(b.LastSent()->frame.velocity_counts, 0);
  b.rmp.SetInjectedStatusBits(0, 0);
  b.Fresh(b.clock.NowNs() + 500 * kDrvMs, 0.5, 0.0);
  EXPECT_TRUE(b.driver->health().motion_allowed());
}

TEST(RmpDriverTest, StopRequestLatchesZero) {
  DriverBench b;
  b.StartAndWait();
  b.Fresh(b.clock.NowNs() + 1000 * kDrvMs, 0.5, 0.0);
  b.driver->RequestStop("operator");
  b.Fresh(b.clock.NowNs() + 2000 * kDrvMs, 0.5, 0.0);
  EXPECT_TRUE(b.driver->health().inhibit & kRmpInhibitStopRequested);
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.0, 1e-3);
  b.driver->ClearStop();
  b.Fresh(b.clock.NowNs() + 1000 * kDrvMs, 0.5, 0.0);
  EXPECT_NE(b.LastSent()->frame.velocity_counts, 0);
  b.driver->CommandZero();
  ASSERT_TRUE(b.driver->RunUntil(b.clock.NowNs() + 100 * kDrvMs).ok());
  EXPECT_EQ(b.LastSent()->frame.velocity_counts, 0);
  EXPECT_TRUE(b.driver->health().inhibit & kRmpInhibitNoCommand);
}

TEST(RmpDriverTest, TurnScaleCheckAgreesWithAMatchingFirmware) {
  DriverBench b;
  b.StartAndWait();
  b.Fresh(b.clock.NowNs() + 5000 * kDrvMs, 0.3, 0.5);
  const RmpTurnScaleCheck& c = b.driver->health().turn_check;
  ASSERT_TRUE(c.valid) << c.samples;
  EXPECT_NEAR(c.ratio, 1.0, 0.03);
  EXPECT_FALSE(c.mismatch);
  EXPECT_NEAR(b.rmp.vehicle().truth().yaw_rate_rps, 0.5, 0.01);
}

TEST(RmpDriverTest, TurnScaleCheckFindsAFirmwareWithAnotherScale) {
  SimRmpOptions sim;
  sim.turn_counts_per_radps = 7.8 * 180.0 / kPiD;  // libsegwayrmp's assumption: 446.9 per rad/s
  DriverBench b(sim);
  b.StartAndWait();
  b.Fresh(b.clock.NowNs() + 5000 * kDrvMs, 0.3, 0.5);
  const RmpTurnScaleCheck& c = b.driver->health().turn_check;
  ASSERT_TRUE(c.valid);
  EXPECT_TRUE(c.mismatch);
  EXPECT_FALSE(c.sign_wrong);
  EXPECT_NEAR(c.ratio, (1024.0 / kPiD) / sim.turn_counts_per_radps, 0.03);
  EXPECT_NEAR(c.suggested_turn_counts_per_radps, sim.turn_counts_per_radps, 0.03 * sim.turn_counts_per_radps);
  EXPECT_TRUE(b.driver->health().motion_allowed()) << "a magnitude mismatch is reported, not a stop";
}

TEST(RmpDriverTest, WrongTurnDirectionStopsTheVehicle) {
  SimRmpOptions sim;
  sim.turn_sign = -1;
  DriverBench b(sim);
  b.StartAndWait();
  b.Fresh(b.clock.NowNs() + 5000 * kDrvMs, 0.3, 0.5);
  const RmpTurnScaleCheck& c = b.driver->health().turn_check;
  ASSERT_TRUE(c.valid);
  EXPECT_TRUE(c.sign_wrong);
  EXPECT_TRUE(b.driver->health().inhibit & kRmpInhibitTurnSignMismatch);
  EXPECT_EQ(b.LastSent()->frame.velocity_counts, 0);
}

TEST(RmpDriverTest, IntegratorResetThatDoesNotTakeFallsBackToASoftwareOffset) {
  SimRmpOptions sim;
  sim.integrator_reset_works = false;
  DriverBench b(sim);
  b.StartAndWait();
  EXPECT_EQ(b.driver->health().odometry_reset, OdometryResetResult::kSoftwareOffset);
  const double x0 = b.rmp.vehicle().truth().x_m;
  b.Fresh(b.clock.NowNs() + 3000 * kDrvMs, 0.5, 0.0);
  const double travelled = b.rmp.vehicle().truth().x_m - x0;
  EXPECT_NEAR(b.driver->odometry().pose().x_m, travelled, 0.02);
  // The sim's integrators start near the rollover; the software offset handles it.
  EXPECT_EQ(b.driver->odometry().origin_counts().left >> 16, 0xFFFFu);
}

// Odometry through the whole chain (twin encoders -> integrator frames -> driver) shows the twin's
// configured scale error and slip noise.
TEST(RmpDriverOdometryStatisticsTest, ScaleErrorAndSlipNoiseReachTheDriversOdometry) {
  SimRmpOptions scaled;
  scaled.vehicle.left_wheel_scale_error = 0.02;
  scaled.vehicle.right_wheel_scale_error = 0.02;
  {
    DriverBench b(scaled);
    b.StartAndWait();
    const double x0 = b.rmp.vehicle().truth().x_m;
    b.Fresh(b.clock.NowNs() + 5000 * kDrvMs, 0.8, 0.0);
    b.Fresh(b.clock.NowNs() + 1500 * kDrvMs, 0.0, 0.0);  // stopped: odometry and truth compare at rest
    const double travelled = b.rmp.vehicle().truth().x_m - x0;
    EXPECT_NEAR(b.driver->odometry().pose().x_m / travelled, 1.02, 0.002);
  }
  constexpr int kRuns = 100;
  constexpr double kSigma = 0.01;  // m per sqrt(m), each wheel
  double sum = 0.0, sum2 = 0.0, distance = 0.0;
  for (int run = 0; run < kRuns; ++run) {
    SimRmpOptions noisy;
    noisy.vehicle.slip_noise_m_per_sqrt_m = kSigma;
    noisy.vehicle.seed = 500 + static_cast<uint64_t>(run);
    noisy.vehicle.step_s = 0.002;
    DriverBench b(noisy);
    b.StartAndWait();
    const double d0 = b.rmp.vehicle().truth().distance_m;
    b.Fresh(b.clock.NowNs() + 4000 * kDrvMs, 1.0, 0.0);
    b.Fresh(b.clock.NowNs() + 1500 * kDrvMs, 0.0, 0.0);
    // Path length, not x: the heading drift that slip causes would shorten x by a few mm.
    const double travelled = b.rmp.vehicle().truth().distance_m - d0;
    const double err = b.driver->odometry().pose().distance_m - travelled;
    sum += err;
    sum2 += err * err;
    distance += travelled / kRuns;
  }
  // The centre moves by the mean of the wheels: variance sigma^2 * d / 2.
  const double expected_std = kSigma * std::sqrt(distance / 2.0);
  const double mean = sum / kRuns;
  const double std_dev = std::sqrt((sum2 - kRuns * mean * mean) / (kRuns - 1));
  RecordProperty("odometry_error_std_mm", std::to_string(1000.0 * std_dev));
  RecordProperty("expected_std_mm", std::to_string(1000.0 * expected_std));
  RecordProperty("odometry_error_mean_mm", std::to_string(1000.0 * mean));
  EXPECT_NEAR(std_dev, expected_std, 0.25 * expected_std) << "distance " << distance;
  EXPECT_NEAR(mean, 0.0, 4.0 * expected_std / std::sqrt(kRuns));
}

TEST(RmpDriverTest, ShutdownSendsZeroThenFallsSilent) {
  DriverBench b;
  b.StartAndWait();
  b.Fresh(b.clock.NowNs() + 1500 * kDrvMs, 0.5, 0.0);
  ASSERT_TRUE(b.driver->Shutdown().ok());
  EXPECT_EQ(b.driver->health().state, RmpDriverState::kStopped);
  int zeros = 0;
  for (auto it = b.driver->recent_sent().rbegin(); it != b.driver->recent_sent().rend() && it->frame.velocity_counts == 0; ++it) ++zeros;
  EXPECT_GE(zeros, 10);
  ASSERT_TRUE(b.driver->RunUntil(b.clock.NowNs() + 5 * kDrvMs).ok());  // the last zero is on the wire
  const uint64_t commands = b.rmp.counters().commands;
  ASSERT_TRUE(b.driver->RunUntil(b.clock.NowNs() + 1000 * kDrvMs).ok());
  EXPECT_EQ(b.rmp.counters().commands, commands) << "nothing sent after the shutdown";
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.0, 1e-3);
}

TEST(RmpDriverTest, GarbageAndDroppedFramesAreCountedAndIgnored) {
  sim::VirtualCanBusOptions bus;
  bus.garbage_probability = 0.05;
  bus.drop_probability = 0.02;
  bus.seed = 11;
  DriverBench b({}, {}, bus);
  b.StartAndWait(6000 * kDrvMs);
  const double x0 = b.rmp.vehicle().truth().x_m;
  b.Fresh(b.clock.NowNs() + 5000 * kDrvMs, 0.5, 0.0);
  const RmpDriverCounters& c = b.driver->health().counters;
  EXPECT_GT(c.decode_errors, 20u);
  EXPECT_LT(c.complete_cycles, c.status_cycles);
  EXPECT_TRUE(b.driver->health().status_fresh);
  EXPECT_GT(b.rmp.vehicle().truth().x_m - x0, 1.5) << "the vehicle still drives";
  // Garbage in an integrator frame looks like a jump and is refused, so the odometry stays close.
  EXPECT_NEAR(b.driver->odometry().pose().x_m, b.rmp.vehicle().truth().x_m - x0, 0.15);
}

TEST(RmpDriverTest, SteppedPollingAlsoKeeps50Hz) {
  DriverBench b;
  ASSERT_TRUE(b.driver->Start().ok());
  for (int64_t t = 0; t < 3000 * kDrvMs; t += kDrvMs) {
    b.bus.AdvanceTo(t);
    if (b.driver->health().state == RmpDriverState::kRunning && t % (33 * kDrvMs) == 0) {
      ASSERT_TRUE(b.driver->SetCommand({0.3, 0.0, t - 30 * kDrvMs}).ok());
    }
    ASSERT_TRUE(b.driver->Poll().ok());
  }
  EXPECT_EQ(b.driver->health().state, RmpDriverState::kRunning);
  EXPECT_NEAR(static_cast<double>(b.driver->health().counters.frames_sent), 150.0, 1.0);
  EXPECT_EQ(b.rmp.counters().commands_too_close, 0u);
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.3, 0.01);
}

TEST(RmpDriverTest, OptionsAndPreconditions) {
  RmpDriverOptions o;
  EXPECT_TRUE(o.Check().ok());
  o.command_rate_hz = 200;
  EXPECT_NE(o.Check().message().find("10..300 ms"), std::string::npos);
  o.command_rate_hz = 2;
  EXPECT_FALSE(o.Check().ok());
  o = {};
  o.operational_mode = OperationalMode::kPowerDown;
  EXPECT_FALSE(o.Check().ok());
  o = {};
  o.velocity_scale = 0.0;
  EXPECT_NE(o.Check().message().find("velocity_scale"), std::string::npos);
  o = {};
  o.max_input_age_s = std::nan("");
  EXPECT_FALSE(o.Check().ok());
  o = {};
  o.status_timeout_s = 2.0;  // two seconds without status would still let it drive
  EXPECT_NE(o.Check().message().find("status_timeout_s"), std::string::npos);
  o = {};
  o.max_input_age_s = 3.0;
  EXPECT_NE(o.Check().message().find("max_input_age_s"), std::string::npos);
  hal::SimClock clock;
  sim::VirtualCanBus bus(&clock);
  EXPECT_FALSE(RmpDriver::Create(nullptr, &clock, {}).ok());
  auto d = RmpDriver::Create(bus.AddEndpoint("pc"), &clock, {});
  ASSERT_TRUE(d.ok());
  EXPECT_EQ((*d)->Poll().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ((*d)->RunUntil(100).code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE((*d)->Start().ok());
  EXPECT_EQ((*d)->Start().code(), StatusCode::kFailedPrecondition);
  // Nobody answers: it keeps sending zero and stays connecting.
  ASSERT_TRUE((*d)->RunUntil(1000 * kDrvMs).ok());
  EXPECT_EQ((*d)->health().state, RmpDriverState::kConnecting);
  EXPECT_TRUE((*d)->health().inhibit & kRmpInhibitStatusStale);
  EXPECT_EQ((*d)->health().counters.motion_frames, 0u);
}

// A line as `candump -l` writes it: "(" 10 digits "." 6 digits ") " IFACE " " 3 hex "#" data bytes.
bool IsRmpCandumpLine(const std::string& line, const std::string& iface, int min_bytes, int max_bytes) {
  auto hex = [](char c) { return (c >= '0' && c <= '9') || (c >= 'A' && c <= 'F'); };
  auto digit = [](char c) { return c >= '0' && c <= '9'; };
  if (line.size() < 19 || line[0] != '(' || line[11] != '.' || line[18] != ')') return false;
  for (int i = 1; i <= 17; ++i) {
    if (i != 11 && !digit(line[static_cast<std::size_t>(i)])) return false;
  }
  const std::string rest = line.substr(19);
  const std::string head = " " + iface + " ";
  if (rest.compare(0, head.size(), head) != 0) return false;
  const std::string frame = rest.substr(head.size());
  if (frame.size() < 4 || frame[3] != '#' || !hex(frame[0]) || !hex(frame[1]) || !hex(frame[2])) return false;
  const std::string data = frame.substr(4);
  if (data.size() % 2 != 0) return false;
  const int bytes = static_cast<int>(data.size() / 2);
  if (bytes < min_bytes || bytes > max_bytes) return false;
  for (char c : data) {
    if (!hex(c)) return false;
  }
  return true;
}

std::string DriverTempPath(const std::string& name) {
  return (std::filesystem::path(::testing::TempDir()) / ("rmp_" + name + "_" + std::to_string(::getpid()) + ".log")).string();
}

// A scripted control input, the same for the recorded run and the replay.
RmpMotionCommand ScriptedCommand(int64_t t) {
  const double s = static_cast<double>(t) * 1e-9;
  return {0.4 + 0.2 * std::sin(s), 0.3 * std::cos(0.7 * s), t - 35 * kDrvMs};
}

TEST(RmpDriverLogTest, EveryFrameIsLoggedInCandumpFormatAndAReplayReproducesTheCommands) {
  const std::string path = DriverTempPath("log");
  int64_t end_ns = 0;
  std::vector<hal::CanFrame> recorded_tx;
  {
    DriverBench b;
    auto log = replay::CandumpWriter::Open(path);
    ASSERT_TRUE(log.ok());
    b.driver->SetFrameLog(log->get());
    b.StartAndWait();
    b.Control(4000 * kDrvMs, ScriptedCommand);
    ASSERT_TRUE(b.driver->Shutdown().ok());
    end_ns = b.clock.NowNs();
    const RmpDriverCounters& c = b.driver->health().counters;
    EXPECT_EQ((*log)->lines_written(), c.frames_sent + c.frames_received + c.error_frames);
    ASSERT_TRUE((*log)->Close().ok());
  }
  Result<std::string> text = ReadFile(path);
  ASSERT_TRUE(text.ok());
  std::size_t pos = 0, lines = 0;
  while (pos < text->size()) {
    const std::size_t end = text->find('\n', pos);
    ASSERT_NE(end, std::string::npos);
    ASSERT_TRUE(IsRmpCandumpLine(text->substr(pos, end - pos), "can0", 8, 8)) << text->substr(pos, end - pos);
    pos = end + 1;
    ++lines;
  }
  Result<std::vector<replay::CandumpRecord>> records = replay::ReadCandumpFile(path);
  ASSERT_TRUE(records.ok()) << records.status().ToString();
  EXPECT_EQ(records->size(), lines);
  std::size_t commands = 0;
  for (const auto& r : *records) {
    if (r.frame.id != kRmpIdCommand) continue;
    ++commands;
    recorded_tx.push_back(r.frame);
    ASSERT_TRUE(DecodeCommandFrame(r.frame).ok());
  }
  EXPECT_GT(commands, 190u);

  // Replay: the RMP's frames come from the log; the driver, given the same inputs, must send the
  // same commands at the same times.
  hal::SimClock clock;
  replay::CanLogReplayOptions ro;
  ro.own_ids = {kRmpIdCommand, kRmpIdShutdown};
  replay::CanLogReplayBus bus(*records, &clock, ro);
  auto d = RmpDriver::Create(&bus, &clock, {});
  ASSERT_TRUE(d.ok());
  RmpDriver& driver = **d;
  ASSERT_TRUE(driver.Start().ok());
  while (driver.health().state != RmpDriverState::kRunning && clock.NowNs() < 3000 * kDrvMs) {
    ASSERT_TRUE(driver.RunUntil(clock.NowNs() + 10 * kDrvMs).ok());
  }
  while (clock.NowNs() < 4000 * kDrvMs) {
    const int64_t t = clock.NowNs();
    (void)driver.SetCommand(ScriptedCommand(t));
    ASSERT_TRUE(driver.RunUntil(std::min<int64_t>(4000 * kDrvMs, t + 33 * kDrvMs)).ok());
  }
  ASSERT_TRUE(driver.Shutdown().ok());
  EXPECT_LE(clock.NowNs(), end_ns + kDrvMs);
  ASSERT_EQ(bus.sent().size(), recorded_tx.size());
  for (std::size_t i = 0; i < recorded_tx.size(); ++i) {
    ASSERT_EQ(bus.sent()[i].data, recorded_tx[i].data) << "command " << i;
    ASSERT_EQ(bus.sent()[i].timestamp_ns / 1000, recorded_tx[i].timestamp_ns / 1000) << "command " << i;
  }
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace idi::rmp
