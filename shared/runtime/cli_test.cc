#include "shared/runtime/cli.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <tuple>
#include <vector>

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

// Numbers on the command line are decimal: hexadecimal ("0x10", which stod reads as 16) is refused
// with the option named; the forms people write still read.
TEST(CliTest, NumbersAreDecimal) {
  for (const char* good : {"1", "-1.5", "1e-3", ".5", "5.", "+2", "010", "1E+3"}) {
    EXPECT_TRUE(IsDecimalNumber(good)) << good;
  }
  for (const char* bad : {"", "0x10", "0X1p3", "inf", "nan", "1e", ".", "-", "1,5", " 1", "1 ", "1_000", "0b101"}) {
    EXPECT_FALSE(IsDecimalNumber(bad)) << bad;
  }
  const auto ok = ParseNumberList(" 1, -1.5,1e-3 , .5", 4, "--aim-mm");
  ASSERT_TRUE(ok.ok()) << ok.status().ToString();
  EXPECT_EQ(ok.value(), (std::vector<double>{1, -1.5, 1e-3, .5}));
  const auto hex = ParseNumberList("0x10,0,90,0,0,0", 6, "--joints-deg");
  ASSERT_FALSE(hex.ok()) << "read as " << hex.value()[0];
  EXPECT_EQ(hex.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(hex.status().message().find("--joints-deg: '0x10' is not a finite decimal number"), std::string::npos)
      << hex.status().message();
  EXPECT_FALSE(ParseNumberList("1e400", 1, "--aim-mm").ok()) << "beyond a double";
}

// CLI11 reads "0x10" as 16 for numeric options, and an integer's "010" as octal 8: every numeric option
// of every command takes decimal numbers only (exit 2, the option named).
TEST(CliTest, NumericOptionsAreDecimal) {
  const auto run = [](const std::vector<std::string>& args, double* real, int* integer) {
    CliApp cli("test", "idi-test");
    CLI::App* cmd = cli.AddCommand(&cli.app, "run", "a command", [] { return Status::Ok(); });
    cmd->add_option("--real", *real, "a real number");
    cmd->add_option("--count", *integer, "an integer")->check(CLI::Range(0, 100));
    std::vector<std::string> words = {"idi-test", "run"};
    words.insert(words.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& w : words) argv.push_back(w.data());
    testing::internal::CaptureStderr();
    const int code = RunCli(cli, static_cast<int>(argv.size()), argv.data());
    return std::pair{code, testing::internal::GetCapturedStderr()};
  };
  double real = 0;
  int integer = 0;
  for (const auto& [text, value] :
       std::vector<std::pair<std::string, double>>{{"1", 1}, {"-1.5", -1.5}, {"1e-3", 1e-3}, {".5", .5}}) {
    const auto [code, err] = run({"--real=" + text}, &real, &integer);
    EXPECT_EQ(code, kExitOk) << text << ": " << err;
    EXPECT_EQ(real, value) << text;
  }
  auto [code, err] = run({"--count", "010"}, &real, &integer);
  EXPECT_EQ(code, kExitOk) << err;
  EXPECT_EQ(integer, 10) << "decimal, not octal";
  std::tie(code, err) = run({"--count", "-0"}, &real, &integer);
  EXPECT_EQ(code, kExitOk) << err;
  EXPECT_EQ(integer, 0);
  for (const std::vector<std::string>& args : {std::vector<std::string>{"--real", "0x10"},
                                               std::vector<std::string>{"--count", "0x10"},
                                               std::vector<std::string>{"--real", "0x1p4"},
                                               std::vector<std::string>{"--count", "1_0"}}) {
    std::tie(code, err) = run(args, &real, &integer);
    EXPECT_EQ(code, kExitBadInput) << args[1];
    EXPECT_NE(err.find(args[0] + ": '" + args[1] + "' is not a decimal number"), std::string::npos) << err;
  }
  // Whether an option takes inf or nan is its own check's to say (the commands' checks name the option).
  std::tie(code, err) = run({"--real=-inf"}, &real, &integer);
  EXPECT_EQ(code, kExitOk) << err;
  EXPECT_TRUE(std::isinf(real));
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
