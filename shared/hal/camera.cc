#include "shared/hal/camera.h"

#include <cmath>

namespace idi::hal {

Status CheckCameraSettings(const CameraSettings& settings, const std::string& where) {
  if (settings.width <= 0 || settings.height <= 0) {
    return InvalidArgument(where + ": frame size " + std::to_string(settings.width) + "x" +
                           std::to_string(settings.height) + " is empty");
  }
  if (!std::isfinite(settings.exposure_us) || settings.exposure_us < 0) {
    return InvalidArgument(where + ": exposure_us " + FormatNumber(settings.exposure_us) + " is invalid");
  }
  if (!std::isfinite(settings.gain_db)) return InvalidArgument(where + ": gain_db is not a finite number");
  return Status::Ok();
}

}  // namespace idi::hal
