#include "rmp/app/camera_frames.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <string>

namespace idi::rmp {
namespace {
int64_t SecToNs(double s) { return static_cast<int64_t>(s * 1e9); }
}  // namespace

CameraFrames::CameraFrames(std::vector<Camera> cameras, CameraFramesOptions options)
    : cams_(std::move(cameras)), state_(cams_.size()), options_(options) {}

void CameraFrames::Warn(std::size_t k, int64_t now_ns, const std::string& what) {
  if (now_ns < state_[k].next_warning_ns) return;
  spdlog::warn("camera {}: {}", cams_[k].device->name(), what);
  state_[k].next_warning_ns = now_ns + SecToNs(options_.warning_interval_s);
}

Result<std::vector<hal::Image>> CameraFrames::Collect(int64_t now_ns) {
  std::vector<hal::Image> out;
  for (std::size_t k = 0; k < cams_.size(); ++k) {
    hal::CameraDevice& cam = *cams_[k].device;
    State& st = state_[k];
    if (st.last_frame_ns < 0) st.last_frame_ns = now_ns;
    for (int n = 0; n < 8; ++n) {  // drain what is queued, never block
      auto img = cam.Grab(std::chrono::milliseconds(0));
      if (!img.ok()) {
        if (img.status().code() != StatusCode::kTimeout) Warn(k, now_ns, img.status().ToString());
        break;
      }
      st.last_frame_ns = now_ns;
      out.push_back(std::move(*img));
    }
    const int64_t silent_ns = now_ns - st.last_frame_ns;
    if (silent_ns > SecToNs(options_.restart_after_s) && now_ns >= st.next_restart_ns) {
      st.next_restart_ns = now_ns + SecToNs(options_.restart_interval_s);
      ++restarts_;
      spdlog::warn(
          "camera {}: no frame for {:.1f} s; restarting it", cam.name(), static_cast<double>(silent_ns) * 1e-9);
      (void)cam.Stop();
      const Status started = cam.Start(cams_[k].settings);
      if (!started.ok()) Warn(k, now_ns, "restart failed: " + started.ToString());
    }
  }
  return out;
}

}  // namespace idi::rmp
