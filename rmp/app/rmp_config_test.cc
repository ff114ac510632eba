#include "rmp/app/rmp_config.h"

#include <gtest/gtest.h>

namespace idi::rmp {
namespace {

TEST(RmpConfigTest, DefaultsAreValid) {
  const RmpConfig c = DefaultRmpConfig();
  EXPECT_TRUE(c.Check().ok()) << c.Check().ToString();
  EXPECT_EQ(c.backend, Backend::kSim);
  EXPECT_DOUBLE_EQ(c.driver.max_input_age_s, 0.2);
  EXPECT_DOUBLE_EQ(c.driver.command_rate_hz, 50.0);
}

TEST(RmpConfigTest, ReadsTheDeploymentFile) {
  // The keys of targets/segway-laptop/rmp.yaml.
  auto c = ParseRmpConfig(
      "backend: hardware\n"
      "state_dir: /var/lib/idi-rmp\n"
      "hardware:\n"
      "  can: {interface: can0}\n"
      "  cameras:\n"
      "    - {name: left, backend: v4l2, device: /dev/video0, width: 640, height: 480}\n"
      "    - {name: right, backend: v4l2, device: /dev/video1, width: 640, height: 480}\n",
      "rmp.yaml");
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(c->backend, Backend::kHardware);
  EXPECT_EQ(c->can_interface, "can0");
  ASSERT_EQ(c->cameras.size(), 2u);
  EXPECT_EQ(c->cameras[1].device, "/dev/video1");
}

TEST(RmpConfigTest, ReadsSectionsWithUnits) {
  auto c = ParseRmpConfig(
      "planner: {cruise_speed_mps: 0.8, max_yaw_rate_rps: 1.2}\n"
      "control: {rate_hz: 25, max_perception_age_s: 0.15}\n"
      "rig:\n"
      "  left: {fx_px: 300, pitch_down_deg: 50}\n"
      "sim:\n"
      "  camera_rate_hz: 10\n"
      "  faults: {frozen_camera: left, frozen_from_s: 2, frozen_to_s: 4, covered_m: [[1, 2]], stamp_glitch_at_s: 3,\n"
      "           stamp_glitch_s: 0.5}\n",
      "c.yaml");
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_DOUBLE_EQ(c->planner.cruise_speed_mps, 0.8);
  EXPECT_DOUBLE_EQ(c->driver.command_rate_hz, 25.0);
  EXPECT_DOUBLE_EQ(c->planner.control_period_s, 0.04);
  EXPECT_DOUBLE_EQ(c->driver.max_input_age_s, 0.15);
  EXPECT_DOUBLE_EQ(c->rig.left.intrinsics.fx(), 300.0);
  EXPECT_DOUBLE_EQ(c->rig.right.intrinsics.fx(), 320.0);
  EXPECT_EQ(c->sim.faults.frozen_camera, "left");
  EXPECT_EQ(c->sim.faults.stamp_glitch_at_s, 3.0);
  EXPECT_EQ(c->sim.faults.stamp_glitch_s, 0.5);
  ASSERT_EQ(c->sim.faults.covered_m.size(), 1u);
}

// rig: {width_px: 2147483647, height_px: 2147483647} was read, and `idi-rmp sim` then allocated 23 GB
// for the cameras' ground footprints: the sizes are bounded by what the twin's renderer draws.
TEST(RmpConfigTest, RefusesImageSizesTheRendererCannotDraw) {
  for (const auto& [text, key] : std::vector<std::pair<std::string, std::string>>{
           {"rig: {width_px: 2147483647, height_px: 2147483647}\n", "rig.width_px = 2147483647"},
           {"rig:\n  width_px: 640\n  height_px: 16385\n", "rig.height_px = 16385"},
           {"rig: {width_px: 99999999999}\n", "rig.width_px = 99999999999"},
           {"rig: {width_px: 0}\n", "rig.width_px = 0"},
           {"rig: {height_px: -480}\n", "rig.height_px = -480"}}) {
    const auto r = ParseRmpConfig(text, "c.yaml");
    ASSERT_FALSE(r.ok()) << text;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("c.yaml:"), std::string::npos) << text << ": " << r.status().message();
    EXPECT_NE(r.status().message().find(key), std::string::npos) << text << ": " << r.status().message();
    EXPECT_NE(r.status().message().find("16384"), std::string::npos) << text << ": " << r.status().message();
  }
  // Each side within its bound, the image not: 268 Mpx, 2 GB per camera in the undistortion map.
  const auto square = ParseRmpConfig("rig:\n  width_px: 16384\n  height_px: 16384\n", "c.yaml");
  ASSERT_FALSE(square.ok());
  EXPECT_EQ(square.status().code(), StatusCode::kInvalidArgument);
  const std::string m = square.status().message();
  EXPECT_NE(m.find("c.yaml:"), std::string::npos) << m;
  EXPECT_NE(m.find("rig.width_px"), std::string::npos) << m;
  EXPECT_NE(m.find("rig.height_px"), std::string::npos) << m;
  EXPECT_NE(m.find("16777216"), std::string::npos) << m;
  EXPECT_TRUE(ParseRmpConfig("rig: {width_px: 4096, height_px: 4096}\n", "c.yaml").ok()) << "16 Mpx, the limit";
  const auto largest = ParseRmpConfig("rig: {width_px: 16384, height_px: 16}\n", "c.yaml");
  ASSERT_TRUE(largest.ok()) << largest.status().ToString();
  EXPECT_EQ(largest->rig.right.intrinsics.width, 16384);
  EXPECT_EQ(largest->rig.right.intrinsics.height, 16);
}

TEST(RmpConfigTest, RefusesMistakesNamingFileLineAndKey) {
  auto unknown = ParseRmpConfig("planner:\n  cruise_speed: 0.5\n", "c.yaml");
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.status().message().find("c.yaml:2"), std::string::npos);
  EXPECT_NE(unknown.status().message().find("planner.cruise_speed"), std::string::npos);
  auto backend = ParseRmpConfig("backend: simulator\n", "c.yaml");
  ASSERT_FALSE(backend.ok());
  EXPECT_NE(backend.status().message().find("backend"), std::string::npos);
  auto rate = ParseRmpConfig("control: {rate_hz: 2}\n", "c.yaml");
  ASSERT_FALSE(rate.ok());
  EXPECT_NE(rate.status().message().find("rate_hz"), std::string::npos);
  auto number = ParseRmpConfig("planner: {max_speed_mps: fast}\n", "c.yaml");
  ASSERT_FALSE(number.ok());
  EXPECT_NE(number.status().message().find("planner.max_speed_mps"), std::string::npos);
  auto cams = ParseRmpConfig("backend: hardware\nhardware: {cameras: [{name: left, device: /dev/video0}]}\n", "c.yaml");
  ASSERT_FALSE(cams.ok());
  EXPECT_NE(cams.status().message().find("right"), std::string::npos);
  EXPECT_FALSE(ParseRmpConfig("sim: {faults: {frozen_camera: middle}}\n", "c.yaml").ok());
  // A key given twice: yaml-cpp keeps both, and the second silently replaced the first.
  auto twice = ParseRmpConfig("planner:\n  max_speed_mps: 0.4\n  max_speed_mps: 4.0\n", "c.yaml");
  ASSERT_FALSE(twice.ok());
  EXPECT_NE(twice.status().message().find("c.yaml:3: key 'planner.max_speed_mps' given twice"), std::string::npos)
      << twice.status().message();
  // A lens model that folds back before the image corners (k1 -0.3 at fx 320: the corners are at radius
  // 1.25, the model gives no ray beyond 0.70): refused when the file is read, naming the camera.
  auto folded = ParseRmpConfig("rig:\n  right: {k1: -0.3}\n", "c.yaml");
  ASSERT_FALSE(folded.ok());
  EXPECT_NE(folded.status().message().find("right camera"), std::string::npos) << folded.status().message();
  EXPECT_NE(folded.status().message().find("cannot be undistorted"), std::string::npos) << folded.status().message();
  EXPECT_TRUE(ParseRmpConfig("rig:\n  right: {k1: -0.05}\n", "c.yaml").ok());
  // Values and keys of the wrong shape: an error naming the file (never a YAML exception).
  for (const char* text : {"[x]: 1\n", "planner: {[a]: 1}\n", "backend: [sim]\n", "control: {rate_hz: [1, 2]}\n"}) {
    const auto r = ParseRmpConfig(text, "c.yaml");
    ASSERT_FALSE(r.ok()) << text;
    EXPECT_NE(r.status().message().find("c.yaml"), std::string::npos) << text << ": " << r.status().message();
  }
  // Fault times the twin's 64-bit nanosecond clock cannot hold, or spans that end before they begin.
  for (const char* text : {"sim: {faults: {rmp_silent_from_s: 1.0e10}}\n",
                           "sim: {faults: {bus_off_duration_s: 1.0e12}}\n",
                           "sim: {faults: {rmp_silent_from_s: 3, rmp_silent_to_s: 2}}\n",
                           "sim: {faults: {integrators_missing_from_s: 3, integrators_missing_to_s: 3}}\n",
                           "sim: {faults: {stamp_glitch_at_s: 1, stamp_glitch_s: -2}}\n",
                           "sim: {faults: {stamp_glitch_at_s: 1, stamp_glitch_s: 1.0e9}}\n"}) {
    const auto r = ParseRmpConfig(text, "c.yaml");
    ASSERT_FALSE(r.ok()) << text;
    EXPECT_NE(r.status().message().find("sim faults"), std::string::npos) << text << ": " << r.status().message();
  }
  // Ages that would let the vehicle drive on stale data are refused, naming the key.
  for (const auto& [text, key] : std::vector<std::pair<std::string, std::string>>{
           {"control: {max_perception_age_s: 5}\n", "max_perception_age_s"},
           {"control: {max_odometry_age_s: 2}\n", "max_odometry_age_s"},
           {"control: {track_lost_s: 30}\n", "track_lost_s"},
           {"control: {status_timeout_s: 3}\n", "status_timeout_s"}}) {
    const auto r = ParseRmpConfig(text, "c.yaml");
    ASSERT_FALSE(r.ok()) << text;
    EXPECT_NE(r.status().message().find(key), std::string::npos) << text << ": " << r.status().message();
  }
  EXPECT_TRUE(ParseRmpConfig("control: {max_perception_age_s: 0.5, status_timeout_s: 0.3}\n", "c.yaml").ok());
  // 19 mm tape: the width tolerance follows the width (it is not a key of the file).
  const auto narrow = ParseRmpConfig("tape: {width_m: 0.019}\n", "c.yaml");
  ASSERT_TRUE(narrow.ok()) << narrow.status().ToString();
  EXPECT_LE(narrow->perception.tape.width_tolerance_m, 0.5 * 0.019);
  EXPECT_EQ(LoadRmpConfig("/nonexistent/rmp.yaml").status().code(), StatusCode::kNotFound);
}

