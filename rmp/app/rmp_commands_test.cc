// idi-rmp's sim, replay and run commands as a user runs them: outputs that would destroy an input or a
// recording are refused before any work, numeric options are checked, and the replay backend stops.
#include "rmp/app/rmp_commands.h"

#include <gtest/gtest.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <iterator>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include "rmp/app/replay_run.h"
#include "rmp/segway/rmp_codec.h"
#include "shared/replay/candump_log.h"
#include "shared/util/atomic_file.h"

namespace idi::rmp {
namespace {

namespace fs = std::filesystem;

// A short straight track and small cameras: a run takes a second or two.
constexpr const char* kCommandsTestTrack = "tape_width_m: 0.05\nspeed_mps: 0.5\npoints_m: [[0, 0], [1.0, 0]]\n";
constexpr const char* kCommandsTestConfig =
    "rig:\n  width_px: 320\n  height_px: 240\n  left: {fx_px: 160, fy_px: 160, cx_px: 159.5, cy_px: 119.5}\n"
    "  right: {fx_px: 160, fy_px: 160, cx_px: 159.5, cy_px: 119.5}\nperception: {max_range_m: 3.0}\n";

class RmpCommandsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("idi-rmp-commands-" + std::to_string(::getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    track_ = Write("track.yaml", kCommandsTestTrack);
    config_ = Write("rmp.yaml", kCommandsTestConfig);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string Write(const std::string& name, const std::string& text) {
    const std::string path = (dir_ / name).string();
    EXPECT_TRUE(WriteFileAtomically(path, text).ok()) << path;
    return path;
  }
  static std::string Read(const std::string& path) {
    auto text = ReadFile(path);
    return text.ok() ? *text : "(unreadable)";
  }
  int Run(std::vector<std::string> args) {
    CliApp cli("test", "idi-rmp");
    AddSimRunCommand(cli);
    AddReplayCommand(cli);
    AddRunCommand(cli);
    args.insert(args.begin(), {"idi-rmp", "-q"});
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    return RunCli(cli, static_cast<int>(argv.size()), argv.data());
  }
  // The exit code and the error message on stderr.
  std::pair<int, std::string> RunCapturingErrors(std::vector<std::string> args) {
    ::testing::internal::CaptureStderr();
    const int rc = Run(std::move(args));
    return {rc, ::testing::internal::GetCapturedStderr()};
  }
  int Sim(std::vector<std::string> args) {
    args.insert(args.begin(), {"sim", "--track", track_, "--config", config_});
    return Run(std::move(args));
  }
  // A drive log of the short track.
  std::string Record(const std::string& name) {
    const std::string rec = (dir_ / name).string();
    EXPECT_EQ(Sim({"--record", rec}), 0);
    return rec;
  }
  // Records one moving tick of the drive log `rec` with another speed; its line in events.jsonl (0: none).
  int ChangeOneMovingTick(const std::string& rec) {
    const std::string events_path = rec + "/events.jsonl";
    const std::string events = Read(events_path);
    int line = 0, changed_line = 0;
    std::string changed;
    for (std::size_t start = 0; start < events.size();) {
      const std::size_t end = events.find('\n', start);
      ++line;
      nlohmann::json e = nlohmann::json::parse(events.substr(start, end - start));
      if (changed_line == 0 && e["type"] == "tick" && e["speed_mps"].get<double>() != 0.0) {
        e["speed_mps"] = e["speed_mps"].get<double>() + 0.1;
        changed_line = line;
        changed += e.dump() + "\n";
      } else {
        changed += events.substr(start, end + 1 - start);
      }
      start = end + 1;
    }
    EXPECT_TRUE(WriteFileAtomically(events_path, changed).ok());
    return changed_line;
  }
  // The exit code, stdout and stderr.
  std::tuple<int, std::string, std::string> RunCapturingOutput(std::vector<std::string> args) {
    ::testing::internal::CaptureStdout();
    const auto [rc, err] = RunCapturingErrors(std::move(args));
    return {rc, ::testing::internal::GetCapturedStdout(), err};
  }

  fs::path dir_;
  std::string track_, config_;
};

TEST_F(RmpCommandsTest, SimRefusesAnOutputThatIsAnInput) {
  for (const char* option : {"--png", "--report", "--can-log"}) {
    for (const std::string& input : {track_, config_}) {
      EXPECT_EQ(Sim({option, input}), 2) << option << " " << input;
    }
  }
  EXPECT_EQ(Read(track_), kCommandsTestTrack);
  EXPECT_EQ(Read(config_), kCommandsTestConfig);
  // Through another name of the file, too.
  fs::create_symlink(track_, dir_ / "link.yaml");
  EXPECT_EQ(Sim({"--report", (dir_ / "link.yaml").string()}), 2);
  EXPECT_EQ(Read(track_), kCommandsTestTrack);
  // Two outputs that are one file.
  const std::string out = (dir_ / "out").string();
  EXPECT_EQ(Sim({"--png", out, "--report", out}), 2);
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(RmpCommandsTest, SimRefusesAnOutputInsideItsRecording) {
  // The folder exists (empty), so that only the check against the recording refuses these outputs.
  const std::string rec = (dir_ / "rec").string();
  fs::create_directories(rec);
  for (const std::string& out : {rec + "/events.jsonl", rec + "/recording.json", rec + "/can.log", rec, rec + "/"}) {
    for (const char* option : {"--png", "--report", "--can-log"}) {
      const auto [rc, err] =
          RunCapturingErrors({"sim", "--track", track_, "--config", config_, "--record", rec, option, out});
      EXPECT_EQ(rc, 2) << option << " " << out;
      EXPECT_NE(err.find("inside"), std::string::npos) << option << " " << out << ": " << err;
      EXPECT_TRUE(fs::is_empty(rec)) << option << " " << out << ": refused before the run";
    }
  }
  // A link outside the folder to a file the recording will make: written through after the run.
  const std::string link = (dir_ / "dl.json").string();
  fs::create_symlink(fs::path(rec) / "recording.json", link);
  {
    const auto [rc, err] =
        RunCapturingErrors({"sim", "--track", track_, "--config", config_, "--record", rec, "--report", link});
    EXPECT_EQ(rc, 2);
    EXPECT_NE(err.find("inside"), std::string::npos) << err;
    EXPECT_TRUE(fs::is_empty(rec)) << "refused before the run";
  }
  // An output that holds the recording: a new file where the run would make its parent folder.
  const std::string parent = (dir_ / "x").string();
  for (const char* option : {"--png", "--report", "--can-log"}) {
    const auto [rc, err] = RunCapturingErrors(
        {"sim", "--track", track_, "--config", config_, "--record", parent + "/rec", option, parent});
    EXPECT_EQ(rc, 2) << option;
    EXPECT_NE(err.find("inside"), std::string::npos) << option << ": " << err;
    EXPECT_FALSE(fs::exists(parent)) << option << ": refused before the run";
  }
  // The recording folder may not be an input either.
  const auto [rc, err] = RunCapturingErrors({"sim", "--track", track_, "--config", config_, "--record", track_});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("same file as the input"), std::string::npos) << err;
  EXPECT_EQ(Read(track_), kCommandsTestTrack);
}

// Nothing ran when an output cannot be written: the command line is at fault (exit 2, not 1).
TEST_F(RmpCommandsTest, UnwritableOutputsAreRefusedAsArguments) {
  if (::geteuid() == 0) GTEST_SKIP() << "root writes in a read-only folder";
  const fs::path ro = dir_ / "read-only";
  fs::create_directories(ro);
  fs::permissions(ro, fs::perms::owner_read | fs::perms::owner_exec);
  for (const char* option : {"--png", "--report", "--can-log"}) {
    const auto [rc, err] =
        RunCapturingErrors({"sim", "--track", track_, "--config", config_, option, (ro / "out").string()});
    EXPECT_EQ(rc, 2) << option << ": " << err;
    EXPECT_NE(err.find(option), std::string::npos) << err;
  }
  EXPECT_EQ(Sim({"--record", (ro / "rec").string()}), 2);
  fs::permissions(ro, fs::perms::owner_all);
}

TEST_F(RmpCommandsTest, SimChecksItsOutputsBeforeTheRun) {
  const std::string rec = (dir_ / "rec").string();
  const std::string missing = (dir_ / "no-such-folder" / "x").string();
  for (const char* option : {"--png", "--report", "--can-log"}) {
    const auto [rc, err] =
        RunCapturingErrors({"sim", "--track", track_, "--config", config_, "--record", rec, option, missing});
    EXPECT_EQ(rc, 2) << option;
    EXPECT_NE(err.find(option), std::string::npos) << err;
    EXPECT_FALSE(fs::exists(rec)) << option << ": the run would have made the recording";
  }
  EXPECT_EQ(Sim({"--record", (dir_ / "no-such-folder" / "rec").string(), "--png", track_ + ".png"}), 0)
      << "a new record folder's parents are made";
  EXPECT_EQ(Sim({"--record", track_ + "/rec"}), 2) << "its nearest existing parent is a file";
}

// A --record folder that holds files is refused before the simulation is set up (its track is not even
// read), naming the option and the folder, as run does; it was refused only when the recorder started.
TEST_F(RmpCommandsTest, SimRefusesANonEmptyRecordFolderBeforeTheRun) {
  const fs::path full = dir_ / "full";
  fs::create_directories(full);
  Write("full/file", "x\n");
  const std::string bad_track = Write("bad-track.yaml", "points_m: not a list\n");
  for (const std::string& track : {track_, bad_track}) {
    const auto [rc, err] =
        RunCapturingErrors({"sim", "--track", track, "--config", config_, "--record", full.string()});
    EXPECT_EQ(rc, 2) << err;
    EXPECT_NE(err.find("sim: --record " + full.string() + ": the folder is not empty"), std::string::npos) << err;
    EXPECT_EQ(err.find(bad_track), std::string::npos) << "the track was read first: " << err;
  }
  EXPECT_EQ(Read((full / "file").string()), "x\n");
  // A folder the command made is not left behind when the run fails before recording.
  const auto [rc, err] = RunCapturingErrors({"sim", "--track", bad_track, "--record", (dir_ / "new").string()});
  EXPECT_EQ(rc, 2) << err;
  EXPECT_FALSE(fs::exists(dir_ / "new"));
  // Nor are the parents it made on the way; a folder that was there stays.
  fs::create_directories(dir_ / "kept");
  const auto [rc2, err2] =
      RunCapturingErrors({"sim", "--track", bad_track, "--record", (dir_ / "kept" / "a" / "b").string()});
  EXPECT_EQ(rc2, 2) << err2;
  EXPECT_FALSE(fs::exists(dir_ / "kept" / "a"));
  EXPECT_TRUE(fs::is_directory(dir_ / "kept"));
}

TEST_F(RmpCommandsTest, SimOutputFailingAfterTheRunKeepsTheReport) {
  // An output that cannot be written after the run (the check before it passed): the report is still
  // there for the command to print.
  SimRunOptions o;
  auto config = ParseRmpConfig(kCommandsTestConfig, "test");
  ASSERT_TRUE(config.ok()) << config.status().ToString();
  o.config = *config;
  auto track = ParseTrackYaml(kCommandsTestTrack, "test-track");
  ASSERT_TRUE(track.ok()) << track.status().ToString();
  o.track = *track;
  o.png = (dir_ / "no-such-folder" / "run.png").string();
  auto res = RunSimulation(o);
  ASSERT_TRUE(res.ok()) << res.status().ToString();
  EXPECT_FALSE(res->output_status.ok());
  EXPECT_NE(res->output_status.message().find("run.png"), std::string::npos) << res->output_status.ToString();
  EXPECT_GT(res->report.frames, 0u);
  EXPECT_EQ(res->report.end, "finished");
  EXPECT_FALSE(res->report.extra.contains("png"));
}

// The recording could not be finished (its folder went away at the end of the run): it is not reported
// as written, and its CAN log is not copied to --can-log.
TEST_F(RmpCommandsTest, SimFailedRecordingIsNotReportedNorCopied) {
  SimRunOptions o;
  auto config = ParseRmpConfig(kCommandsTestConfig, "test");
  ASSERT_TRUE(config.ok()) << config.status().ToString();
  o.config = *config;
  auto track = ParseTrackYaml(kCommandsTestTrack, "test-track");
  ASSERT_TRUE(track.ok()) << track.status().ToString();
  o.track = *track;
  o.record_dir = (dir_ / "rec").string();
  o.can_log = (dir_ / "can.log").string();
  o.on_tick = [&o](const TickRecord&, SimWorld&, const ControlLoop& loop) {
    if (loop.finished()) fs::remove_all(o.record_dir);
  };
  auto res = RunSimulation(o);
  ASSERT_TRUE(res.ok()) << res.status().ToString();
  EXPECT_FALSE(res->output_status.ok());
  EXPECT_EQ(res->report.end, "finished");
  EXPECT_FALSE(res->report.extra.contains("record")) << res->report.ToJson().dump();
  EXPECT_FALSE(res->report.extra.contains("can_log")) << res->report.ToJson().dump();
  EXPECT_FALSE(fs::exists(o.can_log));
}

TEST_F(RmpCommandsTest, SimRefusesBadNumbersNamingTheOption) {
  for (const char* value : {"inf", "-5", "0", "nan", "1e9"}) {
    const auto [rc, err] = RunCapturingErrors({"sim", "--track", track_, "--max-time-s", value});
    EXPECT_EQ(rc, 2) << value;
    EXPECT_NE(err.find("--max-time-s"), std::string::npos) << value << ": " << err;
  }
  for (const char* value : {"-1", "nan", "0", "5", "inf"}) {
    const auto [rc, err] = RunCapturingErrors({"sim", "--track", track_, "--speed-mps", value});
    EXPECT_EQ(rc, 2) << value;
    EXPECT_NE(err.find("--speed-mps"), std::string::npos) << value << ": " << err;
    EXPECT_EQ(err.find(track_), std::string::npos) << value << ": the track file is not at fault: " << err;
  }
}

TEST_F(RmpCommandsTest, ReplayRefusesACanLogThatIsPartOfTheLog) {
  const std::string rec = Record("rec");
  const std::string can = rec + "/can.log";
  const std::string recorded = Read(can);
  ASSERT_FALSE(recorded.empty());
  EXPECT_EQ(Run({"replay", rec, "--can-log", can}), 2);
  EXPECT_EQ(Run({"replay", rec, "--can-log", rec + "/new.log"}), 2) << "a new file inside the log";
  EXPECT_EQ(Run({"replay", rec, "--can-log", rec}), 2);
  fs::create_symlink(can, dir_ / "can-link.log");
  EXPECT_EQ(Run({"replay", rec, "--can-log", (dir_ / "can-link.log").string()}), 2);
  fs::create_hard_link(can, dir_ / "can-hard.log");
  EXPECT_EQ(Run({"replay", rec, "--can-log", (dir_ / "can-hard.log").string()}), 2);
  EXPECT_EQ(Read(can), recorded);
  // A file in one of the log's subfolders (its images), through a hard link outside the log.
  std::string image;
  for (const auto& entry : fs::directory_iterator(fs::path(rec) / "images")) {
    if (entry.is_regular_file()) image = entry.path().string();
  }
  ASSERT_FALSE(image.empty()) << "no images in " << rec;
  const std::string pixels = Read(image);
  fs::create_hard_link(image, dir_ / "image-hard.png");
  const auto [rc, err] = RunCapturingErrors({"replay", rec, "--can-log", (dir_ / "image-hard.png").string()});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("same file as the input"), std::string::npos) << err;
  EXPECT_EQ(Read(image), pixels);
  EXPECT_FALSE(fs::exists(rec + "/new.log"));
  EXPECT_EQ(Run({"replay", rec, "--can-log", (dir_ / "replayed.log").string()}), 0);
  EXPECT_TRUE(fs::exists(dir_ / "replayed.log"));
}

// The log's images behind a link (images/ moved to another disk): the files the reader reads there are
// the log's as much as those inside DIR.
TEST_F(RmpCommandsTest, ReplayRefusesACanLogInTheImagesFolderBehindALink) {
  const std::string rec = Record("rec");
  const fs::path real_images = dir_ / "real-images";
  fs::rename(fs::path(rec) / "images", real_images);
  fs::create_symlink(real_images, fs::path(rec) / "images");
  std::string image;
  for (const auto& entry : fs::directory_iterator(real_images)) {
    if (entry.is_regular_file()) image = entry.path().string();
  }
  ASSERT_FALSE(image.empty());
  const std::string pixels = Read(image);
  {
    const auto [rc, err] = RunCapturingErrors({"replay", rec, "--can-log", image});
    EXPECT_EQ(rc, 2) << err;
    EXPECT_NE(err.find("same file as the input"), std::string::npos) << err;
  }
  EXPECT_EQ(Read(image), pixels);
  {
    const std::string inside = (real_images / "new.log").string();
    const auto [rc, err] = RunCapturingErrors({"replay", rec, "--can-log", inside});
    EXPECT_EQ(rc, 2) << err;
    EXPECT_NE(err.find("inside"), std::string::npos) << err;
    EXPECT_FALSE(fs::exists(inside));
  }
  EXPECT_EQ(Run({"replay", rec, "--can-log", (dir_ / "replayed.log").string()}), 0);
}

// The replay says whether the recorded commands were reproduced, and a log it does not reproduce is a
// failed run (exit 1), in text and JSON alike.
TEST_F(RmpCommandsTest, ReplaySaysWhetherTheCommandsWereReproduced) {
  const std::string rec = Record("rec");
  auto replay = [this](std::vector<std::string> args) { return RunCapturingOutput(std::move(args)); };
  {
    const auto [rc, out, err] = replay({"replay", rec});
    EXPECT_EQ(rc, 0) << err;
    EXPECT_NE(out.find("commands reproduced: yes"), std::string::npos) << out;
  }
  // One moving tick recorded with another speed.
  const int changed_line = ChangeOneMovingTick(rec);
  ASSERT_GT(changed_line, 0) << "no moving tick in " << rec;
  {
    const auto [rc, out, err] = replay({"replay", rec});
    EXPECT_EQ(rc, 1) << err;
    EXPECT_NE(out.find("commands reproduced: no (1 of "), std::string::npos) << out;
    EXPECT_NE(out.find("ticks differ, first at t="), std::string::npos) << out;
    EXPECT_NE(out.find("events.jsonl line " + std::to_string(changed_line)), std::string::npos) << out;
    EXPECT_NE(err.find("commands reproduced: no"), std::string::npos) << err;
  }
  {
    const auto [rc, out, err] = replay({"replay", rec, "--json"});
    EXPECT_EQ(rc, 1) << err;
    const nlohmann::json report = nlohmann::json::parse(out);
    EXPECT_EQ(report.value("commands_reproduced", true), false) << out;
    EXPECT_EQ(report.value("first_tick_difference_line", 0), changed_line) << out;
  }
}

// A drive log's header, the file to fix when its meta is wrong, is named.
TEST_F(RmpCommandsTest, ReplayNamesRecordingJsonForABadMeta) {
  const std::string rec = Record("rec");
  const std::string header_path = rec + "/recording.json";
  const std::string header = Read(header_path);
  for (const auto& [key, value] : std::vector<std::pair<std::string, double>>{
           {"cruise_speed_mps", -1.0}, {"tape_width_m", 0.0}, {"tape_width_m", -0.05}}) {
    nlohmann::json h = nlohmann::json::parse(header);
    h["meta"][key] = value;
    ASSERT_TRUE(WriteFileAtomically(header_path, h.dump()).ok());
    const auto [rc, err] = RunCapturingErrors({"replay", rec});
    EXPECT_EQ(rc, 2) << key << ": " << err;
    EXPECT_NE(err.find(header_path), std::string::npos) << key << ": " << err;
    EXPECT_NE(err.find("meta." + key), std::string::npos) << key << ": " << err;
  }
}

// A recording cut by a power loss: the last line of events.jsonl torn in the middle of a tick. It replays
// up to the tear, says which line it skipped, and what it replayed is reproduced.
TEST_F(RmpCommandsTest, ReplayWarnsOfATornLastLineAndReplaysUpToIt) {
  const std::string rec = Record("rec");
  const std::string events_path = rec + "/events.jsonl";
  const std::string events = Read(events_path);
  // Cut in the middle of the 200th line (the CAN log keeps the frames after it, as after a power loss).
  std::size_t at = 0;
  for (int k = 0; k < 199; ++k) at = events.find('\n', at) + 1;
  ASSERT_LT(at + 15, events.size());
  ASSERT_TRUE(WriteFileAtomically(events_path, events.substr(0, at + 15)).ok());
  ::testing::internal::CaptureStdout();
  const auto [rc, err] = RunCapturingErrors({"replay", rec, "--json"});
  const std::string out = ::testing::internal::GetCapturedStdout();
  EXPECT_EQ(rc, 0) << err;
  EXPECT_NE(err.find(events_path + ":200"), std::string::npos) << err;
  const nlohmann::json report = nlohmann::json::parse(out);
  EXPECT_EQ(report.value("commands_reproduced", false), true) << out;
  EXPECT_GT(report.value("ticks_compared", 0), 50) << out;
  EXPECT_EQ(report.value("end", ""), "log-ended") << out;
}

// can.log cut mid-line by a power loss: the warning names the file and the line it dropped, as the one
// for events.jsonl does.
TEST_F(RmpCommandsTest, ReplayWarnsOfATornLastCanLogLineByItsNumber) {
  const std::string rec = Record("rec");
  const std::string can_path = rec + "/can.log";
  const std::string can = Read(can_path);
  const auto lines = std::count(can.begin(), can.end(), '\n');
  ASSERT_GT(lines, 10);
  ASSERT_EQ(can.back(), '\n');
  ASSERT_TRUE(WriteFileAtomically(can_path, can + "(1.0000").ok());
  const auto [rc, out, err] = RunCapturingOutput({"replay", rec, "--json"});
  EXPECT_EQ(rc, 0) << err;
  EXPECT_NE(err.find(can_path + ":" + std::to_string(lines + 1) + ": the last line has no newline"), std::string::npos)
      << err;
}

// The command frames (id kRmpIdCommand) of a replayed driver's CAN log, with their times.
std::vector<std::pair<int64_t, RmpCommandFrame>> CommandFrames(const std::string& can_log) {
  std::vector<std::pair<int64_t, RmpCommandFrame>> out;
  auto frames = replay::ReadCandumpFile(can_log);
  EXPECT_TRUE(frames.ok()) << frames.status().ToString();
  if (!frames.ok()) return out;
  for (const replay::CandumpRecord& r : *frames) {
    if (r.frame.id != kRmpIdCommand) continue;
    auto cmd = DecodeCommandFrame(r.frame);
    EXPECT_TRUE(cmd.ok()) << cmd.status().ToString();
    if (cmd.ok()) out.emplace_back(r.frame.timestamp_ns, *cmd);
  }
  return out;
}

TEST_F(RmpCommandsTest, ReplayStopsWhenAskedAndCommandsZero) {
  const std::string rec = Record("rec");
  // The whole log, for the number of commands an unstopped replay sends.
  ReplayOptions whole;
  whole.dir = rec;
  whole.can_log = (dir_ / "whole.log").string();
  auto unstopped = RunReplay(whole);
  ASSERT_TRUE(unstopped.ok()) << unstopped.status().ToString();
  const std::size_t unstopped_commands = CommandFrames(whole.can_log).size();

  std::atomic<bool> stop{false};
  ReplayOptions o;
  o.dir = rec;
  o.can_log = (dir_ / "replayed.log").string();
  o.stop = &stop;
  uint64_t ticks = 0;
  bool moving = false;
  int64_t previous_t_ns = -1, stop_t_ns = -1, period_ns = 0;
  o.on_tick = [&](const TickRecord& tick) {
    ++ticks;
    if (tick.speed_mps != 0.0) moving = true;
    if (moving && ticks >= 40 && stop_t_ns < 0) {  // while the vehicle drives
      stop.store(true);
      stop_t_ns = tick.t_ns;
      period_ns = tick.t_ns - previous_t_ns;
    }
    previous_t_ns = tick.t_ns;
  };
  auto res = RunReplay(o);
  ASSERT_TRUE(res.ok()) << res.status().ToString();
  EXPECT_TRUE(moving);
  ASSERT_GE(stop_t_ns, 0);
  ASSERT_GT(period_ns, 0);
  EXPECT_EQ(res->report.end, "stopped");
  EXPECT_FALSE(res->report.completed);
  EXPECT_EQ(res->ticks_compared, ticks);
  // What it compared, it reproduced: the stop's zero commands are not compared with the recording's.
  EXPECT_EQ(res->report.extra.value("commands_reproduced", false), true) << res->report.ToJson().dump();
  EXPECT_TRUE(res->report.extra.contains("comparison")) << res->report.ToJson().dump();
  EXPECT_FALSE(unstopped->report.extra.contains("comparison"));
  // Moving commands before the stop, only zero ones a control period after it, and the replay ended early.
  const auto commands = CommandFrames(o.can_log);
  ASSERT_FALSE(commands.empty());
  bool moved = false;
  for (const auto& [t_ns, cmd] : commands) {
    if (t_ns <= stop_t_ns) {
      moved = moved || cmd.velocity_counts != 0;
      continue;
    }
    if (t_ns <= stop_t_ns + period_ns) continue;
    EXPECT_EQ(cmd.velocity_counts, 0) << "at " << t_ns << " ns, the stop at " << stop_t_ns << " ns";
    EXPECT_EQ(cmd.turn_counts, 0) << "at " << t_ns << " ns, the stop at " << stop_t_ns << " ns";
  }
  EXPECT_TRUE(moved);
  EXPECT_LT(commands.size(), unstopped_commands);

  // A stop before the first tick: nothing replayed.
  stop.store(true);
  o.on_tick = nullptr;
  o.can_log.clear();
  auto early = RunReplay(o);
  ASSERT_TRUE(early.ok()) << early.status().ToString();
  EXPECT_EQ(early->report.end, "stopped");
  EXPECT_EQ(early->ticks_compared, 0u);
}

TEST_F(RmpCommandsTest, RunWithReplayBackendRefusesRecord) {
  const std::string rec = Record("rec");
  const std::string cfg = Write("replay.yaml", "backend: replay\nreplay: {dir: " + rec + "}\n");
  const auto [rc, err] = RunCapturingErrors({"run", "--config", cfg, "--record", (dir_ / "new").string()});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("--record"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(dir_ / "new"));
  EXPECT_EQ(Run({"run", "--config", cfg}), 0);
}

// run with the replay backend compares the commands as replay does: the same line after the report, and
// a log it does not reproduce is a failed run (exit 1); it said nothing and exited 0.
TEST_F(RmpCommandsTest, RunWithReplayBackendSaysWhetherTheCommandsWereReproduced) {
  const std::string rec = Record("rec");
  const std::string cfg = Write("replay.yaml", "backend: replay\nreplay: {dir: " + rec + "}\n");
  {
    const auto [rc, out, err] = RunCapturingOutput({"run", "--config", cfg});
    EXPECT_EQ(rc, 0) << err;
    EXPECT_NE(out.find("commands reproduced: yes"), std::string::npos) << out;
  }
  const int changed_line = ChangeOneMovingTick(rec);
  ASSERT_GT(changed_line, 0) << "no moving tick in " << rec;
  {
    const auto [rc, out, err] = RunCapturingOutput({"run", "--config", cfg});
    EXPECT_EQ(rc, 1) << err;
    EXPECT_NE(out.find("commands reproduced: no (1 of "), std::string::npos) << out;
    EXPECT_NE(out.find("events.jsonl line " + std::to_string(changed_line)), std::string::npos) << out;
    EXPECT_NE(err.find(cfg), std::string::npos) << err;
  }
  {
    const auto [rc, out, err] = RunCapturingOutput({"run", "--config", cfg, "--json"});
    EXPECT_EQ(rc, 1) << err;
    EXPECT_EQ(nlohmann::json::parse(out).value("commands_reproduced", true), false) << out;
  }
}

// Two runs started within one second: the second's drive log gets a folder of its own (<time>-2), made
// with mkdir so that two processes cannot both take one.
TEST_F(RmpCommandsTest, RunNamesItsDriveLogFolderUniquely) {
  const fs::path logs = dir_ / "state" / "logs";
  fs::create_directories(logs);
  // The folders of the seconds around now, taken (empty, as just made by another run).
  std::vector<std::string> taken;
  const std::time_t now = std::time(nullptr);
  for (std::time_t t = now - 1; t <= now + 30; ++t) {
    std::tm tm{};
    localtime_r(&t, &tm);
    char buf[64];
    std::strftime(buf, sizeof(buf), "%Y%m%d-%H%M%S", &tm);
    taken.push_back(buf);
    fs::create_directories(logs / buf);
  }
  const std::string cfg = Write("run.yaml",
                                std::string(kCommandsTestConfig) + "backend: sim\nsim: {track: " + track_ +
                                    "}\nrecord: true\nstate_dir: " + (dir_ / "state").string() + "\n");
  const auto [rc, err] = RunCapturingErrors({"run", "--config", cfg});
  EXPECT_EQ(rc, 0) << err;
  std::vector<std::string> recorded;
  for (const auto& entry : fs::directory_iterator(logs)) {
    if (!fs::is_empty(entry.path())) recorded.push_back(entry.path().filename().string());
  }
  ASSERT_EQ(recorded.size(), 1u);
  EXPECT_NE(std::find(taken.begin(), taken.end(), recorded[0].substr(0, recorded[0].size() - 2)), taken.end())
      << recorded[0];
  EXPECT_EQ(recorded[0].substr(recorded[0].size() - 2), "-2") << recorded[0];
  EXPECT_EQ(Run({"replay", (logs / recorded[0]).string()}), 0);
  // A run that fails after its folder was made and before it recorded (its track file is not a track)
  // leaves no empty folder behind: a service that systemd restarts would leave one per attempt.
  const std::string bad_track = Write("bad-track.yaml", "points_m: not a list\n");
  const std::string bad = Write("bad.yaml",
                                std::string(kCommandsTestConfig) + "backend: sim\nsim: {track: " + bad_track +
                                    "}\nrecord: true\nstate_dir: " + (dir_ / "state").string() + "\n");
  const auto folders = [&logs] { return std::distance(fs::directory_iterator(logs), fs::directory_iterator()); };
  const auto before = folders();
  const auto [bad_rc, bad_err] = RunCapturingErrors({"run", "--config", bad});
  EXPECT_EQ(bad_rc, 2) << bad_err;
  EXPECT_NE(bad_err.find(bad_track), std::string::npos) << bad_err;
  EXPECT_EQ(folders(), before);
}

// The service's notifications (sd_notify) to a socket of the test's own, while it lives.
// A stand-in for systemd's notification socket. Like systemd it reads every message as it comes: a
// datagram socket nobody reads fills after a few messages (net.unix.max_dgram_qlen, 10 by default), and
// sd_notify's send then blocks the service.
class NotifySocket {
 public:
  explicit NotifySocket(const std::string& path) : path_(path) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::snprintf(addr.sun_path, sizeof(addr.sun_path), "%s", path.c_str());
    bound_ = fd_ >= 0 && ::bind(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) == 0;
    ::setenv("NOTIFY_SOCKET", path.c_str(), 1);
    if (bound_) reader_ = std::thread([this] { Read(); });
  }
  ~NotifySocket() {
    ::unsetenv("NOTIFY_SOCKET");
    stop_ = true;
    if (reader_.joinable()) reader_.join();
    if (fd_ >= 0) ::close(fd_);
    ::unlink(path_.c_str());
  }
  NotifySocket(const NotifySocket&) = delete;
  NotifySocket& operator=(const NotifySocket&) = delete;
  bool bound() const { return bound_; }
  // Whether READY=1 came since the last call. sd_notify has queued a command's notifications by the time
  // it returns; what the reader has not taken yet is read here, and the lock makes sure that a datagram it
  // has taken is also looked at.
  bool Ready() {
    std::lock_guard<std::mutex> lock(mu_);
    DrainLocked();
    return ready_.exchange(false);
  }

