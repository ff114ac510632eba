#include "shared/replay/recording.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace idi {
namespace {

namespace fs = std::filesystem;

TEST(RecordingTest, RoundTripWithImagesAndATornLastLine) {
  const fs::path dir = fs::temp_directory_path() / ("idi_recording_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  RecordingHeader h;
  h.kind = "scan";
  // Created on a vehicle up for an hour: its events' clock (from boot) read 3600 s.
  h.created_unix_ns = 1'700'000'000'000'000'000;
  h.created_clock_ns = 3'600'000'000'000;
  CameraModel cam;
  cam.params[kK1] = -0.1;
  h.cameras["left"] = cam;
  auto w = RecordingWriter::Create(dir.string(), h);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  cv::Mat img(32, 48, CV_8UC1, cv::Scalar(7));
  img.at<uint8_t>(3, 4) = 200;
  ASSERT_TRUE(w->Add(10, {{"type", "joints"}, {"arm", 1}, {"q_deg", {1, 2, 3, 4, 5, 6}}}).ok());
  ASSERT_TRUE(w->AddImage(20, "left", 1, img).ok());
  // The same sequence again (a camera that counted from 0 again) is refused: the recorded frame stays.
  EXPECT_EQ(w->AddImage(25, "left", 1, cv::Mat(32, 48, CV_8UC1, cv::Scalar(99))).code(),
            StatusCode::kFailedPrecondition);
  EXPECT_FALSE(w->Add(30, {{"no_type", 1}}).ok());
  ASSERT_TRUE(w->Finish({{"points", 8}}).ok());
  // A run killed while writing leaves half a line.
  {
    std::ofstream out(dir / "events.jsonl", std::ios::app);
    out << R"({"type": "joints", "t_n)";
  }
  const auto r = ReadRecording(dir.string());
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->header.kind, "scan");
  // An event 2 s after creation is 2 s after the wall-clock time of creation (before, the export added
  // the clock's whole reading, an hour here, to the creation time).
  EXPECT_EQ(r->header.created_clock_ns, h.created_clock_ns);
  EXPECT_EQ(UnixTimeOf(r->header, h.created_clock_ns + 2'000'000'000), h.created_unix_ns + 2'000'000'000);
  EXPECT_EQ(r->header.meta["points"], 8);
  EXPECT_DOUBLE_EQ(r->header.cameras.at("left").params[kK1], -0.1);
  ASSERT_EQ(r->events.size(), 2u);
  EXPECT_TRUE(r->truncated);
  EXPECT_EQ(r->truncated_line, 3);
  EXPECT_EQ(r->lines, (std::vector<int>{1, 2}));
  EXPECT_EQ(r->events[0]["t_ns"], 10);
  const auto back = LoadRecordedImage(*r, r->events[1]);
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(cv::norm(*back, img, cv::NORM_INF), 0.0);
  // A new recording never overwrites an old one.
  EXPECT_EQ(RecordingWriter::Create(dir.string(), h).status().code(), StatusCode::kInvalidArgument);
  fs::remove_all(dir);
}

// A power loss can leave the file's last line as NUL bytes (its length written, its data not), with or
// without the newline: torn like a line without a newline, reported by number. Any other garbage in the
// last line stays an error.
TEST(RecordingTest, ANulFilledLastLineIsTorn) {
  const fs::path dir = fs::temp_directory_path() / ("idi_recording_nul_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "recording.json") << R"({"format": "idi-recording", "version": 1, "kind": "x"})";
  const std::string good = "{\"type\":\"note\",\"t_ns\":1}\n";
  for (const bool newline : {true, false}) {
    std::ofstream(dir / "events.jsonl", std::ios::binary) << good << std::string(24, '\0') << (newline ? "\n" : "");
    const auto r = ReadRecording(dir.string());
    ASSERT_TRUE(r.ok()) << "newline " << newline << ": " << r.status().ToString();
    EXPECT_EQ(r->events.size(), 1u);
    EXPECT_TRUE(r->truncated);
    EXPECT_EQ(r->truncated_line, 2);
  }
  // NUL bytes before the last line are not a tear.
  std::ofstream(dir / "events.jsonl", std::ios::binary) << std::string(8, '\0') << "\n" << good;
  EXPECT_FALSE(ReadRecording(dir.string()).ok());
  // Garbage with a newline as the last line is not a tear either.
  std::ofstream(dir / "events.jsonl", std::ios::binary) << good << "{\"type\":\n";
  EXPECT_FALSE(ReadRecording(dir.string()).ok());
  fs::remove_all(dir);
}

TEST(RecordingTest, MalformedInputIsNamed) {
  const fs::path dir = fs::temp_directory_path() / ("idi_recording_bad_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  EXPECT_EQ(ReadRecording(dir.string()).status().code(), StatusCode::kNotFound);
  std::ofstream(dir / "recording.json") << R"({"format": "idi-recording", "version": 1, "kind": "x"})";
  std::ofstream(dir / "events.jsonl") << "{\"type\":\"note\",\"t_ns\":1}\nnot json\n";
  const auto r = ReadRecording(dir.string());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("events.jsonl:2"), std::string::npos) << r.status().message();
  std::ofstream(dir / "recording.json") << R"({"format": "idi-recording", "version": 7})";
  EXPECT_NE(ReadRecording(dir.string()).status().message().find("version 7"), std::string::npos);
  // Fields of the wrong type: a parse error naming the file (before: a JSON type_error, uncaught).
  std::ofstream(dir / "events.jsonl") << "{\"type\":\"note\",\"t_ns\":1}\n";
  for (const char* header : {R"({"format": "idi-recording", "version": "1"})",
                             R"({"format": 5, "version": 1})",
                             R"({"format": "idi-recording", "version": 1, "kind": 3})",
                             R"({"format": "idi-recording", "version": 1, "cameras": {"left": {"width": "640",
                                 "params": [1, 1, 0, 0, 0, 0, 0, 0, 0]}}})",
                             R"({"format": "idi-recording", "version": 1, "cameras": {"left": {"width": 640,
                                 "params": [1, null, 0, 0, 0, 0, 0, 0, 0]}}})",
                             // meta is an object, and its points (the recorded run's count) a count.
                             R"({"format": "idi-recording", "version": 1, "kind": "scan", "meta": "x"})",
                             R"({"format": "idi-recording", "version": 1, "kind": "scan", "meta": {"points": "many"}})",
                             R"({"format": "idi-recording", "version": 1, "kind": "scan", "meta": {"points": -3}})"}) {
    std::ofstream(dir / "recording.json") << header;
    const auto h = ReadRecording(dir.string());
    ASSERT_FALSE(h.ok()) << header;
    EXPECT_EQ(h.status().code(), StatusCode::kParseError) << header;
    EXPECT_NE(h.status().message().find("recording.json"), std::string::npos) << h.status().message();
    if (std::string(header).find("meta") != std::string::npos) {
      EXPECT_NE(h.status().message().find("meta"), std::string::npos) << h.status().message();
    }
  }
  std::ofstream(dir / "recording.json") << R"({"format": "idi-recording", "version": 1})";
  for (const char* event : {"{\"type\":7,\"t_ns\":0}\n", "{\"type\":\"tick\",\"t_ns\":1.5}\n"}) {
    std::ofstream(dir / "events.jsonl") << event;
    const auto e = ReadRecording(dir.string());
    ASSERT_FALSE(e.ok()) << event;
    EXPECT_NE(e.status().message().find("events.jsonl:1"), std::string::npos) << e.status().message();
  }
  Recording rec;
  rec.dir = dir.string();
  EXPECT_FALSE(LoadRecordedImage(rec, nlohmann::json::parse(R"({"type":"image","t_ns":0,"file":5})")).ok());
  fs::remove_all(dir);
}

