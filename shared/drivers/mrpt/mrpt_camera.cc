#include "shared/drivers/mrpt/mrpt_camera.h"

#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/hwdrivers/CCameraSensor.h>
#include <mrpt/obs/CObservationImage.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <utility>

#include "shared/util/timed_call.h"

namespace idi::drivers {

struct MrptCamera::Impl {
  mrpt::hwdrivers::CCameraSensor sensor;
  bool open = false;
};

// The grabber's reads on their own thread, one at a time; each holds the grabber (impl) it reads, and
// nothing else of the camera's (the camera may be gone when a blocked read returns).
class MrptCamera::Reader {
 public:
  // What one read of the grabber gave: a frame (with its arrival on the steady clock) or why not.
  struct Read {
    Status status = Status::Ok();
    cv::Mat pixels;
    std::chrono::steady_clock::time_point arrival;
  };

  Reader(std::shared_ptr<Impl> impl, std::string name, bool gray)
      : call_([impl = std::move(impl), name = std::move(name), gray] { return ReadFrame(*impl, name, gray); }) {}
  std::optional<Read> WaitNext(std::chrono::milliseconds timeout) { return call_.WaitNext(timeout); }
  bool Settle(std::chrono::milliseconds timeout) const { return call_.Settle(timeout); }

 private:
  static Read ReadFrame(Impl& impl, const std::string& name, bool gray) {
    Read out;
    try {
      const mrpt::obs::CObservation::Ptr obs = impl.sensor.getNextFrame();
      out.arrival = std::chrono::steady_clock::now();
      if (!obs) {
        out.status = DeviceError(name + ": no frame (end of stream or camera gone)");
        return out;
      }
      const auto img = std::dynamic_pointer_cast<mrpt::obs::CObservationImage>(obs);
      if (!img) {
        out.status = DeviceError(name + ": MRPT delivered a " + std::string(obs->GetRuntimeClass()->className) +
                                 ", expected an image");
        return out;
      }
      cv::Mat m = img->image.asCvMat<cv::Mat>(mrpt::img::DEEP_COPY);
      if (m.empty()) {
        out.status = DeviceError(name + ": empty image");
      } else if (gray && m.channels() == 3) {
        cv::cvtColor(m, out.pixels, cv::COLOR_BGR2GRAY);
      } else {
        out.pixels = m;
      }
    } catch (const std::exception& e) {
      out.status = DeviceError(name + ": grab failed: " + e.what());
      out.pixels.release();
    }
    return out;
  }

