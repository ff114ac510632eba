// V4l2Camera against real V4L2 capture devices. Runs when IDI_TEST_V4L2_DEVICES lists device nodes
// ("/dev/video0,/dev/video1"); skips otherwise. tools/kernel-test runs it in a VM with the kernel's
// vivid driver (two instances, one capture node each), where IDI_TEST_V4L2_UNBIND
// ("UNBIND_FILE:BIND_FILE:DEVICE", e.g. the vivid driver's sysfs unbind/bind files and "vivid.0")
// also lets the test take a camera away while it streams and bring it back.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "shared/drivers/v4l2/v4l2_camera.h"
#include "shared/hal/clock.h"

namespace idi::drivers {
namespace {

using std::chrono::milliseconds;
constexpr milliseconds kGrabTimeout{5000};  // vivid under qemu TCG gives ~5 frames/s

std::vector<std::string> SplitEnv(const char* name, char sep) {
  std::vector<std::string> parts;
  const char* value = std::getenv(name);
  if (value == nullptr) return parts;
  std::stringstream ss(value);
  for (std::string part; std::getline(ss, part, sep);) {
    if (!part.empty()) parts.push_back(part);
  }
  return parts;
}

class V4l2DeviceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    devices_ = SplitEnv("IDI_TEST_V4L2_DEVICES", ',');
    if (devices_.empty()) GTEST_SKIP() << "IDI_TEST_V4L2_DEVICES not set (tools/kernel-test sets it)";
    // Named devices must exist: a missing one is a failure, not a skip.
    for (const auto& d : devices_) ASSERT_TRUE(std::filesystem::exists(d)) << d << " is listed but missing";
  }
  static V4l2CameraOptions Options(const std::string& device, const std::string& name) {
    V4l2CameraOptions options;
    options.device = device;
    options.name = name;
    options.reconnect_interval = milliseconds(200);
    return options;
  }
  std::vector<std::string> devices_;
};

// Grabs `n` frames and checks what every frame must satisfy.
void ExpectFrames(V4l2Camera& camera, int n, int type) {
  int64_t last_t = 0;
  int64_t last_seq = -1;
  for (int i = 0; i < n; ++i) {
    auto image = camera.Grab(kGrabTimeout);
    ASSERT_TRUE(image.ok()) << image.status().ToString();
    EXPECT_EQ(image->camera, camera.name());
    EXPECT_EQ(image->pixels.cols, 640);
    EXPECT_EQ(image->pixels.rows, 480);
    EXPECT_EQ(image->pixels.type(), type);
    EXPECT_GT(static_cast<int64_t>(image->sequence), last_seq);
    EXPECT_GT(image->timestamp_ns, last_t);
    // Stamped on the monotonic clock (not the wall clock): close to now. vivid stamps the frame's
    // nominal time, which under an emulated CPU can run a fraction of a frame period ahead.
    const int64_t age_ns = hal::MonotonicClock().NowNs() - image->timestamp_ns;
    EXPECT_GT(age_ns, -hal::kNsPerSec);
    EXPECT_LT(age_ns, 10 * hal::kNsPerSec);
    // vivid draws a test pattern: the picture is not flat.
    cv::Scalar mean, stddev;
    cv::meanStdDev(image->pixels, mean, stddev);
    EXPECT_GT(stddev[0], 10.0);
    last_t = image->timestamp_ns;
    last_seq = static_cast<int64_t>(image->sequence);
  }
}

TEST_F(V4l2DeviceTest, NegotiatesGrayAndStreamsWithMmap) {
  V4l2Camera camera(Options(devices_[0], "left"));
  ASSERT_TRUE(camera.Start({}).ok());
  EXPECT_EQ(camera.state(), V4l2CameraState::kStreaming);
  EXPECT_EQ(camera.negotiated().width, 640);
  EXPECT_EQ(camera.negotiated().height, 480);
  EXPECT_GE(camera.negotiated().buffers, 2);
  EXPECT_FALSE(camera.negotiated().bus_info.empty());
  ExpectFrames(camera, 5, CV_8UC1);
  EXPECT_EQ(camera.counters().frames, 5u);
  EXPECT_TRUE(camera.Stop().ok());
  EXPECT_EQ(camera.state(), V4l2CameraState::kStopped);
  EXPECT_EQ(camera.Grab(milliseconds(10)).status().code(), StatusCode::kFailedPrecondition);
}

TEST_F(V4l2DeviceTest, NegotiatesColour) {
  V4l2Camera camera(Options(devices_[0], "left"));
  hal::CameraSettings settings;
  settings.gray = false;
  ASSERT_TRUE(camera.Start(settings).ok());
  ExpectFrames(camera, 3, CV_8UC3);
}

TEST_F(V4l2DeviceTest, RefusesASizeTheDeviceCannotGive) {
  V4l2Camera camera(Options(devices_[0], "left"));
  hal::CameraSettings settings;
  settings.width = 641;
  settings.height = 479;
  Status s = camera.Start(settings);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("cannot capture 641x479"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("640x480"), std::string::npos) << s.message();
  EXPECT_EQ(camera.state(), V4l2CameraState::kStopped);
  // The failed attempt left the device usable.
  ASSERT_TRUE(camera.Start({}).ok());
  ExpectFrames(camera, 1, CV_8UC1);
}

