#include "shared/util/status.h"

#include <gtest/gtest.h>

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
