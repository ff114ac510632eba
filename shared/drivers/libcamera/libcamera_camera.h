// A libcamera camera (CSI sensors behind an ISP, e.g. Raspberry Pi or Rockchip boards, and the UVC
// cameras libcamera also wraps) as a hal::CameraDevice. Optional: built only when pkg-config finds
// libcamera (IDI_WITH_LIBCAMERA in the top CMakeLists.txt).
//
// One viewfinder stream, configured to exactly settings.width x height in the cheapest format to
// convert (libcamera_format.h); buffers from FrameBufferAllocator, memory-mapped once; one request per
// buffer, queued at Start. libcamera completes requests on its own thread (requestCompleted); the
// completed ones wait in a queue until Grab converts the frame and queues the request again, so a
// caller that grabs too slowly makes libcamera drop frames (counted from the sequence gaps) rather
// than this class buffer them. Timestamps come from controls::SensorTimestamp.
//
// State machine: Stopped --Start--> Streaming --camera unplugged (disconnected signal)--> Lost.
// A lost camera makes Grab return DeviceError; Stop and Start again to reopen it. Grab and SetExposure
// are for one owner thread; only the completion queue is shared with libcamera's thread.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "shared/hal/camera.h"
#include "shared/util/status.h"

namespace libcamera {
class Camera;
class CameraManager;
class FrameBuffer;
class FrameBufferAllocator;
class Request;
class Stream;
}  // namespace libcamera

namespace idi::drivers {

struct LibcameraCameraOptions {
  // The camera: its libcamera id (as `cam --list` prints it, or as the "available" list of the
  // NotFound error shows it), or its index "0", "1", ... in libcamera's list. Ids are stable across
  // reboots; indices are not when cameras come and go.
  std::string camera;
  std::string name;          // the hal camera name put in every Image ("left", "right")
  int buffer_count = 4;      // frame buffers (and requests) in flight (2..32)
  double frame_rate_hz = 0;  // 0 = the camera's default; else fixed with controls::FrameDurationLimits
  Status Check() const;
};

struct LibcameraCameraCounters {
  uint64_t frames = 0;         // delivered by Grab
  uint64_t dropped = 0;        // gaps in the frame sequence
  uint64_t corrupted = 0;      // buffers libcamera flagged as failed (skipped)
  uint64_t device_errors = 0;  // times the camera was lost while streaming
};

// What the camera agreed to at the last Start.
struct LibcameraNegotiated {
  std::string id;       // libcamera's camera id
  uint32_t fourcc = 0;  // DRM fourcc of the stream
  int width = 0;
  int height = 0;
  uint32_t stride = 0;  // bytes per line of the first plane
  int buffers = 0;
};

// The ids of the cameras libcamera finds, in its order (an index in LibcameraCameraOptions::camera
// counts in this list). Empty when there are none; DeviceError when the camera manager cannot start.
Result<std::vector<std::string>> ListLibcameraCameras();

class LibcameraCamera final : public hal::CameraDevice {
 public:
  explicit LibcameraCamera(LibcameraCameraOptions options);
  ~LibcameraCamera() override;
  LibcameraCamera(const LibcameraCamera&) = delete;
  LibcameraCamera& operator=(const LibcameraCamera&) = delete;

  std::string name() const override { return options_.name; }
  // Finds and acquires the camera (NotFound when libcamera has no cameras, or none with that id or
  // index, listing the ones it has), configures the stream (InvalidArgument when the camera rejects
  // the configuration or would change the size or format), allocates and maps the buffers, starts
  // it with the exposure, gain and frame rate asked (FailedPrecondition when the camera has no such
  // control, OutOfRange outside its limits), and queues every request.
  Status Start(const hal::CameraSettings& settings) override;
  // Stops the camera (libcamera cancels what is in flight), frees the buffers and releases it.
  Status Stop() override;
  Result<hal::Image> Grab(std::chrono::milliseconds timeout) override;
  // Manual exposure through controls::ExposureTime (µs), automatic exposure off; 0 turns automatic
  // exposure back on. FailedPrecondition when the camera has no such control, OutOfRange outside its
  // limits. Applied from the next request queued; before Start it is kept for Start.
  Status SetExposure(double exposure_us) override;

  bool streaming() const { return started_; }
  const LibcameraCameraCounters& counters() const { return counters_; }
  const LibcameraNegotiated& negotiated() const { return negotiated_; }

 private:
  struct Mapping {
    void* start = nullptr;
    std::size_t length = 0;
  };
  // Where a buffer's frame is in memory (indexed by the FrameBuffer's cookie).
  struct BufferView {
    int fd = -1;  // of the first plane, for dma-buf sync
    const uint8_t* first_plane = nullptr;
    std::size_t length = 0;            // bytes readable from first_plane on
    bool chroma_follows_luma = false;  // NV12's second plane right after the first (colour needs it)
  };
  // Exposure and gain controls for the next request (or for start); unset ones are left alone.
  struct ExposureControls {
    std::optional<bool> ae_enable;
    std::optional<int32_t> exposure_time_us;
    std::optional<float> analogue_gain;
    bool empty() const { return !ae_enable && !exposure_time_us && !analogue_gain; }
  };
  Status FindCamera();
  Status Configure();
  Status AllocateAndMap();
  // The controls for this exposure and gain, checked against the camera's limits.
  // exposure_us < 0 leaves the exposure alone, 0 asks for automatic exposure.
  Result<ExposureControls> MakeExposureControls(double exposure_us, double gain_db) const;
  // Converts a completed request's frame (the caller queues the request again).
  Result<hal::Image> ConvertRequest(libcamera::Request* request);
  Status Requeue(libcamera::Request* request);
  // Run on libcamera's thread.
  void OnRequestCompleted(libcamera::Request* request);
  void OnDisconnected();
  void Teardown();
  std::string Where() const;

  LibcameraCameraOptions options_;
  hal::CameraSettings settings_;
  std::optional<double> exposure_us_;
  LibcameraCameraCounters counters_;
  LibcameraNegotiated negotiated_;
  bool luma_plane_only_ = false;
  std::optional<uint32_t> last_sequence_;  // libcamera's count since Start
  uint64_t sequence_base_ = 0;             // added to it: delivered sequences go on across restarts
  std::optional<uint64_t> last_delivered_;

  // Destroyed in reverse order: the camera and its buffers go before the manager.
  std::shared_ptr<libcamera::CameraManager> manager_;
  std::shared_ptr<libcamera::Camera> camera_;
  bool acquired_ = false;
  bool started_ = false;
  libcamera::Stream* stream_ = nullptr;
  std::unique_ptr<libcamera::FrameBufferAllocator> allocator_;
  std::vector<std::unique_ptr<libcamera::Request>> requests_;
  std::vector<Mapping> mappings_;
  std::vector<BufferView> views_;
  ExposureControls pending_controls_;  // applied with the next request queued

  std::mutex mutex_;  // guards completed_ and lost_, written on libcamera's thread
  std::condition_variable completed_cv_;
  std::deque<libcamera::Request*> completed_;
  bool lost_ = false;
  bool lost_reported_ = false;  // device_errors counts each loss once
};

}  // namespace idi::drivers
