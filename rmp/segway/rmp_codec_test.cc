// Codec tests on byte vectors written from the protocol facts (device-protocols.md §1.2-1.4):
// big-endian 16-bit slots, word-swapped 32-bit integrators, each model's scale factors.
#include "rmp/segway/rmp_codec.h"

#include <gtest/gtest.h>

#include <cmath>

namespace idi::rmp {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

hal::CanFrame BytesFrame(uint32_t id, std::array<uint8_t, 8> bytes, uint8_t dlc = 8) {
  hal::CanFrame f;
  f.id = id;
  f.dlc = dlc;
  f.data = bytes;
  return f;
}

template <typename T>
T DecodeAs(const RmpCodec& codec, const hal::CanFrame& f) {
  Result<RmpStatusMessage> r = codec.Decode(f);
  EXPECT_TRUE(r.ok()) << r.status().ToString();
  if (!r.ok()) return T{};
  const T* m = std::get_if<T>(&*r);
  EXPECT_NE(m, nullptr) << "decoded to another frame type";
  return m ? *m : T{};
}

TEST(RmpModelTest, NamesAndScaleFactorsPerModel) {
  EXPECT_EQ(*ParseRmpModel("RMP 200"), RmpModel::kRmp200);
  EXPECT_EQ(*ParseRmpModel("rmp50"), RmpModel::kRmp50);
  EXPECT_EQ(ParseRmpModel("rmp440").status().code(), StatusCode::kInvalidArgument);
  const RmpScaleFactors s200 = ScaleFactorsFor(RmpModel::kRmp200);
  EXPECT_EQ(s200.wheel_speed_counts_per_mps, 332.0);
  EXPECT_EQ(s200.distance_counts_per_m, 33215.0);
  EXPECT_EQ(s200.yaw_counts_per_rev, 112644.0);
  EXPECT_EQ(s200.torque_counts_per_nm, 1094.0);
  const RmpScaleFactors s100 = ScaleFactorsFor(RmpModel::kRmp100);
  EXPECT_EQ(s100.wheel_speed_counts_per_mps, 401.0);
  EXPECT_EQ(s100.distance_counts_per_m, 40181.0);
  EXPECT_EQ(s100.yaw_counts_per_rev, 117031.0);
  EXPECT_EQ(s100.torque_counts_per_nm, 1463.0);
  EXPECT_EQ(ScaleFactorsFor(RmpModel::kRmp400).distance_counts_per_m, 33215.0);
  EXPECT_EQ(ScaleFactorsFor(RmpModel::kRmp50).wheel_speed_counts_per_mps, 401.0);
  EXPECT_EQ(s200.tilt_counts_per_deg, 7.8);
  EXPECT_EQ(RmpCodec().options().model, RmpModel::kRmp200) << "the default is an RMP 200";
}

TEST(RmpCommandTest, EncodesBigEndianSlotsWithNegativeCounts) {
  const hal::CanFrame f = EncodeCommandFrame({-1176, 1024, 50, 0x0F});
  EXPECT_EQ(f.id, 0x413u);
  EXPECT_FALSE(f.extended);
  EXPECT_EQ(f.dlc, 8);
  const std::array<uint8_t, 8> expected = {0xFB, 0x68, 0x04, 0x00, 0x00, 0x32, 0x00, 0x0F};
  EXPECT_EQ(f.data, expected);
  const hal::CanFrame g = EncodeCommandFrame({1176, -1024, 0, 0});
  const std::array<uint8_t, 8> expected_g = {0x04, 0x98, 0xFC, 0x00, 0, 0, 0, 0};
  EXPECT_EQ(g.data, expected_g);
  EXPECT_EQ(EncodeShutdownFrame().id, 0x412u);
}

TEST(RmpCommandTest, DecodeRoundTripAndRejectsTruncatedOrBeyondLimits) {
  Result<RmpCommandFrame> c = DecodeCommandFrame(BytesFrame(0x413, {0xFE, 0xB4, 0x00, 0x4E, 0x00, 0x0A, 0x00, 0x10}));
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c->velocity_counts, -332);
  EXPECT_EQ(c->turn_counts, 78);
  EXPECT_EQ(c->config_id, 10);
  EXPECT_EQ(c->config_param, 16);
  EXPECT_FALSE(DecodeCommandFrame(BytesFrame(0x413, {}, 6)).ok());
  EXPECT_FALSE(DecodeCommandFrame(BytesFrame(0x413, {0x04, 0x99, 0, 0, 0, 0, 0, 0})).ok()) << "1177 counts";
  EXPECT_FALSE(DecodeCommandFrame(BytesFrame(0x413, {0, 0, 0x04, 0x01, 0, 0, 0, 0})).ok()) << "1025 counts";
  EXPECT_FALSE(DecodeCommandFrame(BytesFrame(0x412, {})).ok());
}

