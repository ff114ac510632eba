// The hardware cell's cameras on real V4L2 capture devices: runs when IDI_TEST_V4L2_DEVICES lists two
// device nodes ("/dev/video0,/dev/video1"), skips otherwise. tools/kernel-test runs it in a VM with the
// kernel's vivid driver (ctest label "kernel"); the arm is the VAL3 emulator on loopback.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "workcell/app/cell_factory.h"
#include "workcell/devices/staubli/val3_emulator.h"

namespace idi::workcell {
namespace {

std::vector<std::string> DevicesFromEnv() {
  std::vector<std::string> out;
  const char* env = std::getenv("IDI_TEST_V4L2_DEVICES");
  if (env == nullptr) return out;
  std::stringstream ss(env);
  for (std::string d; std::getline(ss, d, ',');) {
    if (!d.empty()) out.push_back(d);
  }
  return out;
}

// Connecting opens both configured cameras, homing takes one frame from each, health says so; a reset
// (connect and home again) neither reopens nor fails them.
TEST(CellCamerasDeviceTest, TheHardwareCellOpensItsCamerasAndChecksEachWithAFrame) {
  const std::vector<std::string> devices = DevicesFromEnv();
  if (devices.size() < 2) GTEST_SKIP() << "IDI_TEST_V4L2_DEVICES does not list two nodes (tools/kernel-test sets it)";
  for (const auto& d : devices) ASSERT_TRUE(std::filesystem::exists(d)) << d << " is listed but missing";
  auto arm = Val3Emulator::Start();
  ASSERT_TRUE(arm.ok()) << arm.status().ToString();
  WorkcellConfig c;
  c.backend = "hardware";
  c.state_dir = (std::filesystem::temp_directory_path() / "idi-cell-cameras-test").string();
  c.arms = {{"arm1", "127.0.0.1", (*arm)->port()}};
  c.cameras = {{"left", "v4l2", devices[0]}, {"right", "v4l2", devices[1]}};
  auto cell = MakeCell(c);
  ASSERT_TRUE(cell.ok()) << cell.status().ToString();
  for (int round = 1; round <= 2; ++round) {
    const Status connected = cell->devices->Connect();
    ASSERT_TRUE(connected.ok()) << "round " << round << ": " << connected.ToString();
    const Status homed = cell->devices->Home();
    ASSERT_TRUE(homed.ok()) << "round " << round << ": " << homed.ToString();
    const nlohmann::json h = cell->devices->Health();
    ASSERT_EQ(h.at("cameras").size(), 2u) << h.dump();
    for (std::size_t k = 0; k < 2; ++k) {
      const nlohmann::json& cam = h.at("cameras")[k];
      EXPECT_EQ(cam.at("name").get<std::string>(), k == 0 ? "left" : "right");
      EXPECT_EQ(cam.at("device").get<std::string>(), devices[k]);
      EXPECT_EQ(cam.at("state").get<std::string>(), "streaming") << cam.dump();
      EXPECT_EQ(cam.at("frames").get<int>(), round) << cam.dump();
      EXPECT_FALSE(cam.contains("last_error")) << cam.dump();
    }
  }
  EXPECT_TRUE(cell->devices->StopAll().ok());
}

}  // namespace
}  // namespace idi::workcell
