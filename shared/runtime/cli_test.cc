#include "shared/runtime/cli.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <iostream>

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

// A run whose results could not be written to stdout (a full disk, a closed pipe) fails: exit 1 and the
// reason on stderr (before, exit 0 and the results lost). A run that failed already keeps its code.
TEST(CliTest, AFailedWriteToStandardOutputFailsTheRun) {
  if (!std::filesystem::exists("/dev/full")) GTEST_SKIP() << "no /dev/full";
  // `flush`: the command flushes its line itself (the write fails inside the command, not at the end).
  const auto run = [](Status status, bool flush) {
    CliApp cli("test", "idi-test");
    cli.AddCommand(&cli.app, "say", "prints a line", [status, flush] {
      std::cout << "a result\n";
      if (flush) std::cout << std::flush;
      return status;
    });
    std::cout.flush();
    std::fflush(stdout);
    const int saved = ::dup(STDOUT_FILENO);
    const int full = ::open("/dev/full", O_WRONLY);
    EXPECT_GE(full, 0);
    ::dup2(full, STDOUT_FILENO);
    ::close(full);
    char arg0[] = "idi-test";
    char arg1[] = "say";
    char* argv[] = {arg0, arg1, nullptr};
    testing::internal::CaptureStderr();
    const int code = RunCli(cli, 2, argv);
    const std::string err = testing::internal::GetCapturedStderr();
    ::dup2(saved, STDOUT_FILENO);
    ::close(saved);
    std::clearerr(stdout);
    std::cout.clear();
    return std::pair{code, err};
  };
  for (const bool flush : {false, true}) {
    const auto [code, err] = run(Status::Ok(), flush);
    EXPECT_EQ(code, kExitFailed) << flush;
    // The reason only when the final flush is the write that failed (the line was still buffered).
    EXPECT_NE(err.find(flush ? "idi-test: writing to standard output failed"
                             : "idi-test: writing to standard output failed: No space left on device"),
              std::string::npos)
        << err;
  }
  EXPECT_EQ(run(InvalidArgument("bad input"), false).first, kExitBadInput);
}

}  // namespace
}  // namespace idi
