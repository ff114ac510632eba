// The vehicle's cameras as the control loop's frame source: every frame each camera has ready, without
// waiting. A camera that keeps failing or stops delivering (a libcamera camera that went away, a V4L2
// stream that stalls without an error) is stopped and started again, at most every restart_interval_s,
// and its warnings are rate-limited so that a dead camera does not flood the journal at 50 Hz. Until
// it is back the loop's perception goes stale and the vehicle stands.
#pragma once

#include <memory>
#include <vector>

#include "rmp/app/control_loop.h"
#include "shared/hal/camera.h"

namespace idi::rmp {

struct CameraFramesOptions {
  double restart_after_s = 1.0;     // no frame for this long: restart the camera
  double restart_interval_s = 2.0;  // at most one restart per camera this often
  double warning_interval_s = 5.0;  // one warning per camera this often (the first at once)
};

class CameraFrames final : public FrameSource {
 public:
  struct Camera {
    std::unique_ptr<hal::CameraDevice> device;
    hal::CameraSettings settings;  // what it was started with, for a restart
  };
  CameraFrames(std::vector<Camera> cameras, CameraFramesOptions options = {});

  Result<std::vector<hal::Image>> Collect(int64_t now_ns) override;
  uint64_t restarts() const { return restarts_; }

 private:
  struct State {
    int64_t last_frame_ns = -1;  // or the first call's time
    int64_t next_restart_ns = 0;
    int64_t next_warning_ns = 0;
  };
  void Warn(std::size_t k, int64_t now_ns, const std::string& what);

  std::vector<Camera> cams_;
  std::vector<State> state_;
  CameraFramesOptions options_;
  uint64_t restarts_ = 0;
};

}  // namespace idi::rmp