TEST_F(V4l2DeviceTest, TwoCamerasStreamTogether) {
  if (devices_.size() < 2) GTEST_SKIP() << "needs two devices";
  V4l2Camera left(Options(devices_[0], "left"));
  V4l2Camera right(Options(devices_[1], "right"));
  ASSERT_TRUE(left.Start({}).ok());
  ASSERT_TRUE(right.Start({}).ok());
  EXPECT_NE(left.negotiated().bus_info, right.negotiated().bus_info);
  // A second owner of a streaming device is refused with a clear error, not a crash.
  V4l2Camera intruder(Options(devices_[0], "intruder"));
  Status busy = intruder.Start({});
  EXPECT_EQ(busy.code(), StatusCode::kDeviceError);
  EXPECT_NE(busy.message().find("in use"), std::string::npos) << busy.message();
  for (int i = 0; i < 3; ++i) {
    ExpectFrames(left, 1, CV_8UC1);
    ExpectFrames(right, 1, CV_8UC1);
  }
}

TEST_F(V4l2DeviceTest, ExposureNeedsTheControl) {
  V4l2Camera camera(Options(devices_[0], "left"));
  ASSERT_TRUE(camera.Start({}).ok());
  // vivid has no V4L2_CID_EXPOSURE_ABSOLUTE: the backend says so instead of pretending.
  Status s = camera.SetExposure(2000);
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition) << s.ToString();
  ExpectFrames(camera, 1, CV_8UC1);  // still streaming
}

// Writes `device` to a sysfs driver file (unbind or bind).
void WriteSysfs(const std::string& file, const std::string& device) {
  std::ofstream out(file);
  out << device << std::flush;
  ASSERT_TRUE(out.good()) << "writing " << device << " to " << file;
}

TEST_F(V4l2DeviceTest, CameraThatGoesAwayIsReopenedWhenItComesBack) {
  const auto unbind = SplitEnv("IDI_TEST_V4L2_UNBIND", ':');
  if (unbind.size() != 3) GTEST_SKIP() << "IDI_TEST_V4L2_UNBIND not set (UNBIND_FILE:BIND_FILE:DEVICE)";
  const std::string& unbind_file = unbind[0];
  const std::string& bind_file = unbind[1];
  const std::string& device = unbind[2];
  // A capture node of that device, from sysfs: <driver>/<device>/video4linux/videoN (the last one).
  const auto v4l_dir = std::filesystem::path(unbind_file).parent_path() / device / "video4linux";
  std::error_code ec;
  std::string node;
  for (const auto& e : std::filesystem::directory_iterator(v4l_dir, ec)) {
    node = std::max(node, "/dev/" + e.path().filename().string());
  }
  ASSERT_FALSE(node.empty()) << "no capture node under " << v4l_dir << ": " << ec.message();

  V4l2Camera camera(Options(node, "right"));
  ASSERT_TRUE(camera.Start({}).ok());
  ExpectFrames(camera, 2, CV_8UC1);
  auto before = camera.Grab(kGrabTimeout);
  ASSERT_TRUE(before.ok()) << before.status().ToString();

  WriteSysfs(unbind_file, device);  // the camera disappears while streaming
  struct Rebind {  // bring it back even when an assertion below fails
    std::string file, device;
    bool done = false;
    ~Rebind() {
      if (!done) std::ofstream(file) << device << std::flush;
    }
  } rebind{bind_file, device};
  auto lost = camera.Grab(kGrabTimeout);
  // At most one frame may still have been in flight.
  if (lost.ok()) lost = camera.Grab(kGrabTimeout);
  ASSERT_FALSE(lost.ok());
  EXPECT_EQ(lost.status().code(), StatusCode::kDeviceError) << lost.status().ToString();
  EXPECT_EQ(camera.state(), V4l2CameraState::kLost);
  EXPECT_EQ(camera.counters().device_errors, 1u);
  // While it is gone, Grab keeps reporting it (and waits out its timeout rather than spinning).
  auto still_lost = camera.Grab(milliseconds(500));
  EXPECT_EQ(still_lost.status().code(), StatusCode::kDeviceError);
  EXPECT_EQ(camera.state(), V4l2CameraState::kLost);

  WriteSysfs(bind_file, device);
  rebind.done = true;
  Result<hal::Image> back = DeviceError("not yet");
  for (int attempt = 0; attempt < 20 && !back.ok(); ++attempt) back = camera.Grab(kGrabTimeout);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  // The driver counts from 0 again after STREAMON; the camera's sequence goes on (recordings name
  // frames by it).
  EXPECT_GT(back->sequence, before->sequence);
  EXPECT_EQ(camera.state(), V4l2CameraState::kStreaming);
  EXPECT_EQ(camera.counters().reconnects, 1u);
  ExpectFrames(camera, 2, CV_8UC1);
}

}  // namespace
}  // namespace idi::drivers
