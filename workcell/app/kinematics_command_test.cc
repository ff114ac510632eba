#include "workcell/app/kinematics_command.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace idi::workcell {
namespace {

// Runs `idi-workcell kinematics ARGS...`; returns the exit code, and stderr in `err`.
int RunKinematics(std::vector<std::string> args, std::string* err) {
  CliApp cli("test", "idi-workcell");
  AddKinematicsCommand(cli);
  args.insert(args.begin(), {"idi-workcell", "kinematics"});
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  ::testing::internal::CaptureStderr();
  const int code = RunCli(cli, static_cast<int>(argv.size()), argv.data());
  *err = ::testing::internal::GetCapturedStderr();
  return code;
}

// A target far beyond the workcell (1e308 mm) is bad input, refused before the aiming with the bound
// named (exit 2); before, the aiming ran and failed with "residual inf mm" (exit 1).
TEST(KinematicsCommandTest, AnAimTargetBeyondTheCellIsRefused) {
  std::string err;
  EXPECT_EQ(RunKinematics({"--aim-mm", "1e308,0,0", "--json"}, &err), 2) << err;
  EXPECT_NE(err.find("--aim-mm: the target 1e308,0,0 mm is out of range (at most 100000 mm, 100 m, from the robot "
                     "base)"),
            std::string::npos)
      << err;
  EXPECT_EQ(err.find("residual"), std::string::npos) << err;
  EXPECT_EQ(RunKinematics({"--aim-mm", "0,0,100001", "--json"}, &err), 2) << err;
  EXPECT_NE(err.find("out of range"), std::string::npos) << err;
  // A target in the cell is aimed at.
  EXPECT_EQ(RunKinematics({"--joints-deg", "0,-90,90,0,0,0", "--aim-mm", "3000,200,900", "--json"}, &err), 0) << err;
}

}  // namespace
}  // namespace idi::workcell
