#include "shared/sim/vehicle/vehicle_twin.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <vector>

namespace idi::sim {
namespace {

constexpr int64_t kMs = 1'000'000;

// Sends `cmd` every 20 ms (a 50 Hz driver) from `from_ns` to `to_ns`, advancing the twin; calls
// `each` after every step.
template <typename F>
void DriveTwin(VehicleTwin* twin, VehicleCommand cmd, int64_t from_ns, int64_t to_ns, F each, int64_t every_ns = kMs) {
  for (int64_t t = from_ns; t < to_ns; t += 20 * kMs) {
    twin->Command(t, cmd);
    for (int64_t s = t + every_ns; s <= std::min(t + 20 * kMs, to_ns); s += every_ns) {
      twin->AdvanceTo(s);
      each(*twin);
    }
  }
}
void DriveTwin(VehicleTwin* twin, VehicleCommand cmd, int64_t from_ns, int64_t to_ns) {
  DriveTwin(twin, cmd, from_ns, to_ns, [](const VehicleTwin&) {}, 20 * kMs);
}

TEST(VehicleTwinOptionsTest, RejectsBadValuesNamingTheField) {
  VehicleTwinOptions o;
  EXPECT_TRUE(o.Check().ok());
  o.wheel_separation_m = 0.0;
  EXPECT_NE(o.Check().message().find("wheel_separation_m"), std::string::npos);
  o = {};
  o.slip_noise_m_per_sqrt_m = -0.01;
  EXPECT_NE(o.Check().message().find("slip_noise_m_per_sqrt_m"), std::string::npos);
  o = {};
  o.max_speed_mps = std::nan("");
  EXPECT_NE(o.Check().message().find("max_speed_mps"), std::string::npos);
  o = {};
  o.left_wheel_scale_error = 0.7;
  EXPECT_EQ(o.Check().code(), StatusCode::kInvalidArgument);
  o = {};
  o.step_s = 0.1;
  EXPECT_EQ(o.Check().code(), StatusCode::kInvalidArgument);
}

TEST(VehicleTwinTest, CommandActsAfterTheLatencyWithinTheAccelerationLimit) {
  VehicleTwinOptions o;
  o.command_latency_s = 0.05;
  o.max_accel_mps2 = 1.0;
  VehicleTwin twin(o);
  double max_accel = 0.0;
  bool moved_early = false;
  DriveTwin(&twin, {1.0, 0.0}, 0, 3000 * kMs, [&](const VehicleTwin& t) {
    if (t.now_ns() <= 50 * kMs && t.truth().speed_mps != 0.0) moved_early = true;
    max_accel = std::max(max_accel, std::abs(t.truth().accel_mps2));
  });
  EXPECT_FALSE(moved_early) << "the platform moved before the command latency had passed";
  EXPECT_LE(max_accel, 1.0 + 1e-9);
  EXPECT_GT(max_accel, 0.9) << "the acceleration limit should be reached on a 0 -> 1 m/s step";
  EXPECT_NEAR(twin.truth().speed_mps, 1.0, 1e-3);
  EXPECT_NEAR(twin.truth().y_m, 0.0, 1e-12);
  EXPECT_NEAR(twin.truth().x_m, twin.truth().distance_m, 1e-9);
  // Reaching 1 m/s takes at least 1 s at 1 m/s^2 after a 50 ms latency, so x < 3 - 0.05 - 0.5.
  EXPECT_LT(twin.truth().x_m, 2.45 + 1e-6);
  EXPECT_GT(twin.truth().x_m, 2.0);
}

TEST(VehicleTwinTest, SpeedTurnAndLateralAccelerationLimits) {
  VehicleTwinOptions o;
  VehicleTwin twin(o);
  DriveTwin(&twin, {10.0, 0.0}, 0, 5000 * kMs);
  EXPECT_NEAR(twin.truth().speed_mps, o.max_speed_mps, 1e-6);
  twin.SetSpeedScale(0.5);
  DriveTwin(&twin, {10.0, 0.0}, 5000 * kMs, 9000 * kMs);
  EXPECT_NEAR(twin.truth().speed_mps, 0.5 * o.max_speed_mps, 1e-6);

  VehicleTwin spin(o);
  DriveTwin(&spin, {0.0, 10.0}, 0, 3000 * kMs);
  EXPECT_NEAR(spin.truth().yaw_rate_rps, o.max_yaw_rate_rps, 1e-6);
  spin.SetTurnScale(0.25);
  DriveTwin(&spin, {0.0, -10.0}, 3000 * kMs, 6000 * kMs);
  EXPECT_NEAR(spin.truth().yaw_rate_rps, -0.25 * o.max_yaw_rate_rps, 1e-6);

  VehicleTwin fast_turn(o);
  double max_lateral = 0.0;
  DriveTwin(&fast_turn, {2.0, 3.0}, 0, 5000 * kMs, [&](const VehicleTwin& t) {
    max_lateral = std::max(max_lateral, std::abs(t.truth().speed_mps * t.truth().yaw_rate_rps));
  });
  EXPECT_LE(max_lateral, o.max_lateral_accel_mps2 * 1.01);
  EXPECT_NEAR(fast_turn.truth().yaw_rate_rps, o.max_lateral_accel_mps2 / 2.0, 0.01);
}

TEST(VehicleTwinTest, ConstantSpeedAndYawRateDriveACircleOfRadiusVOverOmega) {
  VehicleTwinOptions o;
  VehicleTwin twin(o);
  DriveTwin(&twin, {0.5, 0.5}, 0, 2000 * kMs);  // settle
  std::vector<std::array<double, 2>> pts;
  DriveTwin(&twin, {0.5, 0.5}, 2000 * kMs, 16000 * kMs,
            [&](const VehicleTwin& t) { pts.push_back({t.truth().x_m, t.truth().y_m}); });
  // Centre = point + radius to the left of the heading.
  const VehicleTruth& tr = twin.truth();
  const double cx = tr.x_m - std::sin(tr.yaw_rad) * 1.0, cy = tr.y_m + std::cos(tr.yaw_rad) * 1.0;
  for (const auto& p : pts) EXPECT_NEAR(std::hypot(p[0] - cx, p[1] - cy), 1.0, 1e-4);
  // Wheels: the right (outer) wheel rolls (R + b/2) / R times the centre's distance.
  EXPECT_NEAR(tr.right_wheel_mps, 0.5 * (1.0 + 0.27), 1e-6);
  EXPECT_NEAR(tr.left_wheel_mps, 0.5 * (1.0 - 0.27), 1e-6);
}

TEST(VehicleTwinTest, FirmwareKeepsTheLastCommandForTheTimeoutThenRampsToZero) {
  VehicleTwinOptions o;
  o.command_timeout_s = 0.4;
  o.timeout_decel_mps2 = 1.0;
  VehicleTwin twin(o);
  DriveTwin(&twin, {1.0, 0.3}, 0, 3000 * kMs);  // last command at t = 2.98 s
  const int64_t last = 2980 * kMs;
  twin.AdvanceTo(last + 390 * kMs);
  EXPECT_NEAR(twin.truth().speed_mps, 1.0, 1e-3) << "inside the timeout the last command still holds";
  EXPECT_FALSE(twin.command_timed_out());
  twin.AdvanceTo(last + 410 * kMs);
  EXPECT_TRUE(twin.command_timed_out());
  twin.AdvanceTo(last + 900 * kMs);
  const double v1 = twin.truth().speed_mps;
  twin.AdvanceTo(last + 1100 * kMs);
  const double v2 = twin.truth().speed_mps;
  EXPECT_NEAR((v1 - v2) / 0.2, 1.0, 0.05) << "ramp at the timeout deceleration";
  twin.AdvanceTo(last + 2500 * kMs);
  EXPECT_NEAR(twin.truth().speed_mps, 0.0, 1e-6);
  EXPECT_NEAR(twin.truth().yaw_rate_rps, 0.0, 1e-6);
  // A new command resumes motion.
  DriveTwin(&twin, {0.5, 0.0}, last + 2500 * kMs, last + 5000 * kMs);
  EXPECT_NEAR(twin.truth().speed_mps, 0.5, 1e-3);
}

TEST(VehicleTwinTest, MotorsDisabledBrakeToAStopAndIgnoreCommands) {
  VehicleTwin twin(VehicleTwinOptions{});
  DriveTwin(&twin, {1.0, 0.0}, 0, 2000 * kMs);
  twin.SetMotorsEnabled(false);
  DriveTwin(&twin, {1.0, 0.0}, 2000 * kMs, 5000 * kMs);
  EXPECT_NEAR(twin.truth().speed_mps, 0.0, 1e-9);
}

// After a timeout (or with the motors off) the last command is gone: a new command resumes from rest,
// and until it takes effect (the latency) the vehicle does not move off towards the old one. Before, it
// reversed towards the old -1 m/s for the latency's 50 ms (and drove off at 1 m/s after a re-enable).
TEST(VehicleTwinTest, ACommandAfterATimeoutDoesNotBringBackTheOldOne) {
  VehicleTwin twin(VehicleTwinOptions{});
  DriveTwin(&twin, {-1.0, 0.0}, 0, 3000 * kMs);
  twin.AdvanceTo(6000 * kMs);  // timed out, ramped to rest
  ASSERT_TRUE(twin.command_timed_out());
  ASSERT_NEAR(twin.truth().speed_mps, 0.0, 1e-9);
  twin.Command(6000 * kMs, {0.0, 0.0});
  for (int64_t t = 6000; t <= 6200; t += 5) {
    twin.AdvanceTo(t * kMs);
    EXPECT_NEAR(twin.truth().speed_mps, 0.0, 1e-9) << "t = " << t << " ms";
  }

  // Commands keep coming while the motors are off (no timeout): the firmware ignores them, and none of
  // them acts once the motors are on again.
  VehicleTwin off(VehicleTwinOptions{});
  DriveTwin(&off, {1.0, 0.0}, 0, 2000 * kMs);
  off.SetMotorsEnabled(false);
  DriveTwin(&off, {1.0, 0.0}, 2000 * kMs, 4000 * kMs);
  ASSERT_FALSE(off.command_timed_out());
  ASSERT_NEAR(off.truth().speed_mps, 0.0, 1e-4);
  off.SetMotorsEnabled(true);
  DriveTwin(&off, {0.0, 0.0}, 4000 * kMs, 4200 * kMs);
  EXPECT_NEAR(off.truth().speed_mps, 0.0, 1e-4) << "re-enabled, it drove off on a command from before";
}

// A command or a scale that is not a number is no command and no motion (std::clamp passes NaN
// through: it made the whole state NaN, and a NaN scale lifted the speed limit).
TEST(VehicleTwinTest, NotANumberNeitherMovesTheVehicleNorLiftsTheLimits) {
  VehicleTwin twin(VehicleTwinOptions{});
  DriveTwin(&twin, {std::nan(""), std::nan("")}, 0, 1000 * kMs);
  EXPECT_EQ(twin.truth().speed_mps, 0.0);
  EXPECT_TRUE(std::isfinite(twin.truth().x_m) && std::isfinite(twin.truth().yaw_rad));
  twin.SetSpeedScale(std::nan(""));
  twin.SetAccelScale(std::nan(""));
  twin.SetTurnScale(std::nan(""));
  EXPECT_EQ(twin.speed_scale(), 0.0);
  DriveTwin(&twin, {5.0, 2.0}, 1000 * kMs, 2000 * kMs);
  EXPECT_EQ(twin.truth().speed_mps, 0.0);
  EXPECT_EQ(twin.truth().yaw_rate_rps, 0.0);
}

// Odometry statistics: the measured wheel distances show the configured scale error and a slip
// noise whose standard deviation grows as sqrt(distance).
TEST(VehicleTwinStatisticsTest, OdometryErrorMatchesScaleErrorAndSlipNoise) {
  constexpr int kRuns = 300;
  constexpr double kSigma = 0.01;  // m per sqrt(m)
  constexpr double kScale = 0.02;
  std::vector<double> left_err;
  double distance_sum = 0.0;
  for (int run = 0; run < kRuns; ++run) {
    VehicleTwinOptions o;
    o.seed = 1000 + static_cast<uint64_t>(run);
    o.step_s = 0.005;
    o.left_wheel_scale_error = kScale;
    o.right_wheel_scale_error = kScale;
    o.slip_noise_m_per_sqrt_m = kSigma;
    VehicleTwin twin(o);
    DriveTwin(&twin, {2.0, 0.0}, 0, 2500 * kMs);
    const VehicleTruth& t = twin.truth();
    distance_sum += t.left_wheel_m;
    left_err.push_back(twin.sensors().left_wheel_m - t.left_wheel_m * (1.0 + kScale));
  }
  const double mean_distance = distance_sum / kRuns;
  ASSERT_GT(mean_distance, 3.0);
  double mean = 0.0, var = 0.0;
  for (double e : left_err) mean += e / kRuns;
  for (double e : left_err) var += (e - mean) * (e - mean) / (kRuns - 1);
  const double expected_std = kSigma * std::sqrt(mean_distance);
  RecordProperty("slip_error_std_mm", std::to_string(1000.0 * std::sqrt(var)));
  RecordProperty("expected_std_mm", std::to_string(1000.0 * expected_std));
  EXPECT_NEAR(std::sqrt(var), expected_std, 0.15 * expected_std);
  EXPECT_NEAR(mean, 0.0, 4.0 * expected_std / std::sqrt(kRuns));
}

TEST(VehicleTwinStatisticsTest, ScaleErrorIsExactWithoutSlipAndUnequalWheelsBendTheOdometry) {
  VehicleTwinOptions o;
  o.left_wheel_scale_error = 0.0;
  o.right_wheel_scale_error = 0.01;
  VehicleTwin twin(o);
  DriveTwin(&twin, {1.0, 0.0}, 0, 10000 * kMs);
  const VehicleTruth& t = twin.truth();
  const VehicleSensors& s = twin.sensors();
  EXPECT_NEAR(s.left_wheel_m, t.left_wheel_m, 1e-9);
  EXPECT_NEAR(s.right_wheel_m, 1.01 * t.right_wheel_m, 1e-9);
  EXPECT_NEAR(s.fore_aft_m, 1.005 * t.distance_m, 1e-9);
  // Heading from the wheels drifts by (dr - dl) / b although the truth drives straight.
  EXPECT_NEAR((s.right_wheel_m - s.left_wheel_m) / o.wheel_separation_m, 0.01 * t.distance_m / 0.54, 1e-9);
  EXPECT_NEAR(t.yaw_rad, 0.0, 1e-12);
}

TEST(VehicleTwinTest, SameSeedSameRunOtherSeedOtherNoise) {
  VehicleTwinOptions o;
  o.slip_noise_m_per_sqrt_m = 0.01;
  o.gyro_noise_rps = 0.01;
  VehicleTwin a(o), b(o);
  o.seed = 2;
  VehicleTwin c(o);
  for (VehicleTwin* t : {&a, &b, &c}) DriveTwin(t, {1.0, 0.2}, 0, 2000 * kMs);
  EXPECT_EQ(a.sensors().left_wheel_m, b.sensors().left_wheel_m);
  EXPECT_EQ(a.sensors().yaw_rad, b.sensors().yaw_rad);
  EXPECT_NE(a.sensors().left_wheel_m, c.sensors().left_wheel_m);
  EXPECT_EQ(a.truth().x_m, c.truth().x_m) << "noise must not change the truth";
}

TEST(VehicleTwinTest, BatteryDrainsAndDropsOnInjection) {
  VehicleTwinOptions o;
  o.base_battery_drain_v_per_h = 36.0;  // 1 V per 100 s, to see it quickly
  VehicleTwin twin(o);
  twin.AdvanceTo(100'000 * kMs);
  EXPECT_NEAR(twin.sensors().base_battery_v, o.base_battery_start_v - 1.0, 1e-6);
  twin.SetBatteryDrop(10.0);
  twin.AdvanceTo(100'001 * kMs);
  EXPECT_NEAR(twin.sensors().base_battery_v, o.base_battery_start_v - 11.0, 1e-3);
  EXPECT_LT(twin.sensors().ui_battery_v, o.ui_battery_start_v);
}

TEST(VehicleTwinTest, IntegratorResetAndPitchByMode) {
  VehicleTwin twin(VehicleTwinOptions{});
  double max_pitch = 0.0;
  DriveTwin(&twin, {1.0, 0.5}, 0, 1500 * kMs, [&](const VehicleTwin& t) { max_pitch = std::max(max_pitch, t.sensors().pitch_rad); });
  EXPECT_GT(max_pitch, 0.05) << "balance mode leans forward while accelerating";
  // The pitch rate stays that of a platform, however the steps fall: steps of 1 us where the
  // acceleration starts gave 1e5 rad/s before the pitch had its lag.
  VehicleTwin fine(VehicleTwinOptions{});
  fine.SetBalanceMode(true);
  double max_rate = 0.0;
  fine.Command(0, {1.0, 0.0});
  for (int64_t t = 1000; t <= 300 * kMs; t += (t % 2 == 0 ? 1001 : 999)) {
    fine.AdvanceTo(t);
    max_rate = std::max(max_rate, std::abs(fine.sensors().pitch_rate_rps));
  }
  EXPECT_LT(max_rate, 5.0);
  EXPECT_GT(twin.sensors().left_wheel_m, 0.1);
  twin.ResetIntegrators(true, false, true, false);
  EXPECT_EQ(twin.sensors().left_wheel_m, 0.0);
  EXPECT_EQ(twin.sensors().yaw_rad, 0.0);
  EXPECT_GT(twin.sensors().right_wheel_m, 0.1);
  EXPECT_GT(twin.sensors().fore_aft_m, 0.1);

  VehicleTwin tractor(VehicleTwinOptions{});
  tractor.SetBalanceMode(false);
  DriveTwin(&tractor, {1.0, 0.0}, 0, 1500 * kMs, [&](const VehicleTwin& t) { EXPECT_EQ(t.sensors().pitch_rad, 0.0); });
}

}  // namespace
}  // namespace idi::sim
