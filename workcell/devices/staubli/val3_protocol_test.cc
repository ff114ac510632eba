#include "workcell/devices/staubli/val3_protocol.h"

#include <gtest/gtest.h>

#include "shared/util/units.h"
#include "workcell/devices/staubli/staubli_joints.h"

namespace idi::workcell {
namespace {

TEST(Val3ProtocolTest, RequestsRoundTrip) {
  const Val3Request move{7, Val3Verb::kMoveJ, {20, 0, -45.5, 90, 0, 12.25, -180}};
  const std::string line = EncodeVal3Request(move);
  EXPECT_EQ(line, "7 MOVEJ 20.0000 0.0000 -45.5000 90.0000 0.0000 12.2500 -180.0000\n");
  const auto parsed = ParseVal3Request(line.substr(0, line.size() - 1));
  ASSERT_TRUE(parsed.ok()) << parsed.status().ToString();
  EXPECT_EQ(parsed->id, 7u);
  EXPECT_EQ(parsed->verb, Val3Verb::kMoveJ);
  EXPECT_EQ(parsed->args, move.args);
  EXPECT_EQ(EncodeVal3Request({1, Val3Verb::kJoints, {}}), "1 JOINTS\n");
  EXPECT_EQ(EncodeVal3Request({2, Val3Verb::kRailMove, {50, 1000}}), "2 RAILMOVE 50.0000 1000.0000\n");
}

TEST(Val3ProtocolTest, BadRequestsAreClassified) {
  EXPECT_EQ(ParseVal3Request("MOVEJ 1 2").status().code(), StatusCode::kParseError);        // no id
  EXPECT_EQ(ParseVal3Request("3 JUMP").status().code(), StatusCode::kInvalidArgument);      // unknown verb
  EXPECT_EQ(ParseVal3Request("3 MOVEJ 1 2").status().code(), StatusCode::kOutOfRange);      // argument count
  EXPECT_EQ(ParseVal3Request("3 RAILMOVE 1 1e3").status().code(), StatusCode::kOutOfRange); // not a plain decimal
  EXPECT_EQ(ParseVal3Request("1000000 PING").status().code(), StatusCode::kParseError);    // id too large
  EXPECT_EQ(ParseVal3Request(std::string(200, '1')).status().code(), StatusCode::kParseError);
}

TEST(Val3ProtocolTest, RepliesRoundTripAndGarbageIsRejected) {
  Val3Reply ok;
  ok.id = 12;
  ok.fields = {"1.0000", "2.0000", "1"};
  EXPECT_EQ(EncodeVal3Reply(ok), "12 OK 1.0000 2.0000 1\n");
  const auto parsed_ok = ParseVal3Reply("12 OK 1.0000 2.0000 1\r");
  ASSERT_TRUE(parsed_ok.ok());
  EXPECT_TRUE(parsed_ok->ok);
  EXPECT_EQ(parsed_ok->fields, ok.fields);

  const auto err = ParseVal3Reply("13 ERR 4 arm power is off");
  ASSERT_TRUE(err.ok());
  EXPECT_FALSE(err->ok);
  EXPECT_EQ(err->error_code, 4);
  EXPECT_EQ(err->error_text, "arm power is off");
  // An id containing the code's digit: the text still starts after the code.
  const auto err14 = ParseVal3Reply("14 ERR 4 arm power is off");
  ASSERT_TRUE(err14.ok());
  EXPECT_EQ(err14->error_text, "arm power is off");

  EXPECT_FALSE(ParseVal3Reply("OK 1 2").ok());
  EXPECT_FALSE(ParseVal3Reply("14 MAYBE").ok());
  EXPECT_FALSE(ParseVal3Reply("15 ERR").ok());
  EXPECT_FALSE(ParseVal3Reply(std::string("16 OK \x01\x02", 8)).ok());
}

TEST(Val3ProtocolTest, TypedDecoders) {
  const auto joints = DecodeVal3Joints(ParseVal3Reply("3 OK 1 2 3 4 5 -6.5 0").value());
  ASSERT_TRUE(joints.ok());
  EXPECT_EQ(joints->deg[5], -6.5);
  EXPECT_FALSE(joints->settled);
  EXPECT_FALSE(DecodeVal3Joints(ParseVal3Reply("3 OK 1 2 3 4 5 1").value()).ok());     // 6 fields
  EXPECT_FALSE(DecodeVal3Joints(ParseVal3Reply("3 OK 1 2 3 4 5 6 2").value()).ok());   // flag not 0/1
  const auto rail = DecodeVal3Rail(ParseVal3Reply("4 OK 1000.2500 1").value());
  ASSERT_TRUE(rail.ok());
  EXPECT_EQ(rail->mm, 1000.25);
  EXPECT_TRUE(rail->settled);
  const auto hello = DecodeVal3Hello(ParseVal3Reply("1 OK IDI-VAL3 1 0").value());
  ASSERT_TRUE(hello.ok());
  EXPECT_EQ(hello->version, 1);
  EXPECT_FALSE(hello->has_rail);
  EXPECT_FALSE(DecodeVal3Hello(ParseVal3Reply("1 OK SOMETHING 1 0").value()).ok());
  const auto status = DecodeVal3Status(ParseVal3Reply("5 OK 1 0 1 1 3").value());
  ASSERT_TRUE(status.ok());
  EXPECT_TRUE(status->powered);
  EXPECT_EQ(status->last_error, 3);
}

TEST(StaubliJointsTest, ControllerAndModelConventionsDifferByTheOffset) {
  // The controller's zero (arm straight up) is (0, -90, +90, 0, 0, 0) deg in the model (rx130.h).
  const Joints model = ControllerDegToModelRad({0, 0, 0, 0, 0, 0});
  EXPECT_NEAR(model[1], DegToRad(-90.0), 1e-15);
  EXPECT_NEAR(model[2], DegToRad(90.0), 1e-15);
  const ControllerJointsDeg back = ModelRadToControllerDeg({0.1, -0.2, 0.3, -0.4, 0.5, -0.6});
  const Joints again = ControllerDegToModelRad(back);
  EXPECT_NEAR(again[3], -0.4, 1e-15);
  EXPECT_NEAR(back[1], RadToDeg(-0.2) + 90.0, 1e-12);
  EXPECT_NEAR(Rx130ControllerMaxDeg()[1], 137.5, 1e-12);
  EXPECT_NEAR(Rx130ControllerMinDeg()[4], -105.0, 1e-12);
}

}  // namespace
}  // namespace idi::workcell