TEST(RmpCommandTest, MotionToCountsSaturatesAtTheProtocolLimits) {
  RmpCommandScaling s;  // RMP 200: 332 counts per m/s, turn 1024 counts ~ pi rad/s
  RmpMotionCounts c = MotionToCounts(1.0, 0.0, s);
  EXPECT_EQ(c.velocity, 332);
  EXPECT_FALSE(c.velocity_saturated);
  c = MotionToCounts(-1.0, -3.14159265358979, s);
  EXPECT_EQ(c.velocity, -332);
  EXPECT_EQ(c.turn, -1024);
  EXPECT_FALSE(c.turn_saturated);
  c = MotionToCounts(10.0, 4.0, s);
  EXPECT_EQ(c.velocity, 1176);
  EXPECT_EQ(c.turn, 1024);
  EXPECT_TRUE(c.velocity_saturated);
  EXPECT_TRUE(c.turn_saturated);
  c = MotionToCounts(-10.0, -4.0, s);
  EXPECT_EQ(c.velocity, -1176);
  EXPECT_EQ(c.turn, -1024);
  // 3.576 m/s is full scale (8 mph) within rounding.
  EXPECT_NEAR(MotionToCounts(3.542, 0, s).velocity, 1176, 1);
  c = MotionToCounts(std::nan(""), 0.1, s);
  EXPECT_TRUE(c.invalid_input);
  EXPECT_EQ(c.velocity, 0);
  EXPECT_EQ(c.turn, 0);

  // libsegwayrmp's turn scale: 7.8 counts per deg/s; 10 deg/s -> 78 counts.
  RmpCommandScaling lib = s;
  lib.turn_counts_per_radps = 7.8 / kDeg;
  EXPECT_EQ(MotionToCounts(0, 10 * kDeg, lib).turn, 78);
  // Compensation for the configured scales: at half velocity scale, 1 m/s needs 664 counts.
  RmpCommandScaling half = s;
  half.velocity_scale_fraction = 0.5;
  EXPECT_EQ(MotionToCounts(1.0, 0, half).velocity, 664);
  EXPECT_NEAR(VelocityCountsToMps(664, half), 1.0, 1e-12);
  RmpCommandScaling inverted = s;
  inverted.turn_sign = -1;
  EXPECT_EQ(MotionToCounts(0, 1.0, inverted).turn, -326);
  EXPECT_NEAR(TurnCountsToRadps(-326, inverted), 1.0, 0.005);
  EXPECT_NEAR(TurnCountsToRadps(1024, s), 3.14159265358979, 1e-9);
}

