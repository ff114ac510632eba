#include "shared/util/status.h"

#include <gtest/gtest.h>

#include <limits>
#include <string>

namespace idi {
namespace {

Result<int> ParsePositive(int v) {
  if (v <= 0) {
    return InvalidArgument("expected a positive number, got " + std::to_string(v));
  }
  return v;
}

Result<int> Doubled(int v) {
  IDI_ASSIGN_OR_RETURN(const int x, ParsePositive(v));
  return 2 * x;
}

Status CheckBoth(int a, int b) {
  IDI_RETURN_IF_ERROR(ParsePositive(a).status());
  IDI_RETURN_IF_ERROR(ParsePositive(b).status());
  return Status::Ok();
}

TEST(StatusTest, OkAndErrorCarryCodeAndMessage) {
  EXPECT_TRUE(Status::Ok().ok());
  const Status s = NotFound("robot.yaml: no such file");
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.code(), StatusCode::kNotFound);
  EXPECT_EQ(s.ToString(), "not found: robot.yaml: no such file");
  EXPECT_EQ(s.WithContext("loading").message(), "loading: robot.yaml: no such file");
}

TEST(StatusTest, ResultPropagatesThroughMacros) {
  EXPECT_EQ(Doubled(4).value(), 8);
  const Result<int> bad = Doubled(-1);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("-1"), std::string::npos);
  EXPECT_TRUE(CheckBoth(1, 2).ok());
  EXPECT_EQ(CheckBoth(1, 0).code(), StatusCode::kInvalidArgument);
}

TEST(StatusDeathTest, ValueOfErrorAborts) {
  const Result<int> bad = ParsePositive(0);
  EXPECT_DEATH((void)bad.value(), "Result::value\\(\\) on an error");
}

}  // namespace
}  // namespace idi

// Messages show a number as it was given (the fewest digits that read back the same, up to 12), or to 6
// significant digits when it needs more, not std::to_string's six fixed decimals (which showed 1e-7 as
// 0.000000 and 1e308 as 309 digits).
TEST(FormatNumberTest, AsGivenOrToSixDigits) {
  EXPECT_EQ(idi::FormatNumber(0.1), "0.1");
  EXPECT_EQ(idi::FormatNumber(2.5), "2.5");
  EXPECT_EQ(idi::FormatNumber(-3.0), "-3");
  EXPECT_EQ(idi::FormatNumber(1e-7), "1e-07");
  EXPECT_EQ(idi::FormatNumber(1e308), "1e+308");
  EXPECT_EQ(idi::FormatNumber(2000.0), "2000");  // not 2e+03
  EXPECT_EQ(idi::FormatNumber(2500.0), "2500");
  EXPECT_EQ(idi::FormatNumber(100000.0), "1e+05");  // the shorter form, as std::to_chars picks it
  EXPECT_EQ(idi::FormatNumber(-0.0), "-0");
  EXPECT_EQ(idi::FormatNumber(1.0000001), "1.0000001");  // a refused value just above 1 is not shown as 1
  EXPECT_EQ(idi::FormatNumber(0.1 + 0.2), "0.3");        // 17 digits to read back: six
  EXPECT_EQ(idi::FormatNumber(3.14159265358979), "3.14159");
  EXPECT_EQ(idi::FormatNumber(std::numeric_limits<double>::infinity()), "inf");
  EXPECT_EQ(idi::FormatNumber(-std::numeric_limits<double>::infinity()), "-inf");
  EXPECT_EQ(idi::FormatNumber(std::numeric_limits<double>::quiet_NaN()), "nan");
  EXPECT_EQ(idi::FormatNumber(0.1f), "0.1");  // not the double nearest the float, 0.100000001
  EXPECT_EQ(idi::FormatNumber(1.5e-9f), "1.5e-09");
  EXPECT_EQ(idi::FormatNumber(4.9406564584124654e-324), "5e-324");  // the smallest denormal
  EXPECT_EQ(idi::FormatNumber(1234.5678901234567), "1234.57");      // 17 digits: six
}