// Image events a replay cannot trust are refused with the file and line named (before, all were read:
// a frame recorded twice was reconstructed from twice and exported twice, a t_ns near the end of int64
// overflowed in UnixTimeOf, and an absolute or ../ file read an image from outside the recording).
TEST(RecordingTest, RefusesImageEventsThatCannotBeReplayed) {
  const fs::path dir = fs::temp_directory_path() / ("idi_recording_events_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  // Created at a wall-clock time (as every run is): 2^63 - 1 ns after it does not fit in int64.
  std::ofstream(dir / "recording.json")
      << R"({"format": "idi-recording", "version": 1, "kind": "scan", "created_unix_ns": 1700000000000000000})";
  const std::string first =
      R"({"t_ns": 1, "type": "image", "camera": "left", "seq": 1, "file": "images/000001_left.png"})";
  const std::pair<std::string, std::string> refused[] = {
      {R"({"t_ns": 2, "type": "image", "camera": "left", "seq": 1, "file": "images/000001_left_again.png"})",
       "frame left/1 recorded twice (first on line 1)"},
      {R"({"t_ns": 2, "type": "image", "camera": "right", "seq": 1, "file": "images/000001_left.png"})",
       "images/000001_left.png recorded twice"},
      {R"({"t_ns": 2, "type": "image", "camera": "left", "seq": -5, "file": "images/a.png"})", "seq"},
      {R"({"t_ns": 2, "type": "image", "camera": "left", "seq": "x", "file": "images/a.png"})", "seq"},
      {R"({"t_ns": 2, "type": "image", "camera": "left", "seq": 2.5, "file": "images/a.png"})", "seq"},
      {R"({"t_ns": 9223372036854775807, "type": "note"})", "t_ns"},
      {R"({"t_ns": 18446744073709551615, "type": "note"})", "t_ns"},
      {R"({"t_ns": 2, "type": "image", "camera": "left", "seq": 2, "file": "/etc/hostname"})", "file"},
      {R"({"t_ns": 2, "type": "image", "camera": "left", "seq": 2, "file": "../outside.png"})", "file"},
      {R"({"t_ns": 2, "type": "image", "camera": "left", "seq": 2, "file": "images/../../outside.png"})", "file"},
      {R"({"t_ns": 2, "type": "image", "camera": "left", "seq": 2, "file": 5})", "file"},
      {R"({"t_ns": 2, "type": "image", "camera": "left", "seq": 2})", "file"},
  };
  for (const auto& [event, message] : refused) {
    std::ofstream(dir / "events.jsonl") << first << "\n" << event << "\n";
    const auto r = ReadRecording(dir.string());
    ASSERT_FALSE(r.ok()) << event;
    EXPECT_EQ(r.status().code(), StatusCode::kParseError) << event;
    EXPECT_NE(r.status().message().find("events.jsonl:2: "), std::string::npos) << r.status().message();
    EXPECT_NE(r.status().message().find(message), std::string::npos) << r.status().message();
  }
  // Other frames of the same camera, the same frame number of another camera, and a t_ns that fits are
  // read.
  std::ofstream(dir / "events.jsonl")
      << first << "\n"
      << R"({"t_ns": 2, "type": "image", "camera": "left", "seq": 2, "file": "images/000002_left.png"})"
      << "\n"
      << R"({"t_ns": 3, "type": "image", "camera": "right", "seq": 1, "file": "images/000001_right.png"})"
      << "\n"
      << R"({"t_ns": 7000000000000000000, "type": "note"})"
      << "\n";
  const auto r = ReadRecording(dir.string());
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->events.size(), 4u);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace idi