 private:
  void DrainLocked() {
    char buf[512];
    ssize_t n;
    while ((n = ::recv(fd_, buf, sizeof(buf) - 1, 0)) > 0) {
      buf[n] = 0;
      if (std::strstr(buf, "READY=1") != nullptr) ready_ = true;
    }
  }
  void Read() {
    while (!stop_) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 20) <= 0) continue;
      std::lock_guard<std::mutex> lock(mu_);
      DrainLocked();
    }
  }
  std::string path_;
  int fd_ = -1;
  bool bound_ = false;
  std::atomic<bool> ready_{false}, stop_{false};
  std::mutex mu_;  // one reader at a time: the thread or Ready()
  std::thread reader_;
};

// A --record folder that cannot take the drive log is refused as an argument (exit 2) before the service
// tells systemd it is ready, not when the recorder starts.
TEST_F(RmpCommandsTest, RunRefusesItsRecordFolderBeforeItIsReady) {
  const std::string cfg =
      Write("sim.yaml", std::string(kCommandsTestConfig) + "backend: sim\nsim: {track: " + track_ + "}\n");
  NotifySocket notify((dir_ / "notify.sock").string());
  ASSERT_TRUE(notify.bound());
  EXPECT_EQ(Run({"run", "--config", cfg, "--record", (dir_ / "new").string()}), 0);
  if (!notify.Ready()) GTEST_SKIP() << "built without libsystemd: no notifications to see";
  const fs::path full = dir_ / "full";
  fs::create_directories(full);
  Write("full/file", "x\n");
  {
    const auto [rc, err] = RunCapturingErrors({"run", "--config", cfg, "--record", full.string()});
    EXPECT_EQ(rc, 2) << err;
    EXPECT_NE(err.find(full.string()), std::string::npos) << err;
    EXPECT_FALSE(notify.Ready()) << "READY=1 before the refusal";
  }
  // A folder that cannot be made: a link to nowhere.
  const fs::path dangling = dir_ / "dangling";
  fs::create_symlink(dir_ / "nowhere" / "rec", dangling);
  {
    const auto [rc, err] = RunCapturingErrors({"run", "--config", cfg, "--record", dangling.string()});
    EXPECT_EQ(rc, 2) << err;
    EXPECT_NE(err.find(dangling.string()), std::string::npos) << err;
    EXPECT_FALSE(notify.Ready()) << "READY=1 before the refusal";
  }
  // An empty folder is fine.
  fs::create_directories(dir_ / "empty");
  EXPECT_EQ(Run({"run", "--config", cfg, "--record", (dir_ / "empty").string()}), 0);
  EXPECT_TRUE(notify.Ready());
  EXPECT_FALSE(fs::is_empty(dir_ / "empty"));
}

TEST_F(RmpCommandsTest, RunRefusesAStateDirThatCannotHoldLogs) {
  const std::string file = Write("state-file", "not a folder\n");
  const std::string cfg = Write("run.yaml",
                                std::string(kCommandsTestConfig) + "backend: sim\nsim: {track: " + track_ +
                                    "}\nrecord: true\nstate_dir: " + file + "\n");
  const auto [rc, err] = RunCapturingErrors({"run", "--config", cfg});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find(cfg), std::string::npos) << err;
  EXPECT_NE(err.find("state_dir"), std::string::npos) << err;
  EXPECT_EQ(Read(file), "not a folder\n");
  // --record naming an input.
  const auto [input_rc, input_err] = RunCapturingErrors({"run", "--config", cfg, "--record", track_});
  EXPECT_EQ(input_rc, 2);
  EXPECT_NE(input_err.find("same file as the input"), std::string::npos) << input_err;
  EXPECT_EQ(Read(track_), kCommandsTestTrack);
}

}  // namespace
}  // namespace idi::rmp
