#include "shared/replay/rawlog_export.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>

#include "shared/drivers/mrpt/mrpt_camera.h"

namespace idi {
namespace {

namespace fs = std::filesystem;

std::vector<RawlogFrame> SomeFrames() {
  std::vector<RawlogFrame> frames;
  for (int k = 0; k < 3; ++k) {
    RawlogFrame f;
    f.timestamp_unix_ns = 1'700'000'000'000'000'000LL + k * 33'000'000LL;
    f.sensor_label = k % 2 == 0 ? "left" : "right";
    f.image = cv::Mat(48, 64, CV_8UC1);
    cv::randu(f.image, 0, 255);
    CameraModel c;
    c.width = 64;
    c.height = 48;
    f.camera = c;
    frames.push_back(f);
  }
  return frames;
}

TEST(RawlogExportTest, WritesImagesMrptReadsBack) {
  const fs::path dir = fs::temp_directory_path() / ("idi_rawlog_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string path = (dir / "run.rawlog").string();
  const auto frames = SomeFrames();
  ASSERT_TRUE(ExportRawlog(frames, path).ok());
  const auto back = ReadRawlogImages(path);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ASSERT_EQ(back->size(), 3u);
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_EQ((*back)[k].sensor_label, frames[k].sensor_label);
    EXPECT_NEAR(static_cast<double>((*back)[k].timestamp_unix_ns), static_cast<double>(frames[k].timestamp_unix_ns), 2e3);
    EXPECT_EQ(cv::norm((*back)[k].image, frames[k].image, cv::NORM_INF), 0.0);
  }
  // Written beside the target and renamed: nothing else is left in the folder.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
  // A target that cannot be replaced (a folder in its place): an error, the folder as it was, no
  // temporary file left.
  fs::create_directories(dir / "taken.rawlog");
  std::ofstream(dir / "taken.rawlog" / "keep") << "x";
  const Status taken = ExportRawlog(frames, (dir / "taken.rawlog").string());
  EXPECT_EQ(taken.code(), StatusCode::kIoError);
  EXPECT_TRUE(fs::exists(dir / "taken.rawlog" / "keep"));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 2);
  // The same file through MRPT's camera sensor (grabber "rawlog"): what a replayed FireWire camera gives.
  hal::SimClock clock;
  drivers::MrptCamera cam({"right", "rawlog", {{"rawlog_file", path}, {"rawlog_camera_sensor_label", "right"}}}, &clock);
  // An exposure asked of a grabber without exposure control is refused, not ignored.
  hal::CameraSettings short_exposure;
  short_exposure.exposure_us = 2000;
  const Status refused = cam.Start(short_exposure);
  EXPECT_EQ(refused.code(), StatusCode::kFailedPrecondition) << refused.ToString();
  EXPECT_NE(refused.message().find("exposure control needs the dc1394 grabber"), std::string::npos);
  ASSERT_TRUE(cam.Start({}).ok());
  const auto img = cam.Grab(std::chrono::milliseconds(5000));
  ASSERT_TRUE(img.ok()) << img.status().ToString();
  EXPECT_EQ(cv::norm(img->pixels, frames[1].image, cv::NORM_INF), 0.0);
  EXPECT_TRUE(cam.Stop().ok());
  // An open that does not return in time is a Timeout naming the camera, not a hang: a stream (MRPT's
  // ffmpeg grabber) that is a FIFO without a writer blocks the grabber's open. While it is blocked, a
  // second start opens no other grabber. Then a writer comes and goes (O_RDWR: it never waits for a
  // reader), which lets the blocked open return on its own thread.
  const std::string fifo = (dir / "blocked.avi").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  drivers::MrptCamera impatient({"right", "ffmpeg", {{"ffmpeg_url", fifo}}, std::chrono::milliseconds(300)}, &clock);
  const Status late = impatient.Start({});
  EXPECT_EQ(late.code(), StatusCode::kTimeout) << late.ToString();
  EXPECT_NE(late.message().find("right (MRPT ffmpeg): the grabber did not open within 300 ms"), std::string::npos)
      << late.message();
  EXPECT_EQ(impatient.Grab(std::chrono::milliseconds(10)).status().code(), StatusCode::kFailedPrecondition);
  EXPECT_TRUE(impatient.Stop().ok());  // nothing open
  const Status again = impatient.Start({});
  EXPECT_EQ(again.code(), StatusCode::kTimeout) << again.ToString();
  EXPECT_NE(again.message().find("an earlier open or close of the grabber is still blocked"), std::string::npos)
      << again.message();
  const int writer = ::open(fifo.c_str(), O_RDWR);
  ASSERT_GE(writer, 0);
  ::close(writer);
  // The first camera, started again, is usable after its stop.
  ASSERT_TRUE(cam.Start({}).ok());
  EXPECT_TRUE(cam.Grab(std::chrono::milliseconds(5000)).ok());
  EXPECT_TRUE(cam.Stop().ok());
  fs::remove_all(dir);
}

TEST(RawlogExportTest, BadInput) {
  std::vector<RawlogFrame> frames(1);
  EXPECT_EQ(ExportRawlog(frames, "/tmp/x.rawlog").code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(ReadRawlogImages("/no/such.rawlog").status().code(), StatusCode::kNotFound);
  hal::SimClock clock;
  drivers::MrptCamera cam({"a602fc", "dc1394", {}}, &clock);
  // The shutter's range (20 us steps, 12 bits); 0 leaves the camera's own; not a number is refused.
  EXPECT_EQ(cam.SetExposure(10).code(), StatusCode::kOutOfRange);
  EXPECT_EQ(cam.SetExposure(100'000).code(), StatusCode::kOutOfRange);
  EXPECT_EQ(cam.SetExposure(-1).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(cam.SetExposure(std::nan("")).code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(cam.SetExposure(8000).ok());
  EXPECT_TRUE(cam.SetExposure(0).ok());
  hal::CameraSettings nan_exposure;
  nan_exposure.exposure_us = std::nan("");
  EXPECT_EQ(cam.Start(nan_exposure).code(), StatusCode::kInvalidArgument);
  // No FireWire bus here: opening fails with the camera named (never a crash).
  const Status st = cam.Start({});
  if (!st.ok()) {
    EXPECT_NE(st.message().find("a602fc"), std::string::npos);
    EXPECT_EQ(cam.Grab(std::chrono::milliseconds(10)).status().code(), StatusCode::kFailedPrecondition);
  }
}

}  // namespace
}  // namespace idi
