// The cells `idi-workcell run` serves: the twin's devices and calibration jobs, and the hardware cell's
// errors when its devices are not there.
#include "workcell/app/cell_factory.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <map>
#include <thread>

#include "shared/util/atomic_file.h"
#include "workcell/app/scan_command.h"
#include "workcell/devices/barrett/barrett_emulator.h"
#include "workcell/devices/ptu/ptu_emulator.h"
#include "workcell/devices/staubli/val3_emulator.h"

namespace idi::workcell {
namespace {

namespace fs = std::filesystem;

class CellTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("idi-cell-test-" + std::to_string(::getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Runs a job of `cell` as the service would: validated, in a run folder of its own.
  Result<nlohmann::json> RunJob(Cell& cell, CalibrationStore& store, const std::string& name, const nlohmann::json& args) {
    for (JobSpec& j : cell.jobs) {
      if (j.name != name) continue;
      IDI_RETURN_IF_ERROR(j.validate(args));
      JobContext ctx;
      ctx.cancel = &cancel_;
      ctx.progress = [this](double f, const std::string&) { progress_.push_back(f); };
      ctx.run_dir = (dir_ / "runs" / name).string();
      fs::create_directories(ctx.run_dir);
      ctx.calibration = &store;
      ctx.devices = cell.devices.get();
      return j.run(ctx, args);
    }
    return NotFound("no job " + name);
  }

  fs::path dir_;
  std::atomic<bool> cancel_{false};
  std::vector<double> progress_;
};

WorkcellConfig SimConfig(const fs::path& state) {
  WorkcellConfig c;
  c.backend = "sim";
  c.state_dir = state.string();
  c.sim_seed = 3;
  return c;
}

// A hardware cell's configuration whose arm and two PTUs are emulators (no hand, no cameras).
struct EmulatedCell {
  std::unique_ptr<Val3Emulator> arm;
  std::unique_ptr<PtuEmulator> left, right;
  WorkcellConfig config;
  bool Start(const fs::path& state) {
    auto a = Val3Emulator::Start();
    PtuEmulatorOptions po;
    po.chatter_on_first_input = false;
    auto l = PtuEmulator::Start(po);
    auto r = PtuEmulator::Start(po);
    if (!a.ok() || !l.ok() || !r.ok()) return false;
    arm = std::move(*a);
    left = std::move(*l);
    right = std::move(*r);
    config = SimConfig(state);
    config.backend = "hardware";
    config.arms = {{"arm1", "127.0.0.1", arm->port()}};
    config.ptus = {{"left", left->port_path(), 9600}, {"right", right->port_path(), 9600}};
    config.hand.device.clear();
    return true;
  }
};

// Scans need the whole calibration; their arguments are checked before queuing.
TEST_F(CellTest, ScanAndDayJobsValidateAndNeedTheCalibration) {
  auto cell = MakeCell(SimConfig(dir_));
  ASSERT_TRUE(cell.ok()) << cell.status().ToString();
  CalibrationStore store((dir_ / "calibration").string());
  ASSERT_TRUE(store.Open().ok());
  EXPECT_EQ(RunJob(*cell, store, "scan", {{"object", "teapot"}}).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(RunJob(*cell, store, "scan", {{"scene", -1}}).status().code(), StatusCode::kInvalidArgument);
  // 2^32 would have run scene 0 (the int conversion wrapped it).
  EXPECT_EQ(RunJob(*cell, store, "scan", {{"scene", int64_t{4294967296}}}).status().code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(RunJob(*cell, store, "scan", {{"colour", "red"}}).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(RunJob(*cell, store, "day", {{"objects", "box,,prism"}}).status().code(), StatusCode::kInvalidArgument);
  const auto r = RunJob(*cell, store, "scan", {{"object", "box"}});
  ASSERT_EQ(r.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("run calibrate-robot1 first"), std::string::npos) << r.status().ToString();
}

TEST_F(CellTest, SimCellConnectsHomesAndReportsHealth) {
  auto cell = MakeCell(SimConfig(dir_));
  ASSERT_TRUE(cell.ok()) << cell.status().ToString();
  ASSERT_TRUE(cell->devices->Connect().ok());
  ASSERT_TRUE(cell->devices->Home().ok());
  const nlohmann::json h = cell->devices->Health();
  ASSERT_EQ(h.at("arms").size(), 2u);
  // Homed: the controller's zero, (0, -90, 90, 0, 0, 0) in the model convention, to encoder resolution.
  const std::vector<double> home = {0, -90, 90, 0, 0, 0};
  for (const auto& arm : h.at("arms")) {
    ASSERT_TRUE(arm.at("ok").get<bool>());
    for (std::size_t i = 0; i < 6; ++i) EXPECT_NEAR(arm.at("joints_deg")[i].get<double>(), home[i], 0.01) << i;
  }
  EXPECT_TRUE(cell->devices->StopAll().ok());
  // What a stale or missing calibration queues, and what a complete calibration holds.
  EXPECT_EQ(cell->calibration_jobs,
            (std::vector<std::string>{"calibrate-robot1", "calibrate-robot2", "calibrate-rail", "calibrate-ptu"}));
  EXPECT_EQ(cell->calibration_items, (std::vector<std::string>{"robot1", "robot2", "rail", "ptu"}));
}

TEST_F(CellTest, CalibrationJobsCommitVersionsTheRailJobUsesTheRobotsInUse) {
  auto cell = MakeCell(SimConfig(dir_));
  ASSERT_TRUE(cell.ok());
  CalibrationStore store(dir_.string());
  ASSERT_TRUE(store.Open().ok());
  const auto r1 = RunJob(*cell, store, "calibrate-robot1", {{"readings", 200}});
  ASSERT_TRUE(r1.ok()) << r1.status().ToString();
  EXPECT_EQ(r1->at("calibration_version").get<int>(), 1);
  EXPECT_EQ(r1->at("item").get<std::string>(), "robot1");
  const auto r2 = RunJob(*cell, store, "calibrate-robot2", {{"readings", 200}});
  ASSERT_TRUE(r2.ok()) << r2.status().ToString();
  const auto rail = RunJob(*cell, store, "calibrate-rail", {{"readings", 100}});
  ASSERT_TRUE(rail.ok()) << rail.status().ToString();
  EXPECT_EQ(rail->at("calibration_version").get<int>(), 3);
  // The rail job read the robots from the calibration in use, not a fresh calibration of its own.
  EXPECT_NE(rail->at("robot1").get<std::string>().find("calibration"), std::string::npos) << rail->dump();
  const auto ptu = RunJob(*cell, store, "calibrate-ptu", {{"image", false}, {"poses", 30}});
  ASSERT_TRUE(ptu.ok()) << ptu.status().ToString();
  auto current = store.Current();
  ASSERT_TRUE(current.ok() && current->has_value());
  EXPECT_EQ((*current)->number, 4);
  for (const char* item : {"robot1", "robot2", "rail", "ptu"}) {
    EXPECT_EQ((*current)->items.count(item), 1u) << item;
    const auto path = store.CurrentItemPath(item);
    ASSERT_TRUE(path.ok()) << item;
    const auto text = ReadFile(*path);
    ASSERT_TRUE(text.ok());
    EXPECT_GT(text->size(), 100u) << item;
  }
  EXPECT_FALSE(progress_.empty());
  // A new calibration of robot 1 makes the rail's stale (it was solved with the old robot 1): the new
  // version leaves it out, and keeps the rest. Before, the old rail went on with the new arm.
  const auto again = RunJob(*cell, store, "calibrate-robot1", {{"readings", 200}});
  ASSERT_TRUE(again.ok()) << again.status().ToString();
  EXPECT_EQ(again->at("dropped"), nlohmann::json::array({"rail"})) << again->dump();
  current = store.Current();
  ASSERT_TRUE(current.ok() && current->has_value());
  EXPECT_EQ((*current)->items.count("rail"), 0u);
  for (const char* item : {"robot1", "robot2", "ptu"}) EXPECT_EQ((*current)->items.count(item), 1u) << item;
}

// A rail job without committed robots calibrates them in its own folder: they are committed with the
// rail solved with them (before, only the rail was, and the robots in use later were others).
TEST_F(CellTest, ARailJobWithoutCommittedRobotsCommitsTheRobotsItMade) {
  auto cell = MakeCell(SimConfig(dir_));
  ASSERT_TRUE(cell.ok());
  CalibrationStore store(dir_.string());
  ASSERT_TRUE(store.Open().ok());
  const auto rail = RunJob(*cell, store, "calibrate-rail", {{"readings", 100}});
  ASSERT_TRUE(rail.ok()) << rail.status().ToString();
  EXPECT_EQ(rail->at("also_committed"), nlohmann::json::array({"robot1", "robot2"})) << rail->dump();
  auto current = store.Current();
  ASSERT_TRUE(current.ok() && current->has_value());
  EXPECT_EQ((*current)->number, 1);
  for (const char* item : {"robot1", "robot2", "rail"}) EXPECT_EQ((*current)->items.count(item), 1u) << item;
}

// scan --sim keeps its calibration in a folder that says which twin seed made it: another seed's files
// are another cell's calibration and are refused (before, `scan --seed 2` picked with seed 1's arms).
TEST_F(CellTest, SimCalibrationOfAnotherTwinSeedIsRefused) {
  const fs::path cal = dir_ / "calibration";
  fs::create_directories(cal);
  for (const char* f : {"robot1.yaml", "robot2.yaml", "rail.yaml", "ptu.yaml"}) std::ofstream(cal / f) << "x: 1\n";
  // Files without the seed are taken as given (a calibration from elsewhere).
  EXPECT_TRUE(EnsureSimCalibration(cal.string(), 2).ok());
  EXPECT_FALSE(fs::exists(cal / "twin.json"));
  std::ofstream(cal / "twin.json") << "{\"seed\": 1}\n";
  EXPECT_TRUE(EnsureSimCalibration(cal.string(), 1).ok());
  const auto other = EnsureSimCalibration(cal.string(), 2);
  ASSERT_FALSE(other.ok());
  EXPECT_EQ(other.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(other.status().message().find("made in the twin of seed 1, not 2"), std::string::npos)
      << other.status().ToString();
  std::ofstream(cal / "twin.json") << "{\"seed\": \"one\"}\n";
  EXPECT_EQ(EnsureSimCalibration(cal.string(), 1).status().code(), StatusCode::kParseError);
}

TEST_F(CellTest, BadJobArgumentsAreRefusedNamingTheField) {
  auto cell = MakeCell(SimConfig(dir_));
  ASSERT_TRUE(cell.ok());
  CalibrationStore store(dir_.string());
  ASSERT_TRUE(store.Open().ok());
  const std::vector<std::pair<std::string, nlohmann::json>> bad = {
      {"calibrate-robot1", {{"readings", 5}}},
      {"calibrate-robot1", {{"readings", "many"}}},
      {"calibrate-robot2", {{"speed", 1}}},
      {"calibrate-ptu", {{"image", "yes"}}},
      {"calibrate-ptu", {{"poses", 3}}},
      {"calibrate-ptu", {{"poses", 20}}},  // fewer than the solve's 24 (before: acquired, then refused)
      {"calibrate-rail", nlohmann::json::array()},
  };
  for (const auto& [job, args] : bad) {
    const auto r = RunJob(*cell, store, job, args);
    ASSERT_FALSE(r.ok()) << job << " " << args.dump();
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument) << r.status().ToString();
    EXPECT_NE(r.status().message().find(job), std::string::npos) << r.status().message();
  }
  auto current = store.Current();
  ASSERT_TRUE(current.ok());
  EXPECT_FALSE(current->has_value()) << "a refused job commits nothing";
}

TEST_F(CellTest, UnknownBackendAndUnreachableHardwareAreClearErrors) {
  WorkcellConfig c = SimConfig(dir_);
  c.backend = "simulation";
  const auto bad = MakeCell(c);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("simulation"), std::string::npos);

  c.backend = "hardware";
  const auto none = MakeCell(c);
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.status().message().find("hardware.arms"), std::string::npos) << none.status().message();

  // An arm whose controller does not answer: port 1 on loopback refuses the connection.
  c.arms = {{"arm1", "127.0.0.1", 1}};
  auto cell = MakeCell(c);
  ASSERT_TRUE(cell.ok()) << cell.status().ToString();
  EXPECT_TRUE(cell->jobs.empty());
  const Status st = cell->devices->Connect();
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("arm1"), std::string::npos) << st.message();
  (void)cell->devices->StopAll();  // stopping a cell that never connected returns (it must not hang)
  EXPECT_EQ(cell->devices->Health().at("arms")[0].at("state").get<std::string>(), "disconnected");
}

// The service homes the cell on its run thread while the control socket's thread may stop it. A stop
// during homing waits for the command in progress (never talks to a driver another thread is using),
// sends no further command of that move (the unit halted), skips the rest of the homing and halts
// every device; health meanwhile answers at once, marked busy.
TEST_F(CellTest, AStopDuringHomingEndsItAfterTheOperationInProgress) {
  EmulatedCell e;
  ASSERT_TRUE(e.Start(dir_));
  WorkcellConfig& c = e.config;
  auto cell = MakeCell(c);
  ASSERT_TRUE(cell.ok()) << cell.status().ToString();
  ASSERT_TRUE(cell->devices->Connect().ok());
  const std::size_t right_commands = e.right->commands().size();
  const std::size_t left_commands = e.left->commands().size();

  // The left unit answers its first homing command late: homing holds the devices meanwhile.
  e.left->DelayNextReply(std::chrono::milliseconds(600));  // within the 1 s reply timeout;
  Status homed = Status::Ok();
  std::thread home([&] { homed = cell->devices->Home(); });
  for (int k = 0; k < 1000 && e.left->commands().size() == left_commands; ++k) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ASSERT_GT(e.left->commands().size(), left_commands) << "the left unit never got its homing move";
  EXPECT_TRUE(cell->devices->Health().at("busy").get<bool>());
  EXPECT_TRUE(cell->devices->StopAll().ok());
  home.join();

  EXPECT_EQ(homed.code(), StatusCode::kCancelled) << homed.ToString();
  EXPECT_NE(homed.message().find("ptu-left: move interrupted by a stop; halt sent"), std::string::npos)
      << homed.message();
  // Position commands (PP<n> / TP<n>; PP alone is a query) sent from `from` on.
  const auto positioned = [](const std::vector<std::string>& commands, std::size_t from) {
    std::vector<std::string> out;
    for (std::size_t k = from; k < commands.size(); ++k) {
      const std::string& cmd = commands[k];
      if ((cmd.rfind("PP", 0) == 0 || cmd.rfind("TP", 0) == 0) && cmd.size() > 2) out.push_back(cmd);
    }
    return out;
  };
  // The left unit's tilt was not commanded after the stop (only the pan command in progress went), the
  // right unit was not moved; both were halted.
  EXPECT_EQ(positioned(e.left->commands(), left_commands), std::vector<std::string>{"PP0"});
  EXPECT_TRUE(positioned(e.right->commands(), right_commands).empty()) << "the right unit was moved after the stop";
  EXPECT_GE(e.left->halts(), 1);
  EXPECT_GE(e.right->halts(), 1);
  EXPECT_FALSE(cell->devices->Health().at("busy").get<bool>());

  // A reset connects again and homes the whole cell.
  ASSERT_TRUE(cell->devices->Connect().ok());
  EXPECT_TRUE(cell->devices->Home().ok());
}

// A stop during a long device operation does not wait for it: the hand's initialisation (HI drives
// every motor to its stops, up to 30 s) is aborted and homing ends Cancelled at once, not with the
// initialisation's Timeout 30 s later.
TEST_F(CellTest, AStopDuringTheHandsInitialisationAbortsItAtOnce) {
  EmulatedCell e;
  ASSERT_TRUE(e.Start(dir_));
  BarrettEmulatorOptions slow;
  slow.hi_duration = std::chrono::minutes(2);
  auto hand = BarrettEmulator::Start(slow);
  ASSERT_TRUE(hand.ok()) << hand.status().ToString();
  e.config.hand.device = (*hand)->port_path();
  auto cell = MakeCell(e.config);
  ASSERT_TRUE(cell.ok()) << cell.status().ToString();
  ASSERT_TRUE(cell->devices->Connect().ok());

  Status homed = Status::Ok();
  std::thread home([&] { homed = cell->devices->Home(); });
  const auto initialising = [&] {
    const auto commands = (*hand)->commands();
    return std::find(commands.begin(), commands.end(), "HI") != commands.end();
  };
  for (int k = 0; k < 2500 && !initialising(); ++k) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  ASSERT_TRUE(initialising()) << "the hand never got HI";
  const Status stopped = cell->devices->StopAll();
  home.join();

  EXPECT_EQ(homed.code(), StatusCode::kCancelled) << homed.ToString();
  EXPECT_NE(homed.message().find("interrupted by a stop"), std::string::npos) << homed.message();
  EXPECT_EQ((*hand)->aborts(), 1);
  EXPECT_GE((*hand)->stops(), 1);
  EXPECT_TRUE(stopped.ok()) << stopped.ToString();
  EXPECT_GE(e.left->halts(), 1);
  EXPECT_GE(e.right->halts(), 1);
  EXPECT_FALSE(cell->devices->Health().at("busy").get<bool>());
}

// The configured cameras are opened when the cell connects, not ignored: a camera node that is not
// there fails the connection naming the camera and its node, after the arm and the PTUs connected,
// and health lists the camera as stopped with the error.
TEST_F(CellTest, AConfiguredCameraThatIsNotThereFailsTheConnectionNamingIt) {
  EmulatedCell e;
  ASSERT_TRUE(e.Start(dir_));
  WorkcellConfig& c = e.config;
  const std::string node = (dir_ / "video-not-here").string();
  c.cameras = {{"left", "v4l2", node}};
  auto cell = MakeCell(c);
  ASSERT_TRUE(cell.ok()) << cell.status().ToString();
  const nlohmann::json before = cell->devices->Health();
  ASSERT_EQ(before.at("cameras").size(), 1u) << before.dump();
  EXPECT_EQ(before.at("cameras")[0].at("name").get<std::string>(), "left");
  EXPECT_EQ(before.at("cameras")[0].at("state").get<std::string>(), "stopped");

  const Status st = cell->devices->Connect();
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.code(), StatusCode::kNotFound) << st.ToString();  // the V4L2 driver's answer
  EXPECT_NE(st.message().find("camera left"), std::string::npos) << st.message();
  EXPECT_NE(st.message().find(node), std::string::npos) << st.message();
  const nlohmann::json after = cell->devices->Health();
  EXPECT_EQ(after.at("arms")[0].at("state").get<std::string>(), "ready") << after.dump();
  EXPECT_EQ(after.at("cameras")[0].at("state").get<std::string>(), "stopped");
  EXPECT_EQ(after.at("cameras")[0].at("frames").get<int>(), 0);
  EXPECT_FALSE(after.at("cameras")[0].value("last_error", std::string()).empty()) << after.dump();
  EXPECT_TRUE(cell->devices->StopAll().ok());
}

}  // namespace
}  // namespace idi::workcell
