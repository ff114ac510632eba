// Cameras through MRPT's generic camera sensor (mrpt::hwdrivers::CCameraSensor): FireWire IIDC cameras
// such as the Basler A602fc of the Biclops head (grabber `dc1394`), plus anything else MRPT grabs from
// (`opencv`, `ffmpeg`, `image_dir`, and `rawlog`, which replays a recorded MRPT rawlog).
#pragma once

#include <chrono>
#include <map>
#include <memory>
#include <string>

#include "shared/hal/camera.h"
#include "shared/hal/clock.h"
#include "shared/util/timed_call.h"

namespace idi::drivers {

struct MrptCameraOptions {
  std::string name = "camera";
  std::string grabber_type = "dc1394";  // dc1394 | opencv | ffmpeg | image_dir | rawlog
  // Further CCameraSensor settings, written as `key = value` into its configuration section
  // (e.g. dc1394_camera_guid, dc1394_framerate, rawlog_file, image_dir_url).
  std::map<std::string, std::string> settings;
  // How long Start waits for the grabber to open and Stop for it to close: the driver's calls take no
  // timeout of their own and can block (a FireWire bus in trouble), and the caller may hold a lock an
  // operator's stop needs.
  std::chrono::milliseconds open_timeout{10'000};
  std::chrono::milliseconds close_timeout{3'000};
};

class MrptCamera final : public hal::CameraDevice {
 public:
  MrptCamera(MrptCameraOptions options, hal::Clock* clock);
  ~MrptCamera() override;
  std::string name() const override { return options_.name; }
  // DeviceError naming the camera and MRPT's reason when the grabber cannot be opened; Timeout naming it
  // when the open has not returned within open_timeout (it goes on on its own thread, with its own
  // grabber, which is released when it returns). While an open or close that timed out is still
  // blocked in the driver, Start opens no other grabber: Timeout saying so. InvalidArgument for
  // settings hal::CheckCameraSettings refuses. settings.exposure_us > 0 sets the shutter (SetExposure).
  Status Start(const hal::CameraSettings& settings) override;
  // Stop waits up to 2 s for a read in progress; a read still blocked then leaves its grabber open (it
  // cannot be closed under the read): DeviceError naming the camera, and the next Start opens a new one.
  // The close itself is waited for up to close_timeout (Timeout naming the camera; it goes on).
  Status Stop() override;
  // CCameraSensor's read takes no timeout and can block in the driver for ever (a camera unplugged
  // mid-frame), so it runs on its own thread (shared/util/timed_call.h): Grab returns Timeout naming the
  // camera when no frame came within `timeout`, and the read goes on. A frame that read brings before
  // the next Grab is old by then and is dropped, so Grab gives the next frame. Frames are timestamped
  // on `clock` at their arrival.
  Result<hal::Image> Grab(std::chrono::milliseconds timeout) override;
  // Only before Start. dc1394 only: the shutter in 20 us steps (the A602fc's), 20 us .. 81.9 ms
  // (OutOfRange outside). 0 (any grabber) leaves the shutter as the camera has it: MRPT does not touch
  // it, and an IIDC camera keeps a manual shutter until it is powered off.
  Status SetExposure(double exposure_us) override;

 private:
  struct Impl;
  class Reader;
  MrptCameraOptions options_;
  hal::Clock* clock_;
  hal::CameraSettings settings_;
  std::shared_ptr<Impl> impl_;  // shared with a read in progress
  std::unique_ptr<Reader> reader_;
  double exposure_us_ = 0;  // 0: the camera's own shutter
  // An open or close that outlasted its wait, still blocked in the driver (Start waits for it to end).
  std::unique_ptr<TimedCall<Status>> pending_;
  uint64_t sequence_ = 0;
};

}  // namespace idi::drivers
