// V4l2Camera without a camera: configuration errors and devices that are missing or not V4L2.
// The streaming paths run against the kernel's vivid driver in v4l2_device_test.cc.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "shared/drivers/v4l2/v4l2_camera.h"

namespace idi::drivers {
namespace {

V4l2CameraOptions CameraOn(const std::string& device) {
  V4l2CameraOptions options;
  options.device = device;
  options.name = "left";
  return options;
}

TEST(V4l2CameraTest, OptionsAreChecked) {
  EXPECT_TRUE(CameraOn("/dev/video0").Check().ok());
  EXPECT_FALSE(CameraOn("").Check().ok());
  auto options = CameraOn("/dev/video0");
  options.name.clear();
  EXPECT_FALSE(options.Check().ok());
  options = CameraOn("/dev/video0");
  options.buffer_count = 1;
  EXPECT_NE(options.Check().message().find("buffer_count 1"), std::string::npos);
  options = CameraOn("/dev/video0");
  options.frame_rate_hz = -5;
  EXPECT_FALSE(options.Check().ok());
}

TEST(V4l2CameraTest, MissingDeviceIsNotFoundAndNamed) {
  V4l2Camera camera(CameraOn("/dev/idi-no-such-video"));
  Status s = camera.Start({});
  EXPECT_EQ(s.code(), StatusCode::kNotFound);
  EXPECT_NE(s.message().find("camera left (/dev/idi-no-such-video)"), std::string::npos) << s.message();
  EXPECT_EQ(camera.state(), V4l2CameraState::kStopped);
}

TEST(V4l2CameraTest, NonV4l2DevicesAreRefused) {
  V4l2Camera null_device(CameraOn("/dev/null"));
  Status s = null_device.Start({});
  EXPECT_EQ(s.code(), StatusCode::kDeviceError);
  EXPECT_NE(s.message().find("VIDIOC_QUERYCAP"), std::string::npos) << s.message();

  const std::string file = ::testing::TempDir() + "/v4l2_not_a_device";
  std::ofstream(file) << "frames\n";
  V4l2Camera regular_file(CameraOn(file));
  s = regular_file.Start({});
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("not a character device"), std::string::npos) << s.message();
}

TEST(V4l2CameraTest, BadSettingsAndGrabBeforeStart) {
  V4l2Camera camera(CameraOn("/dev/null"));
  auto grab = camera.Grab(std::chrono::milliseconds(10));
  ASSERT_FALSE(grab.ok());
  EXPECT_EQ(grab.status().code(), StatusCode::kFailedPrecondition);
  hal::CameraSettings settings;
  settings.gain_db = 6;
  EXPECT_EQ(camera.Start(settings).code(), StatusCode::kInvalidArgument);
  settings = {};
  settings.width = 0;
  EXPECT_EQ(camera.Start(settings).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(camera.SetExposure(-1).code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(camera.SetExposure(2000).ok());  // kept for Start
  EXPECT_TRUE(camera.Stop().ok());
}

TEST(V4l2CameraTest, ListingFindsOnlyCaptureNodes) {
  for (const auto& dev : ListV4l2CaptureDevices()) {
    EXPECT_EQ(dev.path.rfind("/dev/video", 0), 0u);
    EXPECT_FALSE(dev.driver.empty());
  }
}

}  // namespace
}  // namespace idi::drivers
