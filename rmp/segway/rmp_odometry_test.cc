#include "rmp/segway/rmp_odometry.h"

#include <gtest/gtest.h>

#include <cmath>

namespace idi::rmp {
namespace {

constexpr int64_t kOdoMs = 1'000'000;
constexpr double kCountsPerM = 33215.0;  // RMP 200

uint32_t Plus(uint32_t base, double meters) {
  return base + static_cast<uint32_t>(static_cast<int64_t>(std::llround(meters * kCountsPerM)));
}

TEST(RmpOdometryTest, FirstSampleIsTheOriginWhateverTheCounts) {
  const RmpCodec codec;
  RmpOdometry odo(codec);
  EXPECT_FALSE(odo.initialized());
  ASSERT_TRUE(odo.Update(0, {0x9ABCDEF0u, 0x12345678u, 0xFFFFFFFFu, 77}).ok());
  EXPECT_TRUE(odo.initialized());
  EXPECT_EQ(odo.pose().x_m, 0.0);
  EXPECT_EQ(odo.pose().yaw_rad, 0.0);
  EXPECT_EQ(odo.origin_counts().left, 0x9ABCDEF0u);
}

TEST(RmpOdometryTest, StraightForwardAcrossTheRolloverAndBackwards) {
  const RmpCodec codec;
  RmpOdometry odo(codec);
  uint32_t l = 0xFFFFC000u, r = 0xFFFFF000u;  // both roll over within the first metre
  ASSERT_TRUE(odo.Update(0, {l, r, 0, 0}).ok());
  for (int i = 1; i <= 100; ++i) {  // 100 x 332 counts (~1 cm) at 100 Hz
    l += 332;
    r += 332;
    ASSERT_TRUE(odo.Update(i * 10 * kOdoMs, {l, r, 0, 0}).ok());
  }
  EXPECT_LT(l, 0x10000u) << "the left counter rolled over";
  EXPECT_LT(r, 0x10000u) << "the right counter rolled over";
  EXPECT_NEAR(odo.pose().x_m, 33200 / kCountsPerM, 1e-12);
  EXPECT_NEAR(odo.pose().y_m, 0.0, 1e-12);
  EXPECT_NEAR(odo.pose().yaw_rad, 0.0, 1e-12);
  EXPECT_NEAR(odo.pose().speed_mps, 332 / kCountsPerM / 0.01, 1e-9);
  for (int i = 101; i <= 200; ++i) {  // all the way back, across the rollover again, and 50 steps more
    l -= 498;
    r -= 498;
    ASSERT_TRUE(odo.Update(i * 10 * kOdoMs, {l, r, 0, 0}).ok());
  }
  EXPECT_GT(l, 0xFFFF0000u) << "rolled back under zero";
  EXPECT_NEAR(odo.pose().x_m, (33200 - 49800) / kCountsPerM, 1e-9);
  EXPECT_NEAR(odo.pose().distance_m, (33200 + 49800) / kCountsPerM, 1e-9);
  EXPECT_LT(odo.pose().speed_mps, 0.0);
}

TEST(RmpOdometryTest, TurningInPlaceAndArcsFollowTheDifferentialDriveModel) {
  const RmpCodec codec;
  RmpOdometry spin(codec);
  ASSERT_TRUE(spin.Update(0, {100, 100, 0, 0}).ok());
  // Right wheel forward, left back by 0.27*pi/2 m each: a quarter turn left on the spot (b = 0.54 m).
  const double d = 0.27 * 3.14159265358979323846 / 2;
  ASSERT_TRUE(spin.Update(kOdoMs * 100, {Plus(100, -d), Plus(100, d), 0, 0}).ok());
  EXPECT_NEAR(spin.pose().yaw_rad, 3.14159265358979323846 / 2, 1e-4);
  EXPECT_NEAR(spin.pose().x_m, 0.0, 1e-12);
  EXPECT_NEAR(spin.pose().y_m, 0.0, 1e-12);

  // An arc of radius 1 m to the left: wheel distances in ratio (1 - 0.27) : (1 + 0.27).
  RmpOdometry arc(codec);
  uint32_t l = 0, r = 0;
  ASSERT_TRUE(arc.Update(0, {l, r, 0, 0}).ok());
  const double step = 0.01;  // metres of centre path per sample
  double lm = 0, rm = 0;
  for (int i = 1; i <= 157; ++i) {  // ~quarter circle
    lm += step * 0.73;
    rm += step * 1.27;
    ASSERT_TRUE(arc.Update(i * 10 * kOdoMs, {Plus(0, lm), Plus(0, rm), 0, 0}).ok());
  }
  const double theta = arc.pose().yaw_rad;
  EXPECT_NEAR(theta, 1.57, 2e-3);
  EXPECT_NEAR(arc.pose().x_m, std::sin(theta), 2e-4);
  EXPECT_NEAR(arc.pose().y_m, 1.0 - std::cos(theta), 2e-4);
}

TEST(RmpOdometryTest, YawFromTheIntegratorWithItsSign) {
  const RmpCodec codec;  // yaw integrator counts clockwise
  RmpOdometryOptions o;
  o.yaw_source = OdometryYawSource::kYawIntegrator;
  RmpOdometry odo(codec, o);
  ASSERT_TRUE(odo.Update(0, {0, 0, 0, 5}).ok());
  // A quarter revolution clockwise in RMP counts = -pi/2 counter-clockwise.
  ASSERT_TRUE(odo.Update(100 * kOdoMs, {0, 0, 0, 5u + 112644u / 4u}).ok());
  EXPECT_NEAR(odo.pose().yaw_rad, -3.14159265358979323846 / 2, 1e-4);
}

TEST(RmpOdometryTest, ImpossibleJumpsAreRefusedAndTheNextSampleIsTheReference) {
  const RmpCodec codec;
  RmpOdometry odo(codec);
  // 150 m on the counters, then a reset taking effect mid-run: both counters drop to zero.
  ASSERT_TRUE(odo.Update(0, {5'000'000, 5'000'000, 0, 0}).ok());
  ASSERT_TRUE(odo.Update(10 * kOdoMs, {Plus(5'000'000, 0.01), Plus(5'000'000, 0.01), 0, 0}).ok());
  const Status st = odo.Update(20 * kOdoMs, {0, 0, 0, 0});
  EXPECT_EQ(st.code(), StatusCode::kOutOfRange);
  EXPECT_EQ(odo.rejected_jumps(), 1u);
  EXPECT_NEAR(odo.pose().x_m, 0.01, 1e-4);
  ASSERT_TRUE(odo.Update(30 * kOdoMs, {Plus(0, 0.01), Plus(0, 0.01), 0, 0}).ok());
  EXPECT_NEAR(odo.pose().x_m, 0.02, 1e-4);
  EXPECT_EQ(odo.Update(5 * kOdoMs, {0, 0, 0, 0}).code(), StatusCode::kInvalidArgument) << "time went backwards";
  // After a long silence a long (but possible) distance is accepted.
  ASSERT_TRUE(odo.Update(2030 * kOdoMs, {Plus(0, 3.01), Plus(0, 3.01), 0, 0}).ok());
  EXPECT_NEAR(odo.pose().x_m, 3.02, 1e-4);
}

TEST(RmpOdometryTest, ResetAndCalibrationScales) {
  const RmpCodec codec;
  RmpOdometryOptions o;
  o.linear_scale = 0.5;  // e.g. the RMP 50 that reported twice the distance
  RmpOdometry odo(codec, o);
  ASSERT_TRUE(odo.Update(0, {0, 0, 0, 0}).ok());
  ASSERT_TRUE(odo.Update(100 * kOdoMs, {Plus(0, 0.2), Plus(0, 0.2), 0, 0}).ok());
  EXPECT_NEAR(odo.pose().x_m, 0.1, 1e-4);
  odo.Reset();
  EXPECT_FALSE(odo.initialized());
  ASSERT_TRUE(odo.Update(200 * kOdoMs, {Plus(0, 5.0), Plus(0, 5.0), 0, 0}).ok());
  EXPECT_EQ(odo.pose().x_m, 0.0);

  RmpOdometryOptions bad;
  bad.wheel_separation_m = 0.0;
  EXPECT_EQ(bad.Check().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace idi::rmp
