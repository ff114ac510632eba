#include "workcell/devices/ptu/ptu_codec.h"

#include <gtest/gtest.h>

#include "shared/util/units.h"

namespace idi::workcell {
namespace {

TEST(PtuCodecTest, EncodesCommandsWithASpaceDelimiter) {
  EXPECT_EQ(PtuCommand("FT"), "FT ");
  EXPECT_EQ(PtuSetPositionCommand(PtuAxis::kPan, 1200), "PP1200 ");
  EXPECT_EQ(PtuSetPositionCommand(PtuAxis::kTilt, -300), "TP-300 ");
  EXPECT_EQ(PtuQueryCommand(PtuAxis::kPan, PtuQuantity::kResolution), "PR ");
  EXPECT_EQ(PtuQueryCommand(PtuAxis::kTilt, PtuQuantity::kMaximum), "TX ");
  EXPECT_EQ(PtuQueryCommand(PtuAxis::kTilt, PtuQuantity::kPosition), "TP ");
}

TEST(PtuCodecTest, ParsesAckValueAndError) {
  EXPECT_EQ(ParsePtuReply("*").kind, PtuReplyKind::kAck);
  const PtuReply value = ParsePtuReply("* 185.1428");
  EXPECT_EQ(value.kind, PtuReplyKind::kValue);
  EXPECT_EQ(value.text, "185.1428");
  const PtuReply error = ParsePtuReply("! Maximum allowable Pan position is 3090");
  EXPECT_EQ(error.kind, PtuReplyKind::kError);
  EXPECT_EQ(error.text, "Maximum allowable Pan position is 3090");
  EXPECT_TRUE(error.limit_hits.empty());
}

TEST(PtuCodecTest, AsynchronousLimitNoticesAreSeparatedFromTheReply) {
  const PtuReply only = ParsePtuReply("!P");
  EXPECT_EQ(only.kind, PtuReplyKind::kNone);
  ASSERT_EQ(only.limit_hits.size(), 1u);
  EXPECT_EQ(only.limit_hits[0], PtuAxis::kPan);
  // The reset sequence the FLIR driver waits for: both axes twice, then the ack.
  const PtuReply reset = ParsePtuReply("!T!T!P!P*");
  EXPECT_EQ(reset.kind, PtuReplyKind::kAck);
  EXPECT_EQ(reset.limit_hits, (std::vector<PtuAxis>{PtuAxis::kTilt, PtuAxis::kTilt, PtuAxis::kPan, PtuAxis::kPan}));
  const PtuReply with_value = ParsePtuReply("!T * -907");
  EXPECT_EQ(with_value.kind, PtuReplyKind::kValue);
  EXPECT_EQ(with_value.text, "-907");
}

TEST(PtuCodecTest, EchoIsRemoved) {
  const PtuReply echoed = ParsePtuReply("PP * 1200", "PP ");
  EXPECT_EQ(echoed.kind, PtuReplyKind::kValue);
  EXPECT_EQ(echoed.text, "1200");
  EXPECT_EQ(ParsePtuReply("pp1200 *", "PP1200 ").kind, PtuReplyKind::kAck);  // commands are case-insensitive
  EXPECT_EQ(ParsePtuReply("FT", "FT ").kind, PtuReplyKind::kEcho);
  // Not an echo: a different command's text is left alone.
  EXPECT_EQ(ParsePtuReply("TP * 3", "PP ").kind, PtuReplyKind::kUnknown);
}

TEST(PtuCodecTest, ChatterAndNoiseAreUnknown) {
  EXPECT_EQ(ParsePtuReply("independent (default) speed control mode").kind, PtuReplyKind::kUnknown);
  EXPECT_EQ(ParsePtuReply(std::string("\xff\xfe\x13", 3)).kind, PtuReplyKind::kUnknown);
  EXPECT_EQ(ParsePtuReply("Initializing...").kind, PtuReplyKind::kUnknown);
}

TEST(PtuCodecTest, NumbersFromTerseAndVerboseValues) {
  EXPECT_DOUBLE_EQ(PtuFirstNumber("185.1428").value(), 185.1428);
  EXPECT_DOUBLE_EQ(PtuFirstNumber("185.1428 seconds arc per Pan position").value(), 185.1428);
  EXPECT_EQ(PtuFirstInteger("-3090").value(), -3090);
  EXPECT_EQ(PtuFirstInteger("Current Pan position is -12").value(), -12);
  EXPECT_EQ(PtuFirstInteger("Minimum Tilt position is +4").value(), 4);
  EXPECT_EQ(PtuFirstInteger("twelve").status().code(), StatusCode::kParseError);
  EXPECT_EQ(PtuFirstInteger("12.5").status().code(), StatusCode::kParseError);
  EXPECT_EQ(PtuFirstNumber("nan inf").status().code(), StatusCode::kParseError);
}

TEST(PtuCodecTest, ResolutionInArcSecondsToRadians) {
  // PTUMAN p=15: 185.1428 arc-seconds per position = 0.0514285 degrees.
  EXPECT_NEAR(RadToDeg(PtuArcSecondsToRad(185.1428)), 0.0514285, 1e-7);
}

}  // namespace
}  // namespace idi::workcell
