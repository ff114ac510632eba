#include "shared/drivers/mrpt/mrpt_camera.h"

#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/hwdrivers/CCameraSensor.h>
#include <mrpt/obs/CObservationImage.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <sstream>

namespace idi::drivers {

struct MrptCamera::Impl {
  mrpt::hwdrivers::CCameraSensor sensor;
  bool open = false;
};

MrptCamera::MrptCamera(MrptCameraOptions options, hal::Clock* clock)
    : options_(std::move(options)), clock_(clock), impl_(std::make_unique<Impl>()) {}

MrptCamera::~MrptCamera() { (void)Stop(); }

Status MrptCamera::Start(const hal::CameraSettings& settings) {
  if (impl_->open) return Status::Ok();
  settings_ = settings;
  std::ostringstream ini;
  ini << "[CAMERA]\n";
  ini << "grabber_type = " << options_.grabber_type << "\n";
  ini << "capture_grayscale = " << (settings.gray ? 1 : 0) << "\n";
  ini << "preview_decimation = 0\n";
  if (options_.grabber_type == "dc1394") {
    ini << "dc1394_frame_width = " << settings.width << "\n";
    ini << "dc1394_frame_height = " << settings.height << "\n";
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
    mrpt::config::CConfigFileMemory cfg(ini.str());
    impl_->sensor.loadConfig(cfg, "CAMERA");
    impl_->sensor.initialize();
  } catch (const std::exception& e) {
    return DeviceError(options_.name + " (MRPT " + options_.grabber_type + "): cannot open: " + e.what());
  }
  impl_->open = true;
  return Status::Ok();
}

Status MrptCamera::Stop() {
  if (!impl_ || !impl_->open) return Status::Ok();
  try {
    impl_->sensor.close();
  } catch (const std::exception& e) {
    impl_->open = false;
    return DeviceError(options_.name + ": close failed: " + e.what());
  }
  impl_->open = false;
  return Status::Ok();
}

Result<hal::Image> MrptCamera::Grab(std::chrono::milliseconds /*timeout*/) {
  if (!impl_->open) return FailedPrecondition(options_.name + ": not started");
  mrpt::obs::CObservation::Ptr obs;
  try {
    obs = impl_->sensor.getNextFrame();
  } catch (const std::exception& e) {
    return DeviceError(options_.name + ": grab failed: " + e.what());
  }
  if (!obs) return DeviceError(options_.name + ": no frame (end of stream or camera gone)");
  const auto img = std::dynamic_pointer_cast<mrpt::obs::CObservationImage>(obs);
  if (!img) return DeviceError(options_.name + ": MRPT delivered a " + std::string(obs->GetRuntimeClass()->className) +
                               ", expected an image");
  hal::Image out;
  out.timestamp_ns = clock_->NowNs();
  out.sequence = ++sequence_;
  out.camera = options_.name;
  cv::Mat m = img->image.asCvMat<cv::Mat>(mrpt::img::DEEP_COPY);
  if (m.empty()) return DeviceError(options_.name + ": empty image");
  if (settings_.gray && m.channels() == 3) {
    cv::cvtColor(m, out.pixels, cv::COLOR_BGR2GRAY);
  } else {
    out.pixels = m;
  }
  return out;
}

Status MrptCamera::SetExposure(double exposure_us) {
  if (options_.grabber_type != "dc1394") {
    return FailedPrecondition(options_.name + ": exposure control needs the dc1394 grabber");
  }
  if (impl_->open) return FailedPrecondition(options_.name + ": set the exposure before Start");
  if (!(exposure_us > 0) || !std::isfinite(exposure_us)) return InvalidArgument(options_.name + ": bad exposure");
  // IIDC shutter units are camera specific; the A602fc counts 20 us steps.
  options_.settings["dc1394_shutter"] = std::to_string(static_cast<long>(std::lround(exposure_us / 20.0)));
  options_.settings["dc1394_shutter_mode"] = "0";
  return Status::Ok();
}

}  // namespace idi::drivers
