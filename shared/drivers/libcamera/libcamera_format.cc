#include "shared/drivers/libcamera/libcamera_format.h"

#include <libcamera/formats.h>
#include <linux/videodev2.h>

#include <algorithm>
#include <array>

#include "shared/drivers/v4l2/v4l2_format.h"

namespace idi::drivers {
namespace {

namespace formats = libcamera::formats;

// Planar YUV whose first plane is full-resolution luma: gray is that plane alone.
bool LibcameraHasLumaPlane(uint32_t fourcc) {
  return fourcc == formats::NV12.fourcc() || fourcc == formats::NV21.fourcc() || fourcc == formats::YUV420.fourcc() ||
         fourcc == formats::YVU420.fourcc();
}

}  // namespace

Result<LibcameraConversion> LibcameraConversionFor(uint32_t fourcc, bool gray) {
  if (gray && LibcameraHasLumaPlane(fourcc)) return LibcameraConversion{V4L2_PIX_FMT_GREY, true};
  // DRM names packed RGB by the bits of a little-endian word: RGB888 is B, G, R in memory.
  if (fourcc == formats::R8.fourcc()) return LibcameraConversion{V4L2_PIX_FMT_GREY, false};
  if (fourcc == formats::YUYV.fourcc()) return LibcameraConversion{V4L2_PIX_FMT_YUYV, false};
  if (fourcc == formats::UYVY.fourcc()) return LibcameraConversion{V4L2_PIX_FMT_UYVY, false};
  if (fourcc == formats::NV12.fourcc()) return LibcameraConversion{V4L2_PIX_FMT_NV12, false};
  if (fourcc == formats::RGB888.fourcc()) return LibcameraConversion{V4L2_PIX_FMT_BGR24, false};
  if (fourcc == formats::BGR888.fourcc()) return LibcameraConversion{V4L2_PIX_FMT_RGB24, false};
  return InvalidArgument("libcamera format " + FourccToString(fourcc) + " cannot be converted to " +
                         (gray ? "gray" : "BGR"));
}

Result<uint32_t> ChooseLibcameraFormat(const std::vector<uint32_t>& offered, bool gray) {
  static constexpr std::array<libcamera::PixelFormat, 9> kGrayOrder = {formats::R8,
                                                                       formats::NV12,
                                                                       formats::NV21,
                                                                       formats::YUV420,
                                                                       formats::YVU420,
                                                                       formats::YUYV,
                                                                       formats::UYVY,
                                                                       formats::RGB888,
                                                                       formats::BGR888};
  static constexpr std::array<libcamera::PixelFormat, 6> kColorOrder = {
      formats::RGB888, formats::BGR888, formats::YUYV, formats::UYVY, formats::NV12, formats::R8};
  auto pick = [&offered](const auto& order) -> Result<uint32_t> {
    for (const libcamera::PixelFormat& candidate : order) {
      if (std::find(offered.begin(), offered.end(), candidate.fourcc()) != offered.end()) return candidate.fourcc();
    }
    return NotFound("");
  };
  auto chosen = gray ? pick(kGrayOrder) : pick(kColorOrder);
  if (chosen.ok()) return chosen;
  std::string names;
  for (uint32_t f : offered) names += (names.empty() ? "" : ", ") + FourccToString(f);
  return NotFound(
      "no convertible pixel format among those the stream offers (" + (names.empty() ? "none" : names) +
      "); supported for " +
      (gray ? "gray: R8, NV12, NV21, YU12, YV12, YUYV, UYVY, RG24, BG24" : "colour: RG24, BG24, YUYV, UYVY, NV12, R8"));
}

Result<cv::Mat> ConvertLibcameraFrame(const LibcameraFrameLayout& layout,
                                      const uint8_t* data,
                                      std::size_t bytes_used,
                                      bool gray) {
  IDI_ASSIGN_OR_RETURN(const LibcameraConversion conversion, LibcameraConversionFor(layout.fourcc, gray));
  const V4l2FrameLayout v4l2{conversion.v4l2_fourcc, layout.width, layout.height, layout.stride};
  return ConvertV4l2Frame(v4l2, data, bytes_used, gray);
}

}  // namespace idi::drivers
