#include "workcell/devices/barrett/barrett_codec.h"

#include <gtest/gtest.h>

namespace idi::workcell {
namespace {

TEST(BarrettCodecTest, MotorPrefixes) {
  EXPECT_EQ(BarrettMotorPrefix(kBarrettWholeHand), "");
  EXPECT_EQ(BarrettMotorPrefix(kBarrettFingers), "G");
  EXPECT_EQ(BarrettMotorPrefix(kBarrettSpread), "S");
  EXPECT_EQ(BarrettMotorPrefix(kBarrettF1 | kBarrettF3), "13");
  EXPECT_EQ(ParseBarrettMotorPrefix("G").value(), kBarrettFingers);
  EXPECT_EQ(ParseBarrettMotorPrefix("S").value(), kBarrettSpread);
  EXPECT_EQ(ParseBarrettMotorPrefix("").value(), kBarrettWholeHand);
  EXPECT_EQ(ParseBarrettMotorPrefix("12").value(), kBarrettF1 | kBarrettF2);
  EXPECT_EQ(ParseBarrettMotorPrefix("X").status().code(), StatusCode::kInvalidArgument);
}

TEST(BarrettCodecTest, CommandText) {
  EXPECT_EQ(BarrettCommandText(kBarrettWholeHand, "HI"), "HI");
  EXPECT_EQ(BarrettCommandText(kBarrettFingers, "C"), "GC");
  EXPECT_EQ(BarrettCommandText(kBarrettSpread, "M", "1575"), "SM 1575");
  EXPECT_EQ(BarrettCommandText(kBarrettF1, "FGET", "P"), "1FGET P");
  EXPECT_EQ(BarrettCommandBytes("GO"), "GO\r");
}

TEST(BarrettCodecTest, ParsesEchoOutputAndErrors) {
  const BarrettReply done = ParseBarrettReply("GC\r\n", "GC");
  EXPECT_TRUE(done.echo_found);
  EXPECT_FALSE(done.error);
  EXPECT_TRUE(done.lines.empty());

  const BarrettReply value = ParseBarrettReply("1FGET P\r\n1234\r\n", "1FGET P");
  ASSERT_EQ(value.lines.size(), 1u);
  EXPECT_EQ(value.lines[0], "1234");

  const BarrettReply error = ParseBarrettReply("GC\r\nERR 17\r\n", "gc");
  EXPECT_TRUE(error.error);
  EXPECT_EQ(error.error_code, 17);
  EXPECT_EQ(error.error_text, "ERR 17");
}

TEST(BarrettCodecTest, NoiseAndStaleBlocksAreRecognised) {
  // Noise on the echo's line, or a line of noise before it.
  EXPECT_TRUE(ParseBarrettReply(std::string("\x01\x02GC\r\n", 6), "GC").echo_found);
  const BarrettReply noisy = ParseBarrettReply("~~\r\nGO\r\n", "GO");
  EXPECT_TRUE(noisy.echo_found);
  EXPECT_EQ(noisy.dropped_lines, 1);
  // The prompt of an earlier command, or the power-up banner: not this command's reply.
  EXPECT_FALSE(ParseBarrettReply("GO\r\n", "GC").echo_found);
  EXPECT_FALSE(ParseBarrettReply("\r\nBarrettHand Firmware Version 4.3.3\r\n", "1FGET P").echo_found);
  // A bare CR has no visible echo.
  EXPECT_TRUE(ParseBarrettReply("\r\n", "").echo_found);
}

TEST(BarrettCodecTest, Integers) {
  EXPECT_EQ(BarrettIntegers({"1200 1300", "-5"}).value(), (std::vector<long>{1200, 1300, -5}));
  EXPECT_EQ(BarrettIntegers({"12x"}).status().code(), StatusCode::kParseError);
  EXPECT_TRUE(BarrettIntegers({}).value().empty());
}

}  // namespace
}  // namespace idi::workcell
