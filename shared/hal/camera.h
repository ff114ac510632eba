// Camera devices: V4L2, libcamera, FireWire (MRPT), the simulation and log replay all deliver the
// same Image message. Algorithms see only these.
#pragma once

#include <opencv2/core.hpp>

#include <chrono>
#include <cstdint>
#include <string>

#include "shared/util/status.h"

namespace idi::hal {

struct Image {
  int64_t timestamp_ns = 0;  // exposure middle, on the device clock (see clock.h)
  // Frame counter from the device; gaps mean dropped frames. It goes on increasing across a reconnect
  // or restart of the same camera object, so (camera, sequence) names one frame.
  uint64_t sequence = 0;
  std::string camera;        // "left", "right", ...
  cv::Mat pixels;            // CV_8UC1 (gray) or CV_8UC3 (BGR)
};

struct CameraSettings {
  int width = 640;
  int height = 480;
  double exposure_us = 0;  // 0 = automatic / device default
  double gain_db = 0;
  bool gray = true;        // deliver CV_8UC1
};

// InvalidArgument naming `where` for an empty frame size, a negative or non-finite exposure or a
// non-finite gain: what every backend refuses before touching the device.
Status CheckCameraSettings(const CameraSettings& settings, const std::string& where);

class CameraDevice {
 public:
  virtual ~CameraDevice() = default;
  virtual std::string name() const = 0;
  virtual Status Start(const CameraSettings& settings) = 0;
  virtual Status Stop() = 0;
  // The next frame, waiting at most `timeout`. Timeout when no frame came; DeviceError when the device
  // failed (the caller may Stop and Start again to recover).
  virtual Result<Image> Grab(std::chrono::milliseconds timeout) = 0;
  // Short exposure for laser-spot images (§6.4.3); devices without control return FailedPrecondition.
  virtual Status SetExposure(double exposure_us) = 0;
};

}  // namespace idi::hal