// Fault values the twin cannot apply were taken silently: a cover to infinity, a battery that "drops" by
// a negative voltage or by more than it holds.
TEST(RmpConfigTest, RefusesFaultValuesTheTwinCannotApplyNamingTheLine) {
  for (const auto& [text, where] : std::vector<std::pair<std::string, std::string>>{
           {"sim:\n  faults:\n    covered_m: [[0.3, .inf]]\n", "c.yaml:3: sim.faults.covered_m[0]"},
           {"sim:\n  faults:\n    battery_drop_v: -5\n", "c.yaml:3: sim.faults.battery_drop_v = -5"},
           {"sim:\n  faults:\n    battery_drop_v: 1000\n", "c.yaml:3: sim.faults.battery_drop_v = 1000"},
           // Just above the bound: shown as given, not rounded onto the bound ("76 must be in [0, 76]").
           {"sim:\n  faults:\n    battery_drop_v: 76.0000001\n", "c.yaml:3: sim.faults.battery_drop_v = 76.0000001"},
           {"sim:\n  faults:\n    battery_drop_v: .nan\n", "c.yaml:3: sim.faults.battery_drop_v"}}) {
    const auto r = ParseRmpConfig(text, "c.yaml");
    if (r.ok()) {
      ADD_FAILURE() << "accepted: " << text;
      continue;
    }
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument) << text;
    EXPECT_NE(r.status().message().find(where), std::string::npos) << text << ": " << r.status().message();
  }
  const auto fine =
      ParseRmpConfig("sim: {faults: {battery_drop_at_s: 1, battery_drop_v: 10, covered_m: [[0.3, 2]]}}\n", "c.yaml");
  ASSERT_TRUE(fine.ok()) << fine.status().ToString();
  EXPECT_EQ(fine->sim.faults.battery_drop_v, 10.0);
}

