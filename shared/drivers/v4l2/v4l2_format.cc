#include "shared/drivers/v4l2/v4l2_format.h"

#include <linux/videodev2.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>

namespace idi::drivers {
namespace {

// Bytes per pixel of the first plane (NV12: the luma plane).
int V4l2FirstPlaneBytesPerPixel(uint32_t fourcc) {
  switch (fourcc) {
    case V4L2_PIX_FMT_GREY:
    case V4L2_PIX_FMT_NV12:
      return 1;
    case V4L2_PIX_FMT_YUYV:
    case V4L2_PIX_FMT_UYVY:
      return 2;
    case V4L2_PIX_FMT_RGB24:
    case V4L2_PIX_FMT_BGR24:
      return 3;
    default:
      return 0;
  }
}

}  // namespace

std::string FourccToString(uint32_t fourcc) {
  std::string s(4, ' ');
  for (int i = 0; i < 4; ++i) {
    const auto c = static_cast<char>((fourcc >> (8 * i)) & 0xFFu);
    s[static_cast<std::size_t>(i)] = (c >= 0x20 && c < 0x7F) ? c : '?';
  }
  return s;
}

bool IsConvertibleV4l2Format(uint32_t fourcc) { return V4l2FirstPlaneBytesPerPixel(fourcc) > 0; }

Result<uint32_t> ChooseV4l2Format(const std::vector<uint32_t>& offered, bool gray) {
  // Gray: a luma plane is a copy; colour: BGR24 is a copy, YUV needs one cvtColor.
  static constexpr std::array<uint32_t, 6> kGrayOrder = {V4L2_PIX_FMT_GREY,  V4L2_PIX_FMT_NV12,
                                                         V4L2_PIX_FMT_YUYV,  V4L2_PIX_FMT_UYVY,
                                                         V4L2_PIX_FMT_BGR24, V4L2_PIX_FMT_RGB24};
  static constexpr std::array<uint32_t, 6> kColorOrder = {V4L2_PIX_FMT_BGR24, V4L2_PIX_FMT_RGB24,
                                                          V4L2_PIX_FMT_YUYV,  V4L2_PIX_FMT_UYVY,
                                                          V4L2_PIX_FMT_NV12,  V4L2_PIX_FMT_GREY};
  for (uint32_t candidate : gray ? kGrayOrder : kColorOrder) {
    if (std::find(offered.begin(), offered.end(), candidate) != offered.end()) return candidate;
  }
  std::string names;
  for (uint32_t f : offered) names += (names.empty() ? "" : ", ") + FourccToString(f);
  return NotFound("no convertible pixel format among those offered (" + (names.empty() ? "none" : names) +
                  "); supported: GREY, NV12, YUYV, UYVY, BGR3, RGB3");
}

Result<std::size_t> V4l2FrameBytes(const V4l2FrameLayout& layout) {
  const int bpp = V4l2FirstPlaneBytesPerPixel(layout.fourcc);
  if (bpp == 0) return InvalidArgument("unsupported pixel format " + FourccToString(layout.fourcc));
  if (layout.width <= 0 || layout.height <= 0) {
    return InvalidArgument("frame size " + std::to_string(layout.width) + "x" + std::to_string(layout.height) +
                           " is empty");
  }
  const auto row_bytes = static_cast<std::size_t>(layout.width) * static_cast<std::size_t>(bpp);
  if (layout.bytes_per_line < row_bytes) {
    return InvalidArgument("bytes per line " + std::to_string(layout.bytes_per_line) + " < " +
                           std::to_string(row_bytes) + " for " + FourccToString(layout.fourcc) + " width " +
                           std::to_string(layout.width));
  }
  if (layout.fourcc == V4L2_PIX_FMT_NV12 && (layout.width % 2 != 0 || layout.height % 2 != 0)) {
    return InvalidArgument("NV12 needs an even frame size");
  }
  auto rows = static_cast<std::size_t>(layout.height);
  if (layout.fourcc == V4L2_PIX_FMT_NV12) rows += rows / 2;  // interleaved chroma rows follow luma
  return layout.bytes_per_line * (rows - 1) + row_bytes;
}

Result<cv::Mat> ConvertV4l2Frame(const V4l2FrameLayout& layout, const uint8_t* data, std::size_t bytes_used,
                                 bool gray) {
  IDI_ASSIGN_OR_RETURN(const std::size_t needed, V4l2FrameBytes(layout));
  if (data == nullptr || bytes_used < needed) {
    return DeviceError("truncated " + FourccToString(layout.fourcc) + " frame: " + std::to_string(bytes_used) +
                       " bytes, " + std::to_string(needed) + " needed for " + std::to_string(layout.width) +
                       "x" + std::to_string(layout.height));
  }
  const int w = layout.width;
  const int h = layout.height;
  const std::size_t step = layout.bytes_per_line;
  auto* bytes = const_cast<uint8_t*>(data);  // wrapped read-only: every path below copies
  cv::Mat out;
  switch (layout.fourcc) {
    case V4L2_PIX_FMT_GREY: {
      const cv::Mat src(h, w, CV_8UC1, bytes, step);
      if (gray) {
        out = src.clone();
      } else {
        cv::cvtColor(src, out, cv::COLOR_GRAY2BGR);
      }
      break;
    }
    case V4L2_PIX_FMT_YUYV:
    case V4L2_PIX_FMT_UYVY: {
      const bool yuyv = layout.fourcc == V4L2_PIX_FMT_YUYV;
      const cv::Mat src(h, w, CV_8UC2, bytes, step);
      if (gray) {
        // Luma is every other byte: the first of each pair in YUYV, the second in UYVY.
        out.create(h, w, CV_8UC1);
        const int luma = yuyv ? 0 : 1;
        for (int r = 0; r < h; ++r) {
          const uint8_t* in_row = src.ptr<uint8_t>(r);
          uint8_t* out_row = out.ptr<uint8_t>(r);
          for (int c = 0; c < w; ++c) out_row[c] = in_row[2 * c + luma];
        }
      } else {
        cv::cvtColor(src, out, yuyv ? cv::COLOR_YUV2BGR_YUYV : cv::COLOR_YUV2BGR_UYVY);
      }
      break;
    }
    case V4L2_PIX_FMT_NV12: {
      if (gray) {
        out = cv::Mat(h, w, CV_8UC1, bytes, step).clone();
      } else {
        cv::cvtColor(cv::Mat(h + h / 2, w, CV_8UC1, bytes, step), out, cv::COLOR_YUV2BGR_NV12);
      }
      break;
    }
    case V4L2_PIX_FMT_RGB24:
    case V4L2_PIX_FMT_BGR24: {
      const bool rgb = layout.fourcc == V4L2_PIX_FMT_RGB24;
      const cv::Mat src(h, w, CV_8UC3, bytes, step);
      if (gray) {
        cv::cvtColor(src, out, rgb ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY);
      } else if (rgb) {
        cv::cvtColor(src, out, cv::COLOR_RGB2BGR);
      } else {
        out = src.clone();
      }
      break;
    }
    default:
      return InvalidArgument("unsupported pixel format " + FourccToString(layout.fourcc));
  }
  return out;
}

}  // namespace idi::drivers