  TimedCall<Read> call_;
};

MrptCamera::MrptCamera(MrptCameraOptions options, hal::Clock* clock)
    : options_(std::move(options)), clock_(clock), impl_(std::make_shared<Impl>()) {}

MrptCamera::~MrptCamera() { (void)Stop(); }

Status MrptCamera::Start(const hal::CameraSettings& settings) {
  if (impl_->open) return Status::Ok();
  const std::string where = options_.name + " (MRPT " + options_.grabber_type + ")";
  IDI_RETURN_IF_ERROR(hal::CheckCameraSettings(settings, where));
  if (pending_) {
    if (!pending_->Settle(std::chrono::milliseconds(0))) {
      return Timeout(where +
                     ": an earlier open or close of the grabber is still blocked in the driver; not "
                     "opening another");
    }
    pending_.reset();  // it returned: its grabber is released
  }
  // A grabber left open under a blocked read (Stop) stays with that read; this Start opens a new one
  // (which the driver may refuse while the old one still holds the camera).
  if (reader_) {
    reader_.reset();
    impl_ = std::make_shared<Impl>();
  }
  if (settings.exposure_us > 0) IDI_RETURN_IF_ERROR(SetExposure(settings.exposure_us));
  settings_ = settings;
  std::ostringstream ini;
  ini << "[CAMERA]\n";
  ini << "grabber_type = " << options_.grabber_type << "\n";
  ini << "capture_grayscale = " << (settings.gray ? 1 : 0) << "\n";
  ini << "preview_decimation = 0\n";
  if (options_.grabber_type == "dc1394") {
    ini << "dc1394_frame_width = " << settings.width << "\n";
    ini << "dc1394_frame_height = " << settings.height << "\n";
    if (exposure_us_ > 0) {
      // IIDC shutter units are camera specific; the A602fc counts 20 us steps. Mode 0: manual.
      ini << "dc1394_shutter = " << std::lround(exposure_us_ / 20.0) << "\n";
      ini << "dc1394_shutter_mode = 0\n";
    }
  } else if (options_.grabber_type == "opencv") {
    ini << "cv_frame_width = " << settings.width << "\n";
    ini << "cv_frame_height = " << settings.height << "\n";
  }
  for (const auto& [key, value] : options_.settings) {
    if (key.find_first_of("=\n[]") != std::string::npos || value.find('\n') != std::string::npos) {
      return InvalidArgument(options_.name + ": bad MRPT camera setting '" + key + "'");
    }
    ini << key << " = " << value << "\n";
  }
  try {
    // On its own thread (see open_timeout); the call holds the grabber it opens.
    auto open = std::make_unique<TimedCall<Status>>([impl = impl_, config = ini.str(), where]() -> Status {
      try {
        mrpt::config::CConfigFileMemory cfg(config);
        impl->sensor.loadConfig(cfg, "CAMERA");
        impl->sensor.initialize();
        return Status::Ok();
      } catch (const std::exception& e) {
        return DeviceError(where + ": cannot open: " + e.what());
      } catch (...) {
        return DeviceError(where + ": cannot open: unknown exception");
      }
    });
    const std::optional<Status> opened = open->Wait(options_.open_timeout);
    if (!opened) {
      pending_ = std::move(open);
      impl_ = std::make_shared<Impl>();  // the blocked open keeps its grabber
      return Timeout(where + ": the grabber did not open within " + std::to_string(options_.open_timeout.count()) +
                     " ms (the open goes on in the driver)");
    }
    if (!opened->ok()) {
      impl_ = std::make_shared<Impl>();  // the next start begins with a fresh grabber
      return *opened;
    }
  } catch (const std::exception& e) {  // no thread for the open
    impl_ = std::make_shared<Impl>();
    return DeviceError(where + ": cannot open: " + e.what());
  }
  impl_->open = true;
  reader_ = std::make_unique<Reader>(impl_, options_.name, settings.gray);
  return Status::Ok();
}

Status MrptCamera::Stop() {
  if (!impl_ || !impl_->open) return Status::Ok();
  if (reader_ && !reader_->Settle(std::chrono::milliseconds(2000))) {
    impl_->open = false;  // Grab refuses from now on; the grabber stays with the blocked read
    return DeviceError(options_.name +
                       ": a frame read has been blocked in the driver for over 2 s; the grabber "
                       "is left open to it, and the next start opens another (which the driver may refuse "
                       "until that read returns)");
  }
  reader_.reset();
  impl_->open = false;
  // On its own thread (see close_timeout), holding the grabber; the next Start opens a fresh one.
  std::shared_ptr<Impl> impl = std::exchange(impl_, std::make_shared<Impl>());
  try {
    auto close = std::make_unique<TimedCall<Status>>([impl, name = options_.name]() -> Status {
      try {
        impl->sensor.close();
        return Status::Ok();
      } catch (const std::exception& e) {
        return DeviceError(name + ": close failed: " + e.what());
      } catch (...) {
        return DeviceError(name + ": close failed: unknown exception");
      }
    });
    impl.reset();  // the call holds it
    const std::optional<Status> closed = close->Wait(options_.close_timeout);
    if (!closed) {
      pending_ = std::move(close);
      return Timeout(options_.name + ": the grabber did not close within " +
                     std::to_string(options_.close_timeout.count()) + " ms (left to the driver)");
    }
    return *closed;
  } catch (const std::exception& e) {  // no thread for the close: the grabber goes with `impl`
    return DeviceError(options_.name + ": close failed: " + e.what());
  }
}

Result<hal::Image> MrptCamera::Grab(std::chrono::milliseconds timeout) {
  if (!impl_->open || !reader_) return FailedPrecondition(options_.name + ": not started");
  // The next frame: one that a read which outlasted an earlier grab brought before this call is old and
  // dropped (TimedCall::WaitNext).
  const std::optional<Reader::Read> r = reader_->WaitNext(std::max(timeout, std::chrono::milliseconds(0)));
  if (!r) {
    return Timeout(options_.name + ": no frame within " + std::to_string(timeout.count()) +
                   " ms (the read goes on in the driver)");
  }
  if (!r->status.ok()) return r->status;
  hal::Image out;
  // On `clock`, from its age on the steady clock (the read's thread never touches `clock`).
  const auto age = std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - r->arrival);
  out.timestamp_ns = clock_->NowNs() - age.count();
  out.sequence = ++sequence_;
  out.camera = options_.name;
  out.pixels = r->pixels;
  return out;
}

Status MrptCamera::SetExposure(double exposure_us) {
  if (impl_->open) return FailedPrecondition(options_.name + ": set the exposure before Start");
  if (!std::isfinite(exposure_us) || exposure_us < 0) {
    return InvalidArgument(options_.name + ": exposure " + FormatNumber(exposure_us) + " us is invalid");
  }
  if (exposure_us > 0 && options_.grabber_type != "dc1394") {
    return FailedPrecondition(options_.name + ": exposure control needs the dc1394 grabber");
  }
  // The shutter's 12 bits of 20 us steps.
  if (exposure_us > 0 && (exposure_us < 20.0 || exposure_us > 4095 * 20.0)) {
    return OutOfRange(options_.name + ": exposure " + FormatNumber(exposure_us) +
                      " us is outside the shutter's 20 .. 81900 us");
  }
  exposure_us_ = exposure_us;
  return Status::Ok();
}

}  // namespace idi::drivers
