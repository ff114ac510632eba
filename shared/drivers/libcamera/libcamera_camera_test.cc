// LibcameraCamera without a camera: option checks, and the errors a real camera manager gives on a
// machine with no camera (or without the one asked for). Streaming needs a camera and is not tested
// here.
#include "shared/drivers/libcamera/libcamera_camera.h"

#include <gtest/gtest.h>

#include <string>

namespace idi::drivers {
namespace {

LibcameraCameraOptions CameraNamed(const std::string& camera) {
  LibcameraCameraOptions options;
  options.camera = camera;
  options.name = "left";
  return options;
}

TEST(LibcameraCameraTest, OptionsAreChecked) {
  EXPECT_TRUE(CameraNamed("0").Check().ok());
  EXPECT_TRUE(CameraNamed("/base/soc/i2c0mux/i2c@1/imx219@10").Check().ok());
  EXPECT_FALSE(CameraNamed("").Check().ok());
  auto options = CameraNamed("0");
  options.name.clear();
  EXPECT_FALSE(options.Check().ok());
  options = CameraNamed("0");
  options.buffer_count = 1;
  EXPECT_NE(options.Check().message().find("buffer_count 1"), std::string::npos);
}

TEST(LibcameraCameraTest, BadSettingsAndGrabBeforeStart) {
  LibcameraCamera camera(CameraNamed("0"));
  auto grab = camera.Grab(std::chrono::milliseconds(10));
  ASSERT_FALSE(grab.ok());
  EXPECT_EQ(grab.status().code(), StatusCode::kFailedPrecondition);
  hal::CameraSettings settings;
  settings.width = 0;
  EXPECT_EQ(camera.Start(settings).code(), StatusCode::kInvalidArgument);
  settings = hal::CameraSettings{};
  settings.exposure_us = -1;
  EXPECT_EQ(camera.Start(settings).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(camera.SetExposure(-5).code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(camera.SetExposure(2000).ok());  // kept for Start
  EXPECT_TRUE(camera.Stop().ok());
}

// A camera manager starts on any machine; the cameras it lists decide what the errors say.
TEST(LibcameraCameraTest, MissingCameraIsNotFoundAndListsTheAvailableOnes) {
  auto ids = ListLibcameraCameras();
  ASSERT_TRUE(ids.ok()) << ids.status().ToString();
  LibcameraCamera camera(CameraNamed("idi-no-such-camera"));
  const Status s = camera.Start({});
  EXPECT_EQ(s.code(), StatusCode::kNotFound) << s.ToString();
  EXPECT_NE(s.message().find("camera left (libcamera idi-no-such-camera)"), std::string::npos) << s.message();
  if (ids->empty()) {
    EXPECT_NE(s.message().find("libcamera finds no cameras"), std::string::npos) << s.message();
  } else {
    EXPECT_NE(s.message().find("available: 0: '" + ids->front() + "'"), std::string::npos) << s.message();
  }
  EXPECT_FALSE(camera.streaming());
  EXPECT_EQ(camera.Grab(std::chrono::milliseconds(1)).status().code(), StatusCode::kFailedPrecondition);
}

TEST(LibcameraCameraTest, IndexPastTheListIsNotFound) {
  auto ids = ListLibcameraCameras();
  ASSERT_TRUE(ids.ok());
  LibcameraCamera camera(CameraNamed(std::to_string(ids->size())));
  EXPECT_EQ(camera.Start({}).code(), StatusCode::kNotFound);
}

// libcamera aborts on a second CameraManager in one process: two cameras (and the list) share one.
TEST(LibcameraCameraTest, TwoCamerasShareTheProcessCameraManager) {
  LibcameraCamera left(CameraNamed("idi-no-such-left"));
  LibcameraCamera right(CameraNamed("idi-no-such-right"));
  EXPECT_EQ(left.Start({}).code(), StatusCode::kNotFound);
  EXPECT_EQ(right.Start({}).code(), StatusCode::kNotFound);
  EXPECT_TRUE(ListLibcameraCameras().ok());
  EXPECT_TRUE(left.Stop().ok());
  EXPECT_TRUE(right.Stop().ok());
}

}  // namespace
}  // namespace idi::drivers
