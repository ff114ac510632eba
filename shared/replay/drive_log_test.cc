#include "shared/replay/drive_log.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <utility>

namespace idi::replay {
namespace {

namespace fs = std::filesystem;

std::string TempDir(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("idi_drive_log_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(p);
  return p.string();
}

TEST(DriveLogTest, WritesAndReadsFramesTicksAndCan) {
  const std::string dir = TempDir("roundtrip");
  RecordingHeader header;
  header.meta = {{"start_ns", 1000}};
  auto writer = DriveLogWriter::Create(dir, header);
  ASSERT_TRUE(writer.ok()) << writer.status().ToString();
  hal::Image img;
  img.camera = "left";
  img.sequence = 7;
  img.timestamp_ns = 5'000'000;
  img.pixels = cv::Mat(4, 6, CV_8UC1);
  for (int i = 0; i < 24; ++i) img.pixels.data[i] = static_cast<uint8_t>(i * 10);
  ASSERT_TRUE((*writer)->AddFrame(img).ok());
  ASSERT_TRUE((*writer)->AddDelivered(35'000'000, "left", 7).ok());
  ASSERT_TRUE((*writer)->AddTick({40'000'000, 7, -1, 0.25, -0.5, "drive", "follow"}).ok());
  hal::CanFrame f;
  f.timestamp_ns = 40'000'000;
  f.id = 0x413;
  f.dlc = 8;
  ASSERT_TRUE((*writer)->can_log()->Write(f, CanDirection::kTransmitted).ok());
  ASSERT_TRUE((*writer)->Finish({{"start_ns", 1000}, {"ticks", 1}}).ok());

  auto log = ReadDriveLog(dir);
  ASSERT_TRUE(log.ok()) << log.status().ToString();
  ASSERT_EQ(log->frames.size(), 1u);
  EXPECT_EQ(log->frames[0].seq, 7u);
  EXPECT_EQ(log->frames[0].exposure_ns, 5'000'000);
  EXPECT_EQ(log->frames[0].delivered_ns, 35'000'000);
  ASSERT_EQ(log->ticks.size(), 1u);
  EXPECT_EQ(log->ticks[0].left_seq, 7);
  EXPECT_EQ(log->ticks[0].right_seq, -1);
  EXPECT_DOUBLE_EQ(log->ticks[0].yaw_rate_rps, -0.5);
  EXPECT_EQ(log->ticks[0].decision, "drive");
  ASSERT_EQ(log->can.size(), 1u);
  EXPECT_EQ(log->can[0].frame.id, 0x413u);
  EXPECT_EQ(log->can[0].direction, CanDirection::kTransmitted);
  EXPECT_EQ(log->recording.header.meta.value("ticks", 0), 1);
  // Lossless: the image comes back bit for bit.
  auto back = LoadDriveFrame(*log, log->frames[0]);
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(cv::norm(back->pixels, img.pixels, cv::NORM_INF), 0.0);
  EXPECT_EQ(back->timestamp_ns, 5'000'000);
  fs::remove_all(dir);
}

TEST(DriveLogTest, NamesWhatIsWrong) {
  EXPECT_EQ(ReadDriveLog("/nonexistent/idi/log").status().code(), StatusCode::kNotFound);
  // Another kind of recording.
  const std::string dir = TempDir("kind");
  RecordingHeader header;
  header.kind = "scan";
  ASSERT_TRUE(RecordingWriter::Create(dir, header).ok());
  auto log = ReadDriveLog(dir);
  ASSERT_FALSE(log.ok());
  EXPECT_NE(log.status().message().find("rmp-drive"), std::string::npos);
  fs::remove_all(dir);
  // A delivery of an unknown frame, and a tick without its fields.
  const std::string bad = TempDir("bad");
  {
    auto w = DriveLogWriter::Create(bad, {});
    ASSERT_TRUE(w.ok());
    ASSERT_TRUE((*w)->AddDelivered(1, "left", 3).ok());
    ASSERT_TRUE((*w)->Finish({}).ok());
  }
  auto l2 = ReadDriveLog(bad);
  ASSERT_FALSE(l2.ok());
  EXPECT_NE(l2.status().message().find("never recorded"), std::string::npos);
  // A frame recorded twice (its first copy was left undelivered, as if dropped), a frame delivered twice,
  // a negative sequence number and an image event without its file.
  const std::pair<const char*, const char*> cases[] = {
      {R"({"type":"image","t_ns":5,"camera":"left","seq":1,"file":"a.png"})"
       "\n"
       R"({"type":"image","t_ns":6,"camera":"left","seq":1,"file":"b.png"})",
       "frame left/1 recorded twice (first on line 1)"},  // ReadRecording refuses it
      {R"({"type":"image","t_ns":5,"camera":"left","seq":1,"file":"a.png"})"
       "\n"
       R"({"type":"delivered","t_ns":6,"camera":"left","seq":1})"
       "\n"
       R"({"type":"delivered","t_ns":7,"camera":"left","seq":1})",
       "delivered twice"},
      {R"({"type":"image","t_ns":5,"camera":"left","seq":-1,"file":"a.png"})", "non-negative"},
      {R"({"type":"image","t_ns":5,"camera":"left","seq":1})", "needs its file name"}};
  for (const auto& [events, why] : cases) {
    std::ofstream(fs::path(bad) / "events.jsonl") << events << "\n";
    const auto l3 = ReadDriveLog(bad);
    ASSERT_FALSE(l3.ok()) << events;
    EXPECT_EQ(l3.status().code(), StatusCode::kParseError);
    EXPECT_NE(l3.status().message().find(why), std::string::npos) << l3.status().message();
  }
  fs::remove_all(bad);
}

// A drive log whose events and CAN log are the texts given.
std::string WriteLog(const std::string& name, const std::string& events, const std::string& can) {
  const std::string dir = TempDir(name);
  {
    auto w = DriveLogWriter::Create(dir, {});
    EXPECT_TRUE(w.ok()) << w.status().ToString();
    if (w.ok()) {
      EXPECT_TRUE((*w)->Finish({}).ok());
    }
  }
  std::ofstream(fs::path(dir) / "events.jsonl") << events;
  std::ofstream(fs::path(dir) / kDriveLogCanFile) << can;
  return dir;
}

// A tick event after its t_ns.
constexpr const char* kTick =
    R"("type":"tick","left_seq":-1,"right_seq":-1,"speed_mps":0,"yaw_rate_rps":0,"decision":"drive","state":"follow"})";

constexpr const char* kInOrderCan =
    "(0000000001.000000) can0 402#0081008100000075 R\n"
    "(0000000001.010000) can0 413#0000000000000000 T\n";

// Ticks out of time order cannot be rerun on one clock: the tick's line is named (blank lines counted).
TEST(DriveLogTest, RefusesTicksOutOfTimeOrder) {
  const std::string good = WriteLog(
      "in_order", std::string("{\"t_ns\":20000000,") + kTick + "\n\n{\"t_ns\":40000000," + kTick + "\n", kInOrderCan);
  auto log = ReadDriveLog(good);
  ASSERT_TRUE(log.ok()) << log.status().ToString();
  ASSERT_EQ(log->ticks.size(), 2u);
  EXPECT_EQ(log->ticks[1].line, 3);
  fs::remove_all(good);

  const std::string ticks = WriteLog(
      "ticks_back", std::string("{\"t_ns\":40000000,") + kTick + "\n\n{\"t_ns\":20000000," + kTick + "\n", kInOrderCan);
  auto back = ReadDriveLog(ticks);
  ASSERT_FALSE(back.ok());
  EXPECT_EQ(back.status().code(), StatusCode::kParseError);
  EXPECT_NE(back.status().message().find(ticks + "/events.jsonl:3:"), std::string::npos) << back.status().message();
  EXPECT_NE(back.status().message().find("line 1"), std::string::npos) << back.status().message();
  fs::remove_all(ticks);
}

// A can.log whose time goes backwards would be fed to the replay in another order than the recorded run
// saw it: its line is named (comment lines counted).
TEST(DriveLogTest, RefusesACanLogWhoseTimeGoesBackwards) {
  const std::string frames = WriteLog("can_back",
                                      std::string("{\"t_ns\":20000000,") + kTick + "\n",
                                      "(0000000001.010000) can0 413#0000000000000000 T\n"
                                      "# a comment\n"
                                      "(0000000001.000000) can0 402#0081008100000075 R\n");
  auto can_back = ReadDriveLog(frames);
  ASSERT_FALSE(can_back.ok());
  EXPECT_EQ(can_back.status().code(), StatusCode::kParseError);
  EXPECT_NE(can_back.status().message().find(frames + "/can.log:3:"), std::string::npos) << can_back.status().message();
  EXPECT_NE(can_back.status().message().find("backwards"), std::string::npos) << can_back.status().message();
  fs::remove_all(frames);
}

}  // namespace
}  // namespace idi::replay
