// Pixel formats of V4L2 capture devices and their conversion into the hal Image (CV_8UC1 gray or
// CV_8UC3 BGR). Pure functions on byte buffers, so they are tested without a device.
#pragma once

#include <opencv2/core.hpp>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "shared/util/status.h"

namespace idi::drivers {

// "YUYV" for V4L2_PIX_FMT_YUYV; non-printable bytes become '?'.
std::string FourccToString(uint32_t fourcc);

// Whether ConvertV4l2Frame handles this format: GREY, YUYV, UYVY, NV12, RGB24, BGR24.
bool IsConvertibleV4l2Format(uint32_t fourcc);

// The best format among those a device offers: the cheapest conversion to the wanted output (gray
// prefers GREY, then a luma plane; colour prefers BGR24). NotFound naming the offered formats when
// none can be converted (e.g. a camera that only gives MJPEG).
Result<uint32_t> ChooseV4l2Format(const std::vector<uint32_t>& offered, bool gray);

// One frame's memory layout as negotiated with VIDIOC_S_FMT.
struct V4l2FrameLayout {
  uint32_t fourcc = 0;
  int width = 0;
  int height = 0;
  uint32_t bytes_per_line = 0;  // of the first (or only) plane; >= width * bytes per pixel
};

// Bytes one frame needs with this layout (InvalidArgument for unknown formats or bad sizes).
Result<std::size_t> V4l2FrameBytes(const V4l2FrameLayout& layout);

// Copies and converts a frame into a new CV_8UC1 (gray) or CV_8UC3 BGR image. DeviceError when the
// buffer holds fewer bytes than the layout needs (a truncated frame), InvalidArgument for a layout
// that cannot be right (unknown format, zero size, lines shorter than the width).
Result<cv::Mat> ConvertV4l2Frame(const V4l2FrameLayout& layout, const uint8_t* data, std::size_t bytes_used,
                                 bool gray);

}  // namespace idi::drivers
