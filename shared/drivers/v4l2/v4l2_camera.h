// A V4L2 capture device (USB/UVC cameras, CSI cameras behind a V4L2 driver, the kernel's vivid test
// driver) as a hal::CameraDevice: format negotiation, mmap streaming, frame timestamps on the
// monotonic clock, and recovery when the camera disappears and comes back.
//
// State machine: Stopped --Start--> Streaming --device fails--> Lost --reopened--> Streaming.
// A failure while streaming (the device unplugged or unbound: POLLERR, ENODEV, EIO) makes Grab return
// DeviceError once and close the device; the following Grab calls try to reopen it every
// `reconnect_interval` with the same settings, and the reopened device must be the same camera (same
// driver card name and bus info; if its node got a new number, the other /dev/video* nodes are
// searched). Counters tell how often each thing happened. Not thread-safe: one owner per camera.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "shared/hal/camera.h"
#include "shared/util/status.h"

namespace idi::drivers {

struct V4l2CameraOptions {
  std::string device;  // /dev/video0, or better a stable /dev/v4l/by-id/... or by-path link
  std::string name;    // the hal camera name put in every Image ("left", "right")
  int buffer_count = 4;           // mmap buffers the driver fills in turn (2..32)
  double frame_rate_hz = 0;       // 0 = the device's default; else asked with VIDIOC_S_PARM
  std::chrono::milliseconds reconnect_interval{500};  // between reopen attempts of a lost device
  Status Check() const;
};

enum class V4l2CameraState { kStopped, kStreaming, kLost };
const char* V4l2CameraStateName(V4l2CameraState state);

struct V4l2CameraCounters {
  uint64_t frames = 0;         // delivered by Grab
  uint64_t dropped = 0;        // gaps in the driver's frame sequence
  uint64_t corrupted = 0;      // buffers the driver flagged V4L2_BUF_FLAG_ERROR (skipped)
  uint64_t device_errors = 0;  // times the device failed while streaming
  uint64_t reconnects = 0;     // times a lost device was reopened
};

// What the device agreed to at the last Start or reconnect.
struct V4l2Negotiated {
  std::string path;      // the node actually opened
  std::string driver;    // e.g. "uvcvideo", "vivid"
  std::string card;      // the device's name
  std::string bus_info;  // e.g. "usb-0000:00:14.0-1", "platform:vivid-000"
  uint32_t fourcc = 0;
  int width = 0;
  int height = 0;
  uint32_t bytes_per_line = 0;
  int64_t frame_interval_ns = 0;  // 0 when the driver does not say
  int buffers = 0;
};

// A capture node found by ListV4l2CaptureDevices.
struct V4l2DeviceInfo {
  std::string path;
  std::string driver;
  std::string card;
  std::string bus_info;
};

// The /dev/video* nodes that can capture video with streaming I/O, sorted by path.
std::vector<V4l2DeviceInfo> ListV4l2CaptureDevices();

class V4l2Camera final : public hal::CameraDevice {
 public:
  explicit V4l2Camera(V4l2CameraOptions options);
  ~V4l2Camera() override;
  V4l2Camera(const V4l2Camera&) = delete;
  V4l2Camera& operator=(const V4l2Camera&) = delete;

  std::string name() const override { return options_.name; }
  // Opens the device, negotiates the pixel format for settings.width x height (InvalidArgument naming
  // the sizes the device offers if it cannot give exactly that), maps the buffers and starts streaming.
  Status Start(const hal::CameraSettings& settings) override;
  Status Stop() override;
  Result<hal::Image> Grab(std::chrono::milliseconds timeout) override;
  // Manual exposure through V4L2_CID_EXPOSURE_ABSOLUTE (100 µs units); 0 returns to automatic.
  // FailedPrecondition when the device has no such control. Before Start it is kept for Start.
  Status SetExposure(double exposure_us) override;

  V4l2CameraState state() const { return state_; }
  const V4l2CameraCounters& counters() const { return counters_; }
  const V4l2Negotiated& negotiated() const { return negotiated_; }

 private:
  struct Buffer {
    void* start = nullptr;
    std::size_t length = 0;
  };
  // Opens options_.device (or the node now holding the same camera) and starts streaming.
  Status OpenAndStream();
  Status OpenNode(const std::string& path);
  Status NegotiateFormat();
  Status MapBuffersAndStream();
  Status ApplyExposure();
  // Stops streaming (best effort), unmaps, closes.
  void CloseDevice();
  // Closes a failed device and enters kLost; returns the DeviceError to give the caller.
  Status LoseDevice(const std::string& what);
  Result<hal::Image> DequeueFrame(std::chrono::steady_clock::time_point deadline, std::chrono::milliseconds timeout);
  std::string Where() const;

  V4l2CameraOptions options_;
  hal::CameraSettings settings_;
  std::optional<double> exposure_us_;
  V4l2CameraState state_ = V4l2CameraState::kStopped;
  V4l2CameraCounters counters_;
  V4l2Negotiated negotiated_;
  // The camera's identity from the first successful open: a reconnect must find the same one.
  std::string identity_card_;
  std::string identity_bus_info_;
  int fd_ = -1;
  std::vector<Buffer> buffers_;
  bool streaming_ = false;
  bool timestamps_monotonic_ = false;
  bool timestamp_at_start_of_exposure_ = false;
  std::optional<uint32_t> last_sequence_;  // the driver's count in this stream
  uint64_t sequence_base_ = 0;             // added to it: delivered sequences go on across reconnects
  std::optional<uint64_t> last_delivered_;
  std::chrono::steady_clock::time_point next_reconnect_{};
  std::string lost_reason_;
};

}  // namespace idi::drivers
