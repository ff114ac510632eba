#include "rmp/app/fov_command.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "shared/util/units.h"

namespace idi::rmp {
namespace {

int RunFovCli(std::vector<std::string> args, std::string* out = nullptr) {
  CliApp cli("test", "idi-rmp");
  AddFovCommand(cli);
  args.insert(args.begin(), {"idi-rmp", "-q", "fov"});
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  testing::internal::CaptureStdout();
  const int code = RunCli(cli, static_cast<int>(argv.size()), argv.data());
  const std::string printed = testing::internal::GetCapturedStdout();
  if (out != nullptr) *out = printed;
  return code;
}

// Non-finite geometry went through with exit 0 ("sees the ground from 1000000000.00 m to -1000000000.00 m").
TEST(FovCommandTest, RefusesNonFiniteAndNonsensicalGeometry) {
  for (const char* option :
       {"--height-m", "--pitch-down-deg", "--baseline-m", "--forward-m", "--toe-in-deg", "--fx-px"}) {
    for (const char* value : {"inf", "-inf", "nan"}) {
      SCOPED_TRACE(std::string(option) + " " + value);
      std::string out;
      EXPECT_EQ(RunFovCli({option, value}, &out), kExitBadInput);
      EXPECT_TRUE(out.empty()) << out;
    }
  }
  for (const auto& [option, value] : std::vector<std::pair<std::string, std::string>>{{"--height-m", "0"},
                                                                                      {"--height-m", "1e9"},
                                                                                      {"--baseline-m", "-0.3"},
                                                                                      {"--fx-px", "-600"},
                                                                                      {"--fx-px", "1e-300"},
                                                                                      {"--fx-px", "49"},
                                                                                      {"--pitch-down-deg", "90"},
                                                                                      {"--toe-in-deg", "120"}}) {
    EXPECT_EQ(RunFovCli({option, value}), kExitBadInput) << option << " " << value;
  }
  FovOptions o;
  o.toe_in_deg = std::numeric_limits<double>::quiet_NaN();
  const Status st = o.Check();
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(st.message().find("--toe-in-deg"), std::string::npos) << st.message();
  EXPECT_NE(st.message().find("nan"), std::string::npos) << st.message();
  EXPECT_FALSE(ComputeFov(o).ok());
  EXPECT_TRUE(FovOptions{}.Check().ok());
}

TEST(FovCommandTest, NearestGroundIsTheBottomRow) {
  auto views = ComputeFov(FovOptions{});
  ASSERT_TRUE(views.ok()) << views.status().ToString();
  ASSERT_EQ(views->size(), 2u);
  for (const CameraGroundView& v : *views) {
    EXPECT_TRUE(v.sees_ground);
    EXPECT_FALSE(v.to_horizon);
    // 1 m up, 40 deg down; the bottom row is atan(240 / 600) below the optical axis.
    EXPECT_NEAR(v.nearest_ground_m, 0.25 + 1.0 / std::tan(DegToRad(40.0) + std::atan(240.0 / 600.0)), 1e-6);
    EXPECT_GT(v.farthest_ground_m, v.nearest_ground_m);
    EXPECT_LT(v.farthest_ground_m, 15.0);
    EXPECT_FALSE(v.footprint_m.empty());
  }
  EXPECT_EQ(RunFovCli({}), kExitOk);
}

// A camera looking up "saw the ground from 4.40 m to 15.25 m": the range cuts of rays above the horizon.
TEST(FovCommandTest, SaysWhenACameraDoesNotSeeTheGroundOrSeesToTheHorizon) {
  FovOptions up;
  up.pitch_down_deg = -60;
  auto views = ComputeFov(up);
  ASSERT_TRUE(views.ok()) << views.status().ToString();
  for (const CameraGroundView& v : *views) {
    EXPECT_FALSE(v.sees_ground) << v.camera;
    EXPECT_TRUE(v.to_horizon) << v.camera;
    EXPECT_TRUE(v.footprint_m.empty()) << v.camera;
  }
  std::string out;
  EXPECT_EQ(RunFovCli({"--pitch-down-deg", "-60"}, &out), kExitOk);
  EXPECT_NE(out.find("left camera: does not see the ground"), std::string::npos) << out;
  EXPECT_EQ(out.find(" m to "), std::string::npos) << out;

  // 10 deg down with a 21.8 deg half field: the bottom row meets the ground, the top looks above the horizon.
  FovOptions level;
  level.pitch_down_deg = 10;
  views = ComputeFov(level);
  ASSERT_TRUE(views.ok()) << views.status().ToString();
  for (const CameraGroundView& v : *views) {
    EXPECT_TRUE(v.sees_ground) << v.camera;
    EXPECT_TRUE(v.to_horizon) << v.camera;
    EXPECT_NEAR(v.nearest_ground_m, 0.25 + 1.0 / std::tan(DegToRad(10.0) + std::atan(240.0 / 600.0)), 1e-6);
  }
  EXPECT_EQ(RunFovCli({"--pitch-down-deg", "10"}, &out), kExitOk);
  EXPECT_NE(out.find("right camera: sees the ground from 1.86 m ahead to the horizon"), std::string::npos) << out;
  EXPECT_EQ(RunFovCli({"--pitch-down-deg", "10", "--json"}, &out), kExitOk);
  EXPECT_NE(out.find("\"farthest_ground_m\":null"), std::string::npos) << out;
  EXPECT_NE(out.find("\"to_horizon\":true"), std::string::npos) << out;
}

}  // namespace
}  // namespace idi::rmp
