// Pixel formats of libcamera streams (DRM fourccs, libcamera/formats.h) and their conversion into the
// hal Image (CV_8UC1 gray or CV_8UC3 BGR). The conversion itself is the V4L2 backend's
// (v4l2_format.h): each libcamera format is mapped onto the V4L2 layout with the same bytes. Pure
// functions on byte buffers, so they are tested without a camera.
#pragma once

#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "shared/util/status.h"

namespace idi::drivers {

// How a frame in a libcamera format becomes a hal Image.
struct LibcameraConversion {
  uint32_t v4l2_fourcc = 0;      // the V4L2 format with the same memory layout, handed to ConvertV4l2Frame
  bool luma_plane_only = false;  // gray from planar YUV: only the first (luma) plane is read, as GREY
};

// The conversion for a format with no modifier, or InvalidArgument naming it when the backend cannot
// deliver that output from it (e.g. colour from NV21, anything from MJPEG or a Bayer format).
Result<LibcameraConversion> LibcameraConversionFor(uint32_t fourcc, bool gray);

// The best format among those a stream offers: the cheapest conversion to the wanted output (gray
// prefers R8, then a luma plane, then packed YUV; colour prefers RGB888, whose bytes are B, G, R).
// NotFound naming the offered formats when none can be converted.
Result<uint32_t> ChooseLibcameraFormat(const std::vector<uint32_t>& offered, bool gray);

// One frame's first plane as configured: `stride` bytes per line of the first plane.
struct LibcameraFrameLayout {
  uint32_t fourcc = 0;
  int width = 0;
  int height = 0;
  uint32_t stride = 0;
};

// Copies and converts a frame into a new CV_8UC1 or CV_8UC3 BGR image. `data` starts at the first
// plane; for colour from NV12 it must hold the chroma plane right after the luma rows (the caller
// checks the buffer's planes are laid out so). Errors as ConvertV4l2Frame's (DeviceError for a
// truncated frame, InvalidArgument for a layout that cannot be right).
Result<cv::Mat> ConvertLibcameraFrame(const LibcameraFrameLayout& layout,
                                      const uint8_t* data,
                                      std::size_t bytes_used,
                                      bool gray);

}  // namespace idi::drivers
