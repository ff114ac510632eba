#include "shared/runtime/cli.h"

#include <gtest/gtest.h>

namespace idi {
namespace {

TEST(CliTest, ParsesNumberLists) {
  const auto r = ParseNumberList("1, -2.5,3e2", 3, "--joints-deg");
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.value(), (std::vector<double>{1, -2.5, 300}));
  EXPECT_FALSE(ParseNumberList("1,2", 3, "--joints-deg").ok());
  EXPECT_FALSE(ParseNumberList("1,x,3", 3, "--joints-deg").ok());
  EXPECT_FALSE(ParseNumberList("1,nan,3", 3, "--joints-deg").ok());
  const auto bad = ParseNumberList("1,,3", 3, "--aim-mm");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("--aim-mm"), std::string::npos);
  // A trailing comma is a missing number, not the end of the list.
  const auto trailing = ParseNumberList("0,-60,100,0,50,0,", 6, "--joints-deg");
  ASSERT_FALSE(trailing.ok());
  EXPECT_NE(trailing.status().message().find("missing after the last comma"), std::string::npos)
      << trailing.status().message();
}

TEST(CliTest, ExitCodes) {
  EXPECT_EQ(ExitCodeFor(Status::Ok()), 0);
  EXPECT_EQ(ExitCodeFor(InvalidArgument("x")), 2);
  EXPECT_EQ(ExitCodeFor(NotFound("x")), 2);
  EXPECT_EQ(ExitCodeFor(ParseError("x")), 2);
  EXPECT_EQ(ExitCodeFor(NotConverged("x")), 1);
  EXPECT_EQ(ExitCodeFor(DeviceError("x")), 1);
}

}  // namespace
}  // namespace idi