TEST(RmpConfigTest, ScaleAndModeCommands) {
  EXPECT_EQ(MakeScaleConfig(RmpConfigId::kMaxVelocityScale, 1.0)->param, 16);
  EXPECT_EQ(MakeScaleConfig(RmpConfigId::kMaxVelocityScale, 0.75)->param, 12);
  EXPECT_EQ(MakeScaleConfig(RmpConfigId::kMaxAccelScale, 0.99)->param, 15) << "floor, never above the request";
  EXPECT_EQ(MakeScaleConfig(RmpConfigId::kMaxTurnScale, 0.0)->param, 0);
  EXPECT_EQ(MakeScaleConfig(RmpConfigId::kMaxTurnScale, 1.5).status().code(), StatusCode::kOutOfRange);
  EXPECT_EQ(MakeScaleConfig(RmpConfigId::kMaxTurnScale, std::nan("")).status().code(), StatusCode::kOutOfRange);
  EXPECT_EQ(MakeScaleConfig(RmpConfigId::kGainSchedule, 0.5).status().code(), StatusCode::kInvalidArgument);
  // Current limit 1.0 = 256 = 0x0100, sent as a full big-endian uint16 (ORCA).
  Result<RmpConfigRequest> current = MakeScaleConfig(RmpConfigId::kCurrentLimitScale, 1.0);
  ASSERT_TRUE(current.ok());
  const hal::CanFrame f = EncodeCommandFrame({0, 0, static_cast<uint16_t>(current->id), current->param});
  const std::array<uint8_t, 8> expected = {0, 0, 0, 0, 0x00, 0x0E, 0x01, 0x00};
  EXPECT_EQ(f.data, expected);
  EXPECT_EQ(MakeGainScheduleConfig(GainSchedule::kHeavy).param, 2);
  EXPECT_EQ(MakeGainScheduleConfig(GainSchedule::kHeavy).id, RmpConfigId::kGainSchedule);
  EXPECT_EQ(MakeBalanceLockoutConfig(true).param, 1);
  EXPECT_EQ(static_cast<int>(MakeBalanceLockoutConfig(false).id), 15);
  EXPECT_EQ(MakeOperationalModeConfig(OperationalMode::kBalance).param, 2);
  EXPECT_EQ(MakeOperationalModeConfig(OperationalMode::kTractor).param, 1);
  EXPECT_EQ(static_cast<int>(MakeOperationalModeConfig(OperationalMode::kTractor).id), 16);
  EXPECT_EQ(MakeResetIntegratorsConfig().param, 0x0F);
  EXPECT_EQ(MakeResetIntegratorsConfig(kRmpResetLeftWheel | 0xF0).param, 0x02);
  EXPECT_EQ(static_cast<int>(MakeResetIntegratorsConfig().id), 50);
}

TEST(RmpIntegratorTest, WordSwappedAndShortestSignedDifference) {
  std::array<uint8_t, 8> d = {0x56, 0x78, 0x12, 0x34, 0xFF, 0xFE, 0xFF, 0xFF};
  EXPECT_EQ(GetWordSwappedU32(d, 0), 0x12345678u) << "low word first, each word big-endian";
  EXPECT_EQ(GetWordSwappedU32(d, 2), 0xFFFFFFFEu);
  std::array<uint8_t, 8> e{};
  PutWordSwappedU32(&e, 0, 0x12345678u);
  PutWordSwappedU32(&e, 2, 0xFFFFFFFEu);
  EXPECT_EQ(e, d);
  EXPECT_EQ(IntegratorDelta(5, 0xFFFFFFFBu), 10) << "forward across the rollover";
  EXPECT_EQ(IntegratorDelta(0xFFFFFFFBu, 5), -10) << "backward across the rollover";
  EXPECT_EQ(IntegratorDelta(0x80000010u, 0x7FFFFFF0u), 0x20);
  EXPECT_EQ(IntegratorDelta(1000, 3000), -2000);
  EXPECT_EQ(IntegratorDelta(7, 7), 0);
}