// hardware.cameras with the given entries (and the CAN interface the hardware backend needs).
Result<RmpConfig> HardwareCameras(const std::string& left, const std::string& right) {
  return ParseRmpConfig("backend: hardware\nhardware:\n  cameras:\n    - " + left + "\n    - " + right + "\n",
                        "c.yaml");
}

TEST(RmpConfigTest, CameraBackendsAreCheckedAtLoad) {
  auto unknown = HardwareCameras("{name: left, backend: gstreamer, device: x}", "{name: right, device: /dev/video1}");
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.status().message().find("backend 'gstreamer' must be v4l2 or libcamera"), std::string::npos)
      << unknown.status().message();
  auto same = HardwareCameras("{name: left, device: /dev/video0}", "{name: right, device: /dev/video0}");
  ASSERT_FALSE(same.ok());
  EXPECT_NE(same.status().message().find("same v4l2 device '/dev/video0' as camera 'left'"), std::string::npos)
      << same.status().message();
  auto size = HardwareCameras("{name: left, device: /dev/video0, width: 0}", "{name: right, device: /dev/video1}");
  ASSERT_FALSE(size.ok());
  EXPECT_NE(size.status().message().find("camera 'left': width and height"), std::string::npos);
  // A size other than the rig's calibration (640 x 480 by default) would fail on every pair.
  auto hd = HardwareCameras("{name: left, device: /dev/video0}",
                            "{name: right, device: /dev/video1, width: 1280, height: 720}");
  ASSERT_FALSE(hd.ok());
  EXPECT_NE(hd.status().message().find("camera 'right': 1280x720 differs from the rig's calibration, 640x480"),
            std::string::npos)
      << hd.status().message();
  auto no_device = HardwareCameras("{name: left, device: /dev/video0}", "{name: right, backend: v4l2}");
  ASSERT_FALSE(no_device.ok());
  EXPECT_NE(no_device.status().message().find("camera 'right' has no device"), std::string::npos);
}

