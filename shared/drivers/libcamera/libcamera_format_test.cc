#include "shared/drivers/libcamera/libcamera_format.h"

#include <gtest/gtest.h>
#include <libcamera/formats.h>
#include <linux/videodev2.h>

#include <vector>

namespace idi::drivers {
namespace {

namespace formats = libcamera::formats;

TEST(LibcameraFormatTest, ChoosesCheapestConversion) {
  const std::vector<uint32_t> offered = {formats::MJPEG.fourcc(),
                                         formats::YUYV.fourcc(),
                                         formats::NV12.fourcc(),
                                         formats::BGR888.fourcc(),
                                         formats::RGB888.fourcc()};
  EXPECT_EQ(*ChooseLibcameraFormat(offered, /*gray=*/true), formats::NV12.fourcc());
  EXPECT_EQ(*ChooseLibcameraFormat(offered, /*gray=*/false), formats::RGB888.fourcc());
  EXPECT_EQ(*ChooseLibcameraFormat({formats::YUYV.fourcc(), formats::R8.fourcc()}, true), formats::R8.fourcc());
  // Planar YUV with the chroma planes swapped still has a luma plane for gray, but no colour path.
  EXPECT_EQ(*ChooseLibcameraFormat({formats::YVU420.fourcc()}, true), formats::YVU420.fourcc());
  EXPECT_FALSE(ChooseLibcameraFormat({formats::YVU420.fourcc()}, false).ok());
}

TEST(LibcameraFormatTest, NoConvertibleFormatNamesWhatWasOffered) {
  auto r = ChooseLibcameraFormat({formats::MJPEG.fourcc(), formats::SBGGR8.fourcc()}, true);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kNotFound);
  EXPECT_NE(r.status().message().find("MJPG, BA81"), std::string::npos) << r.status().message();
  EXPECT_FALSE(ChooseLibcameraFormat({}, false).ok());
}

TEST(LibcameraFormatTest, FormatsMapOntoTheV4l2LayoutWithTheSameBytes) {
  EXPECT_EQ(LibcameraConversionFor(formats::R8.fourcc(), true)->v4l2_fourcc, V4L2_PIX_FMT_GREY);
  // DRM's RGB888 is B, G, R in memory: V4L2's BGR24. BGR888 is R, G, B: RGB24.
  EXPECT_EQ(LibcameraConversionFor(formats::RGB888.fourcc(), false)->v4l2_fourcc, V4L2_PIX_FMT_BGR24);
  EXPECT_EQ(LibcameraConversionFor(formats::BGR888.fourcc(), false)->v4l2_fourcc, V4L2_PIX_FMT_RGB24);
  auto nv12_gray = LibcameraConversionFor(formats::NV12.fourcc(), true);
  ASSERT_TRUE(nv12_gray.ok());
  EXPECT_TRUE(nv12_gray->luma_plane_only);
  EXPECT_EQ(nv12_gray->v4l2_fourcc, V4L2_PIX_FMT_GREY);
  auto nv12_colour = LibcameraConversionFor(formats::NV12.fourcc(), false);
  ASSERT_TRUE(nv12_colour.ok());
  EXPECT_FALSE(nv12_colour->luma_plane_only);
  EXPECT_EQ(nv12_colour->v4l2_fourcc, V4L2_PIX_FMT_NV12);
  auto nv21_colour = LibcameraConversionFor(formats::NV21.fourcc(), false);
  ASSERT_FALSE(nv21_colour.ok());
  EXPECT_EQ(nv21_colour.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(nv21_colour.status().message().find("NV21"), std::string::npos);
}

TEST(LibcameraFormatTest, YuyvGrayIsTheLumaWithPaddingSkipped) {
  // 2x2 pixels, lines padded to 6 bytes (the padding 0xEE must not show up).
  const std::vector<uint8_t> yuyv = {10,
                                     128,
                                     20,
                                     128,
                                     0xEE,
                                     0xEE,  //
                                     30,
                                     128,
                                     40,
                                     128,
                                     0xEE,
                                     0xEE};
  auto gray = ConvertLibcameraFrame({formats::YUYV.fourcc(), 2, 2, 6}, yuyv.data(), yuyv.size(), true);
  ASSERT_TRUE(gray.ok()) << gray.status().ToString();
  ASSERT_EQ(gray->type(), CV_8UC1);
  EXPECT_EQ(gray->at<uint8_t>(0, 0), 10);
  EXPECT_EQ(gray->at<uint8_t>(0, 1), 20);
  EXPECT_EQ(gray->at<uint8_t>(1, 0), 30);
  EXPECT_EQ(gray->at<uint8_t>(1, 1), 40);
}

TEST(LibcameraFormatTest, Nv12GrayReadsOnlyTheLumaPlane) {
  // The caller hands just the luma plane (stride 4, width 3): no chroma bytes follow.
  const std::vector<uint8_t> luma = {1, 2, 3, 0xEE, 5, 6, 7, 0xEE};
  auto gray = ConvertLibcameraFrame({formats::NV12.fourcc(), 3, 2, 4}, luma.data(), luma.size(), true);
  ASSERT_TRUE(gray.ok()) << gray.status().ToString();
  ASSERT_EQ(gray->size(), cv::Size(3, 2));
  EXPECT_EQ(gray->at<uint8_t>(0, 2), 3);
  EXPECT_EQ(gray->at<uint8_t>(1, 0), 5);
  // YUV420 (I420) the same way.
  auto i420 = ConvertLibcameraFrame({formats::YUV420.fourcc(), 3, 2, 4}, luma.data(), luma.size(), true);
  ASSERT_TRUE(i420.ok());
  EXPECT_EQ(i420->at<uint8_t>(1, 2), 7);
}

TEST(LibcameraFormatTest, PackedRgbComesOutBgr) {
  const std::vector<uint8_t> bgr_bytes = {50, 100, 200};  // RGB888: B, G, R
  auto a = ConvertLibcameraFrame({formats::RGB888.fourcc(), 1, 1, 3}, bgr_bytes.data(), 3, false);
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a->at<cv::Vec3b>(0, 0), cv::Vec3b(50, 100, 200));
  auto b = ConvertLibcameraFrame({formats::BGR888.fourcc(), 1, 1, 3}, bgr_bytes.data(), 3, false);
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(b->at<cv::Vec3b>(0, 0), cv::Vec3b(200, 100, 50));
  auto gray = ConvertLibcameraFrame({formats::R8.fourcc(), 1, 1, 1}, bgr_bytes.data(), 1, false);
  ASSERT_TRUE(gray.ok());
  EXPECT_EQ(gray->at<cv::Vec3b>(0, 0), cv::Vec3b(50, 50, 50));
}

TEST(LibcameraFormatTest, TruncatedAndImpossibleFramesAreErrors) {
  const std::vector<uint8_t> bytes(7, 0);
  EXPECT_EQ(ConvertLibcameraFrame({formats::YUYV.fourcc(), 2, 2, 4}, bytes.data(), bytes.size(), true).status().code(),
            StatusCode::kDeviceError);
  EXPECT_EQ(ConvertLibcameraFrame({formats::YUYV.fourcc(), 2, 2, 3}, bytes.data(), bytes.size(), true).status().code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(ConvertLibcameraFrame({formats::MJPEG.fourcc(), 2, 2, 4}, bytes.data(), bytes.size(), true).status().code(),
            StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace idi::drivers