TEST(RmpStatusTest, DecodesEachStatusFrameFromBytes) {
  const RmpCodec codec;  // RMP 200, RMP reports clockwise yaw positive
  EXPECT_EQ(DecodeAs<RmpBuildFrame>(codec, BytesFrame(0x400, {0x12, 0x34, 0xAA, 0xBB, 0, 0, 0, 0})).build_id, 0x1234);

  // 0x401: pitch +78 counts = +10 deg, pitch rate -78 = -10 deg/s, roll -39 = -5 deg, roll rate +39 = +5 deg/s.
  const RmpTiltFrame tilt = DecodeAs<RmpTiltFrame>(codec, BytesFrame(0x401, {0x00, 0x4E, 0xFF, 0xB2, 0xFF, 0xD9, 0x00, 0x27}));
  EXPECT_NEAR(tilt.pitch_rad, 10 * kDeg, 1e-12);
  EXPECT_NEAR(tilt.pitch_rate_rps, -10 * kDeg, 1e-12);
  EXPECT_NEAR(tilt.roll_rad, -5 * kDeg, 1e-12);
  EXPECT_NEAR(tilt.roll_rate_rps, 5 * kDeg, 1e-12);

  // 0x402: left 332 = 1 m/s, right -166 = -0.5 m/s, yaw rate 78 counts clockwise = -10 deg/s CCW.
  const RmpSpeedFrame sp = DecodeAs<RmpSpeedFrame>(codec, BytesFrame(0x402, {0x01, 0x4C, 0xFF, 0x5A, 0x00, 0x4E, 0xFF, 0xFF}));
  EXPECT_NEAR(sp.left_wheel_mps, 1.0, 1e-12);
  EXPECT_NEAR(sp.right_wheel_mps, -0.5, 1e-12);
  EXPECT_NEAR(sp.yaw_rate_rps, -10 * kDeg, 1e-12);
  EXPECT_EQ(sp.servo_frames, 65535);

  const RmpWheelIntegratorFrame wi =
      DecodeAs<RmpWheelIntegratorFrame>(codec, BytesFrame(0x403, {0x81, 0xBF, 0x00, 0x00, 0xFF, 0xFE, 0xFF, 0xFF}));
  EXPECT_EQ(wi.left_counts, 33215u) << "0x000081BF = 33215 counts = 1 m";
  EXPECT_NEAR(codec.DistanceMeters(static_cast<int32_t>(wi.left_counts)), 1.0, 1e-12);
  EXPECT_EQ(static_cast<int32_t>(wi.right_counts), -2);

  // 0x404: fore/aft 0x00010000, yaw -112644 counts = one turn; the RMP counts clockwise.
  const uint32_t minus_rev = static_cast<uint32_t>(-112644);
  const RmpBodyIntegratorFrame bi = DecodeAs<RmpBodyIntegratorFrame>(
      codec, BytesFrame(0x404, {0x00, 0x00, 0x00, 0x01, static_cast<uint8_t>((minus_rev >> 8) & 0xFF),
                                static_cast<uint8_t>(minus_rev & 0xFF), static_cast<uint8_t>(minus_rev >> 24),
                                static_cast<uint8_t>((minus_rev >> 16) & 0xFF)}));
  EXPECT_EQ(bi.fore_aft_counts, 0x00010000u);
  EXPECT_EQ(bi.yaw_counts, minus_rev);
  EXPECT_NEAR(codec.YawRadians(static_cast<int32_t>(bi.yaw_counts)), 2 * 3.14159265358979323846, 1e-12);

  // 0x405: +1094 = 1 N m, -2188 = -2 N m.
  const RmpTorqueFrame tq = DecodeAs<RmpTorqueFrame>(codec, BytesFrame(0x405, {0x04, 0x46, 0xF7, 0x74, 0x12, 0x34, 0x56, 0x78}));
  EXPECT_NEAR(tq.left_nm, 1.0, 1e-12);
  EXPECT_NEAR(tq.right_nm, -2.0, 1e-12);

  // 0x406: balance, tall, UI 848 counts = 12.0 V, base 288 counts = 72 V.
  const RmpModeFrame md = DecodeAs<RmpModeFrame>(codec, BytesFrame(0x406, {0x00, 0x02, 0x00, 0x01, 0x03, 0x50, 0x01, 0x20}));
  EXPECT_EQ(md.mode, OperationalMode::kBalance);
  EXPECT_EQ(md.gain_schedule, GainSchedule::kTall);
  EXPECT_NEAR(md.ui_battery_v, 12.0, 1e-12);
  EXPECT_NEAR(md.base_battery_v, 72.0, 1e-12);

  const RmpCommandEchoFrame echo = DecodeAs<RmpCommandEchoFrame>(codec, BytesFrame(0x407, {0xFB, 0x68, 0x04, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(echo.velocity_counts, -1176);
  EXPECT_EQ(echo.turn_counts, 1024);

  // 0x680: word 1 = motors enabled + low-battery hazard; word 2 = E-stop open on side B.
  const RmpCuStatusFrame cu = DecodeAs<RmpCuStatusFrame>(codec, BytesFrame(0x680, {0x00, 0x00, 0x40, 0x80, 0x02, 0x00, 0, 0}));
  EXPECT_EQ(cu.word1, 0x4080);
  EXPECT_EQ(cu.word2, 0x0200);
  EXPECT_TRUE(cu.motors_enabled());
  EXPECT_TRUE(cu.low_battery());
  EXPECT_TRUE(cu.fault()) << "E-stop open";
  EXPECT_FALSE((RmpCuStatusFrame{kRmpStatus1MotorsEnabled | kRmpStatus1BalanceMode, 0}).fault());
  EXPECT_TRUE((RmpCuStatusFrame{kRmpStatus1MotorFeedbackFault, 0}).fault());
  EXPECT_TRUE((RmpCuStatusFrame{0, kRmpStatus2LowBusVoltage}).low_battery());
}

TEST(RmpStatusTest, Rmp100ScalesAndYawSignOption) {
  RmpCodecOptions o;
  o.model = RmpModel::kRmp100;
  o.yaw_rate_sign = +1;
  const RmpCodec codec(o);
  const RmpSpeedFrame sp = DecodeAs<RmpSpeedFrame>(codec, BytesFrame(0x402, {0x01, 0x91, 0xFE, 0x6F, 0x00, 0x4E, 0, 0}));
  EXPECT_NEAR(sp.left_wheel_mps, 1.0, 1e-12);
  EXPECT_NEAR(sp.right_wheel_mps, -1.0, 1e-12);
  EXPECT_NEAR(sp.yaw_rate_rps, 10 * kDeg, 1e-12);
  EXPECT_NEAR(codec.DistanceMeters(40181), 1.0, 1e-12);
  EXPECT_NEAR(DecodeAs<RmpTorqueFrame>(codec, BytesFrame(0x405, {0x05, 0xB7, 0, 0, 0, 0, 0, 0})).left_nm, 1.0, 1e-12);
}

TEST(RmpStatusTest, GarbageAndTruncatedFramesAreErrorsForeignFramesAreNotFound) {
  const RmpCodec codec;
  auto code = [&](const hal::CanFrame& f) { return codec.Decode(f).status().code(); };
  EXPECT_EQ(code(BytesFrame(0x402, {0x01, 0x4C, 0, 0, 0, 0, 0}, 7)), StatusCode::kParseError) << "truncated";
  EXPECT_EQ(code(BytesFrame(0x403, {}, 0)), StatusCode::kParseError) << "empty";
  EXPECT_EQ(code(BytesFrame(0x406, {0x00, 0x05, 0, 0, 0, 0, 0, 0})), StatusCode::kParseError) << "mode 5";
  EXPECT_EQ(code(BytesFrame(0x406, {0x00, 0x01, 0x00, 0x07, 0, 0, 0, 0})), StatusCode::kParseError) << "gain schedule 7";
  EXPECT_EQ(code(BytesFrame(0x406, {0x00, 0x01, 0x00, 0x00, 0, 0, 0xFF, 0xFF})), StatusCode::kParseError) << "16 kV battery";
  EXPECT_EQ(code(BytesFrame(0x401, {0x03, 0xE8, 0, 0, 0, 0, 0, 0})), StatusCode::kParseError) << "pitch 128 deg";
  EXPECT_EQ(code(BytesFrame(0x402, {0x7F, 0xFF, 0, 0, 0, 0, 0, 0})), StatusCode::kParseError) << "98 m/s wheel";
  EXPECT_EQ(code(BytesFrame(0x407, {0x07, 0xD0, 0, 0, 0, 0, 0, 0})), StatusCode::kParseError) << "echo 2000 counts";
  hal::CanFrame rtr = BytesFrame(0x401, {});
  rtr.rtr = true;
  EXPECT_EQ(code(rtr), StatusCode::kParseError);
  EXPECT_EQ(code(BytesFrame(0x408, {})), StatusCode::kNotFound);
  EXPECT_EQ(code(BytesFrame(0x413, {})), StatusCode::kNotFound) << "a command from another node";
  hal::CanFrame ext = BytesFrame(0x401, {});
  ext.extended = true;
  EXPECT_EQ(code(ext), StatusCode::kNotFound);
  hal::CanFrame err = BytesFrame(0x040, {});
  err.error = true;
  EXPECT_EQ(code(err), StatusCode::kNotFound);
}

TEST(RmpStatusTest, EncodersRoundTripWithinOneCount) {
  const RmpCodec codec;
  const RmpTiltFrame tilt{0.1, -0.2, 0.05, 1.0};
  const RmpTiltFrame t2 = DecodeAs<RmpTiltFrame>(codec, codec.Encode(tilt));
  EXPECT_NEAR(t2.pitch_rad, tilt.pitch_rad, 0.5 * kDeg / 7.8);
  EXPECT_NEAR(t2.roll_rate_rps, tilt.roll_rate_rps, 0.5 * kDeg / 7.8);
  const RmpSpeedFrame sp{1.2345, -0.5, 0.7, 42};
  const RmpSpeedFrame sp2 = DecodeAs<RmpSpeedFrame>(codec, codec.Encode(sp));
  EXPECT_NEAR(sp2.left_wheel_mps, sp.left_wheel_mps, 0.5 / 332);
  EXPECT_NEAR(sp2.right_wheel_mps, sp.right_wheel_mps, 0.5 / 332);
  EXPECT_NEAR(sp2.yaw_rate_rps, sp.yaw_rate_rps, 0.5 * kDeg / 7.8);
  EXPECT_EQ(sp2.servo_frames, 42);
  // The yaw rate goes on the wire clockwise-positive.
  EXPECT_EQ(codec.Encode(RmpSpeedFrame{0, 0, 10 * kDeg, 0}).data[4], 0xFF);
  const RmpModeFrame md{OperationalMode::kTractor, GainSchedule::kHeavy, 12.3, 70.25};
  const RmpModeFrame md2 = DecodeAs<RmpModeFrame>(codec, codec.Encode(md));
  EXPECT_EQ(md2.mode, md.mode);
  EXPECT_EQ(md2.gain_schedule, md.gain_schedule);
  EXPECT_NEAR(md2.ui_battery_v, 12.3, 0.0125);
  EXPECT_NEAR(md2.base_battery_v, 70.25, 1e-12);
  // Saturation in the encoder instead of wrap-around.
  const RmpTorqueFrame big = DecodeAs<RmpTorqueFrame>(codec, codec.Encode(RmpTorqueFrame{100.0, -100.0}));
  EXPECT_NEAR(big.left_nm, 32767 / 1094.0, 1e-12);
  EXPECT_NEAR(big.right_nm, -32768 / 1094.0, 1e-12);
  const RmpWheelIntegratorFrame wi{0xFFFFFFFFu, 0x00000001u};
  EXPECT_EQ(DecodeAs<RmpWheelIntegratorFrame>(codec, codec.Encode(wi)).left_counts, 0xFFFFFFFFu);
  EXPECT_EQ(codec.DistanceCounts(-1.0), static_cast<uint32_t>(-33215));
  EXPECT_EQ(codec.YawCounts(2 * 3.14159265358979323846), static_cast<uint32_t>(-112644));
}

}  // namespace
}  // namespace idi::rmp
