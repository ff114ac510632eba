// The vehicle's frame source: a camera that fails or stalls is restarted (not more often than the
// restart interval); a healthy one is left alone.
#include "rmp/app/camera_frames.h"

#include <gtest/gtest.h>

#include <deque>

namespace idi::rmp {
namespace {

constexpr int64_t kMs = 1'000'000;

// A camera that delivers one frame per Grab while `healthy`, else fails as a camera that went away.
class FakeCamera final : public hal::CameraDevice {
 public:
  explicit FakeCamera(std::string name) : name_(std::move(name)) {}
  std::string name() const override { return name_; }
  Status Start(const hal::CameraSettings& s) override {
    ++starts;
    started_with = s;
    if (comes_back_on_start) healthy = true;
    return Status::Ok();
  }
  Status Stop() override {
    ++stops;
    return Status::Ok();
  }
  Result<hal::Image> Grab(std::chrono::milliseconds) override {
    if (!healthy) return DeviceError(name_ + ": the camera is gone; stop and start it");
    if (pending == 0) return Timeout("no frame");
    --pending;
    hal::Image img;
    img.camera = name_;
    img.sequence = sequence++;
    return img;
  }
  Status SetExposure(double) override { return Status::Ok(); }

  bool healthy = true, comes_back_on_start = false;
  int pending = 0, starts = 0, stops = 0;
  uint64_t sequence = 0;
  hal::CameraSettings started_with;

 private:
  std::string name_;
};

TEST(CameraFramesTest, AFailingCameraIsRestartedAndAHealthyOneIsNot) {
  auto left = std::make_unique<FakeCamera>("left");
  auto right = std::make_unique<FakeCamera>("right");
  FakeCamera* l = left.get();
  FakeCamera* r = right.get();
  hal::CameraSettings s;
  s.width = 320;
  s.height = 240;
  std::vector<CameraFrames::Camera> cams;
  cams.push_back({std::move(left), s});
  cams.push_back({std::move(right), s});
  CameraFrames frames(std::move(cams));
  int64_t t = 0;
  auto step = [&](int64_t ms) {
    std::size_t n = 0;
    for (int64_t end = t + ms * kMs; t < end; t += 20 * kMs) {
      l->pending = r->pending = 1;
      n += frames.Collect(t).value().size();
    }
    return n;
  };
  EXPECT_EQ(step(500), 50u);  // both deliver, 25 ticks each
  l->healthy = false;         // the left camera goes away
  step(900);
  EXPECT_EQ(l->starts, 0) << "restarted before restart_after_s";
  step(300);
  EXPECT_EQ(l->starts, 1);
  EXPECT_EQ(l->stops, 1);
  EXPECT_EQ(l->started_with.width, 320);
  step(1000);
  EXPECT_EQ(l->starts, 1) << "restarted again within restart_interval_s";
  step(1200);
  EXPECT_EQ(l->starts, 2);
  // It comes back on the next restart and is then left alone; the right one never was restarted.
  l->comes_back_on_start = true;
  step(2200);
  EXPECT_EQ(l->starts, 3);
  EXPECT_TRUE(l->healthy);
  EXPECT_EQ(step(2000), 200u);
  EXPECT_EQ(l->starts, 3);
  EXPECT_EQ(r->starts, 0);
  EXPECT_EQ(frames.restarts(), 3u);
}

// A stream that stalls without an error (Grab only times out) is restarted too.
TEST(CameraFramesTest, AStalledStreamIsRestarted) {
  auto cam = std::make_unique<FakeCamera>("left");
  FakeCamera* c = cam.get();
  std::vector<CameraFrames::Camera> cams;
  cams.push_back({std::move(cam), hal::CameraSettings{}});
  CameraFrames frames(std::move(cams));
  for (int64_t t = 0; t < 1500 * kMs; t += 20 * kMs) (void)frames.Collect(t);
  EXPECT_EQ(c->starts, 1);
}

}  // namespace
}  // namespace idi::rmp
