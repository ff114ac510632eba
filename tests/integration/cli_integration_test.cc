// The binaries' command-line contracts: --help/--version, exit codes (0 ok, 2 bad input, 1 failed
// run), JSON on stdout, messages on stderr naming what was wrong.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "tests/support/run_command.h"

namespace idi::test {
namespace {

const std::string kWorkcell = IDI_WORKCELL_BIN;
const std::string kRmp = IDI_RMP_BIN;

TEST(CliIntegrationTest, HelpAndVersion) {
  for (const std::string& bin : {kWorkcell, kRmp}) {
    const auto help = RunCommand(bin + " --help");
    EXPECT_EQ(help.exit_code, 0) << bin;
    EXPECT_NE(help.out.find("Subcommands"), std::string::npos) << help.out;
    const auto version = RunCommand(bin + " --version");
    EXPECT_EQ(version.exit_code, 0);
    EXPECT_NE(version.out.find("0.1.0"), std::string::npos) << version.out;
    const auto none = RunCommand(bin);
    EXPECT_EQ(none.exit_code, 2) << "no subcommand is a usage error";
    const auto bogus = RunCommand(bin + " no-such-command");
    EXPECT_EQ(bogus.exit_code, 2);
  }
}

TEST(CliIntegrationTest, KinematicsJsonAimsTheLaser) {
  const auto r = RunCommand(kWorkcell + " kinematics --joints-deg 0,-90,90,0,0,0 --aim-mm 3000,200,900 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  // Straight up with nominal parameters: the flange is at (0, 0, 1360).
  EXPECT_NEAR(j["flange_mm"][2].get<double>(), 1360.0, 1e-9);
  EXPECT_LT(j["aim"]["miss_mm"].get<double>(), 1e-6);
}

TEST(CliIntegrationTest, BadInputExitsWithTwoAndSaysWhat) {
  auto r = RunCommand(kWorkcell + " kinematics --joints-deg 0,1,2");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--joints-deg: expected 6"), std::string::npos) << r.err;
  r = RunCommand(kWorkcell + " kinematics --joints-deg 0,-90,90,0,200,0");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("joint 5"), std::string::npos) << r.err;
  r = RunCommand(kWorkcell + " kinematics --robot /no/such/robot.yaml");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("/no/such/robot.yaml"), std::string::npos) << r.err;
}

TEST(CliIntegrationTest, ParamsFileRoundTripsThroughKinematics) {
  const std::string dir = MakeTempDir("params_cli");
  const std::string path = dir + "/robot.yaml";
  auto r = RunCommand(kWorkcell + " params rx130 --out " + path);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = RunCommand(kWorkcell + " kinematics --robot " + path + " --json");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  // Corrupt one value: the run is refused with the file and key named.
  {
    std::ofstream out(path, std::ios::app);
    out << "bogus_mm: 1\n";
  }
  r = RunCommand(kWorkcell + " kinematics --robot " + path);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("unknown key 'bogus_mm'"), std::string::npos) << r.err;
  std::filesystem::remove_all(dir);
}

TEST(CliIntegrationTest, RmpFootprint) {
  const auto r = RunCommand(kRmp + " fov --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j.size(), 2u);
  EXPECT_GT(j[0]["nearest_ground_m"].get<double>(), 0.25);
  const auto bad = RunCommand(kRmp + " fov --height-m -1");
  EXPECT_EQ(bad.exit_code, 2);
}

}  // namespace
}  // namespace idi::test
