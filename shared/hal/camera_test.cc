#include "shared/hal/camera.h"

#include <gtest/gtest.h>

#include <cmath>

namespace idi::hal {
namespace {

// The settings every camera backend refuses, each named with the camera it was meant for.
TEST(CameraSettingsTest, EmptySizeBadExposureAndNonFiniteGainAreRefused) {
  EXPECT_TRUE(CheckCameraSettings({}, "cam").ok());
  CameraSettings s;
  s.height = 0;
  Status st = CheckCameraSettings(s, "camera left");
  EXPECT_EQ(st.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(st.message().find("camera left: frame size 640x0 is empty"), std::string::npos) << st.message();
  s = {};
  s.exposure_us = -1;
  EXPECT_EQ(CheckCameraSettings(s, "cam").code(), StatusCode::kInvalidArgument);
  s.exposure_us = std::nan("");
  EXPECT_NE(CheckCameraSettings(s, "cam").message().find("exposure_us"), std::string::npos);
  s = {};
  s.gain_db = INFINITY;
  EXPECT_NE(CheckCameraSettings(s, "cam").message().find("gain_db is not a finite number"), std::string::npos);
}

}  // namespace
}  // namespace idi::hal
