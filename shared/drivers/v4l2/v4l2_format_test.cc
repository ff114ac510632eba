#include "shared/drivers/v4l2/v4l2_format.h"

#include <gtest/gtest.h>
#include <linux/videodev2.h>

#include <vector>

namespace idi::drivers {
namespace {

TEST(V4l2FormatTest, FourccNames) {
  EXPECT_EQ(FourccToString(V4L2_PIX_FMT_YUYV), "YUYV");
  EXPECT_EQ(FourccToString(V4L2_PIX_FMT_MJPEG), "MJPG");
  EXPECT_EQ(FourccToString(0x01020304u), "????");
}

TEST(V4l2FormatTest, ChoosesCheapestConversion) {
  const std::vector<uint32_t> offered = {V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_RGB24,
                                         V4L2_PIX_FMT_GREY};
  EXPECT_EQ(*ChooseV4l2Format(offered, /*gray=*/true), V4L2_PIX_FMT_GREY);
  EXPECT_EQ(*ChooseV4l2Format(offered, /*gray=*/false), V4L2_PIX_FMT_RGB24);
  EXPECT_EQ(*ChooseV4l2Format({V4L2_PIX_FMT_UYVY, V4L2_PIX_FMT_YUYV}, true), V4L2_PIX_FMT_YUYV);
}

TEST(V4l2FormatTest, NoConvertibleFormatNamesWhatWasOffered) {
  auto r = ChooseV4l2Format({V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_H264}, true);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kNotFound);
  EXPECT_NE(r.status().message().find("MJPG, H264"), std::string::npos) << r.status().message();
  EXPECT_FALSE(ChooseV4l2Format({}, false).ok());
}

TEST(V4l2FormatTest, FrameBytesHonourPaddingAndPlanes) {
  EXPECT_EQ(*V4l2FrameBytes({V4L2_PIX_FMT_YUYV, 4, 2, 8}), 16u);
  EXPECT_EQ(*V4l2FrameBytes({V4L2_PIX_FMT_YUYV, 4, 2, 12}), 20u);  // last line needs no padding
  EXPECT_EQ(*V4l2FrameBytes({V4L2_PIX_FMT_NV12, 4, 2, 4}), 12u);   // 2 luma rows + 1 chroma row
  EXPECT_EQ(V4l2FrameBytes({V4L2_PIX_FMT_YUYV, 4, 2, 7}).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(V4l2FrameBytes({V4L2_PIX_FMT_NV12, 3, 2, 4}).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(V4l2FrameBytes({V4L2_PIX_FMT_GREY, 0, 2, 4}).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(V4l2FrameBytes({V4L2_PIX_FMT_MJPEG, 4, 2, 8}).status().code(), StatusCode::kInvalidArgument);
}

TEST(V4l2FormatTest, YuyvGrayIsTheLumaWithPaddingSkipped) {
  // 2x2 pixels, lines padded to 6 bytes (the two padding bytes are 0xEE and must not show up).
  const std::vector<uint8_t> yuyv = {10, 128, 20, 128, 0xEE, 0xEE,  //
                                     30, 128, 40, 128, 0xEE, 0xEE};
  auto gray = ConvertV4l2Frame({V4L2_PIX_FMT_YUYV, 2, 2, 6}, yuyv.data(), yuyv.size(), true);
  ASSERT_TRUE(gray.ok()) << gray.status().ToString();
  ASSERT_EQ(gray->type(), CV_8UC1);
  EXPECT_EQ(gray->at<uint8_t>(0, 0), 10);
  EXPECT_EQ(gray->at<uint8_t>(0, 1), 20);
  EXPECT_EQ(gray->at<uint8_t>(1, 0), 30);
  EXPECT_EQ(gray->at<uint8_t>(1, 1), 40);
  const std::vector<uint8_t> uyvy = {128, 11, 128, 22};
  auto gray2 = ConvertV4l2Frame({V4L2_PIX_FMT_UYVY, 2, 1, 4}, uyvy.data(), uyvy.size(), true);
  ASSERT_TRUE(gray2.ok());
  EXPECT_EQ(gray2->at<uint8_t>(0, 0), 11);
  EXPECT_EQ(gray2->at<uint8_t>(0, 1), 22);
}

TEST(V4l2FormatTest, YuyvColourIsBt601) {
  // BT.601 limited range: Y=81, U=90, V=240 is pure red.
  const std::vector<uint8_t> red = {81, 90, 81, 240};
  auto bgr = ConvertV4l2Frame({V4L2_PIX_FMT_YUYV, 2, 1, 4}, red.data(), red.size(), false);
  ASSERT_TRUE(bgr.ok());
  ASSERT_EQ(bgr->type(), CV_8UC3);
  const auto px = bgr->at<cv::Vec3b>(0, 1);
  EXPECT_LT(px[0], 30);   // blue
  EXPECT_LT(px[1], 30);   // green
  EXPECT_GT(px[2], 225);  // red
}

TEST(V4l2FormatTest, RgbIsSwappedToBgrAndNv12GrayIsTheLumaPlane) {
  const std::vector<uint8_t> rgb = {200, 100, 50};
  auto bgr = ConvertV4l2Frame({V4L2_PIX_FMT_RGB24, 1, 1, 3}, rgb.data(), rgb.size(), false);
  ASSERT_TRUE(bgr.ok());
  EXPECT_EQ(bgr->at<cv::Vec3b>(0, 0), cv::Vec3b(50, 100, 200));
  const std::vector<uint8_t> nv12 = {1, 2, 3, 4, 5, 6, 7, 8, 128, 128, 128, 128};
  auto gray = ConvertV4l2Frame({V4L2_PIX_FMT_NV12, 4, 2, 4}, nv12.data(), nv12.size(), true);
  ASSERT_TRUE(gray.ok());
  EXPECT_EQ(gray->at<uint8_t>(1, 3), 8);
  auto grey_to_bgr = ConvertV4l2Frame({V4L2_PIX_FMT_GREY, 4, 2, 4}, nv12.data(), 8, false);
  ASSERT_TRUE(grey_to_bgr.ok());
  EXPECT_EQ(grey_to_bgr->at<cv::Vec3b>(1, 2), cv::Vec3b(7, 7, 7));
}

TEST(V4l2FormatTest, TruncatedFrameIsADeviceError) {
  const std::vector<uint8_t> short_frame(15, 0);
  auto r = ConvertV4l2Frame({V4L2_PIX_FMT_YUYV, 4, 2, 8}, short_frame.data(), short_frame.size(), true);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kDeviceError);
  EXPECT_NE(r.status().message().find("truncated YUYV frame: 15 bytes, 16 needed"), std::string::npos)
      << r.status().message();
  EXPECT_FALSE(ConvertV4l2Frame({V4L2_PIX_FMT_YUYV, 4, 2, 8}, nullptr, 16, true).ok());
}

}  // namespace
}  // namespace idi::drivers