TEST(RmpConfigTest, LibcameraCamerasByIdOrIndexWhenBuiltWithIt) {
  auto c = HardwareCameras("{name: left, backend: libcamera, device: 0}",
                           "{name: right, backend: libcamera, device: '/base/soc/i2c0mux/i2c@1/imx219@10'}");
  if (LibcameraBuilt()) {
    ASSERT_TRUE(c.ok()) << c.status().ToString();
    ASSERT_EQ(c->cameras.size(), 2u);
    EXPECT_EQ(c->cameras[0].backend, "libcamera");
    EXPECT_EQ(c->cameras[0].device, "0");
    EXPECT_EQ(c->cameras[1].device, "/base/soc/i2c0mux/i2c@1/imx219@10");
    auto no_id = HardwareCameras("{name: left, backend: libcamera}", "{name: right, device: /dev/video1}");
    ASSERT_FALSE(no_id.ok());
    EXPECT_NE(no_id.status().message().find("libcamera camera id"), std::string::npos) << no_id.status().message();
    // The same index twice is one camera; v4l2 and libcamera names never collide.
    EXPECT_FALSE(
        HardwareCameras("{name: left, backend: libcamera, device: 0}", "{name: right, backend: libcamera, device: 0}")
            .ok());
    EXPECT_TRUE(
        HardwareCameras("{name: left, backend: libcamera, device: 0}", "{name: right, device: /dev/video0}").ok());
  } else {
    ASSERT_FALSE(c.ok());
    EXPECT_NE(c.status().message().find("built without libcamera"), std::string::npos) << c.status().message();
    EXPECT_NE(c.status().message().find("camera 'left'"), std::string::npos) << c.status().message();
  }
}

}  // namespace
}  // namespace idi::rmp
