// The ViCKi procedures end to end in the digital twin, and `idi-workcell calibrate` on files.
#include "workcell/procedures/calibration_procedures.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>

#include "shared/calib/evaluation.h"
#include "shared/sim/workcell/workcell_twin.h"
#include "workcell/app/calibrate_command.h"
#include "workcell/procedures/calibration_files.h"

namespace idi::workcell {
namespace {

CellSetup TwinCellSetup(const sim::WorkcellTwin& twin) {
  CellSetup s;
  for (const sim::Wall& w : twin.Setup().walls) {
    s.wall_names.push_back(w.name);
    s.world_from_wall.push_back(w.world_from_wall);
  }
  return s;
}

ArmDevices Devices(sim::WorkcellTwin& twin, int k) {
  return {&twin.arm(k), &twin.rail(k), &twin.laser(k), [&twin, k](int w) { return twin.ObserveSpot(k, w); }};
}

TEST(CalibrationProceduresTest, RobotAcquisitionAndCalibrationInTheTwin) {
  sim::WorkcellTwin twin({});
  ArmDevices dev = Devices(twin, 0);
  RobotAcquisitionOptions o;
  o.per_set = 75;
  o.held_out = 30;
  const auto acq = AcquireRobotData(dev, 0, TwinCellSetup(twin), calib::ArmModel{}, o);
  ASSERT_TRUE(acq.ok()) << acq.status().ToString();
  EXPECT_EQ(acq->data.readings.size() + static_cast<std::size_t>(acq->loop_failures) + acq->held_out.size(), 180u);
  EXPECT_NEAR(acq->data.distance_mm, 1000.0, 1e-9);  // the rail readings' difference
  EXPECT_TRUE(std::isfinite(acq->selection.condition_number));
  EXPECT_LT(acq->mean_loop_iterations, 10.0);
  calib::RobotCalibrationOptions co;
  co.noise.plane_normal = acq->plane_normal_in_base;
  const auto r = calib::CalibrateRobot(acq->data, co);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  // Against the twin's truth: every parameter within 5 reported std (the std includes the rail's
  // repeatability acting on the scale).
  const ParamSet truth = calib::PackRobotCalibration(twin.true_robot(0), twin.true_laser(0), r->point_mm, twin.true_rail(0));
  for (std::size_t i = 0; i < kRx130ParamCount + kLaserParamCount; ++i) {
    EXPECT_LT(std::abs(r->params.value(i) - truth.value(i)), 5.0 * r->params.stddev(i)) << truth.spec(i).Key();
  }
  EXPECT_GT(r->residuals.variance_factor, 0.5);
  EXPECT_LT(r->residuals.variance_factor, 2.0);
  // §4.5.4 on the held-out readings: calibrated lines meet far better than nominal ones.
  const calib::ArmModel nominal;
  const auto before = calib::LaserSpread(calib::LaserLines(nominal.robot, nominal.laser, acq->held_out));
  const auto after = calib::LaserSpread(calib::LaserLines(r->robot, r->laser, acq->held_out));
  ASSERT_TRUE(before.ok() && after.ok());
  EXPECT_GT(before->mean_mm, 5.0 * after->mean_mm);
}

// The operator's stop (or a signal) during an acquisition ends it with Cancelled at the next reading,
// not after hundreds more; the rail acquisition likewise.
TEST(CalibrationProceduresTest, AcquisitionsStopWhenCancelled) {
  sim::WorkcellTwin twin({});
  ArmDevices dev = Devices(twin, 0);
  RobotAcquisitionOptions o;
  o.per_set = 75;
  o.held_out = 30;
  int polls = 0;
  o.cancelled = [&polls] { return ++polls > 10; };
  const auto acq = AcquireRobotData(dev, 0, TwinCellSetup(twin), calib::ArmModel{}, o);
  ASSERT_FALSE(acq.ok());
  EXPECT_EQ(acq.status().code(), StatusCode::kCancelled) << acq.status().ToString();
  EXPECT_EQ(polls, 11) << "stopped at the first poll that said so";

  ArmDevices d1 = Devices(twin, 0), d2 = Devices(twin, 1);
  const calib::ArmModel nominal;
  RailAcquisitionOptions ro;
  ro.readings = 60;
  polls = 0;
  ro.cancelled = [&polls] { return ++polls > 3; };
  const auto rail = AcquireRailData(d1, d2, TwinCellSetup(twin), nominal, nominal, ro);
  ASSERT_FALSE(rail.ok());
  EXPECT_EQ(rail.status().code(), StatusCode::kCancelled) << rail.status().ToString();
  EXPECT_EQ(polls, 4);
}

// An arm that fails with a device fault after `good_moves` moves (a collision, an emergency stop, a
// controller that stopped answering), and counts its stops.
class FaultingArm : public hal::ArmDevice {
 public:
  FaultingArm(hal::ArmDevice& arm, int good_moves, StatusCode fault)
      : arm_(arm), good_moves_(good_moves), fault_(fault) {}
  std::string name() const override { return arm_.name(); }
  Status MoveJoints(const Joints& q, const hal::MoveOptions& o) override {
    ++moves;
    if (moves > good_moves_) return {fault_, name() + ": controller fault"};
    return arm_.MoveJoints(q, o);
  }
  Result<hal::JointState> ReadJoints() override { return arm_.ReadJoints(); }
  Status Stop() override {
    ++stops;
    return arm_.Stop();
  }
  int moves = 0, stops = 0;

 private:
  hal::ArmDevice& arm_;
  int good_moves_;
  StatusCode fault_;
};

// Robot 1's acquisition (75 readings per set, 30 held out: 180 configurations) with its arm replaced.
Result<RobotAcquisition> AcquireWithRobotOne(sim::WorkcellTwin& twin,
                                             hal::ArmDevice& arm,
                                             RobotAcquisition* partial = nullptr) {
  ArmDevices dev = Devices(twin, 0);
  dev.arm = &arm;
  RobotAcquisitionOptions o;
  o.per_set = 75;
  o.held_out = 30;
  o.partial = partial;
  return AcquireRobotData(dev, 0, TwinCellSetup(twin), calib::ArmModel{}, o);
}

// N of a status "...: stopped after N readings..." (-1 without it).
int ReadingsTakenIn(const Status& s) {
  const std::string key = "stopped after ";
  const std::size_t at = s.message().find(key);
  return at == std::string::npos ? -1 : std::stoi(s.message().substr(at + key.size()));
}

// A device fault during an acquisition ends it at once with that fault, the arm stopped and the laser
// off: it is not an aiming miss to count while the arm is commanded through hundreds more
// configurations (which ended in NotConverged, a code the service does not take for a fault). Misses
// (a joint limit, a spot off the wall) still only count.
TEST(CalibrationProceduresTest, ADeviceFaultEndsAnAcquisition) {
  for (const StatusCode fault : {StatusCode::kDeviceError, StatusCode::kTimeout}) {
    sim::WorkcellTwin twin({});
    FaultingArm arm(twin.arm(0), 40, fault);
    RobotAcquisition partial;
    const auto acq = AcquireWithRobotOne(twin, arm, &partial);
    ASSERT_FALSE(acq.ok());
    EXPECT_EQ(acq.status().code(), fault) << acq.status().ToString();
    EXPECT_NE(acq.status().message().find("robot 1: acquisition: stopped after"), std::string::npos)
        << acq.status().ToString();
    // What was measured before the fault is handed back, not lost.
    EXPECT_GT(ReadingsTakenIn(acq.status()), 0);
    EXPECT_EQ(static_cast<int>(partial.data.readings.size()), ReadingsTakenIn(acq.status()));
    for (std::size_t i = 0; i < partial.data.readings.size(); ++i) {
      EXPECT_EQ(partial.data.readings[i].set, 1);
      EXPECT_EQ(partial.data.readings[i].row, static_cast<int>(i) + 2);
      for (const double j : partial.data.readings[i].q) EXPECT_TRUE(std::isfinite(j));
    }
    EXPECT_EQ(arm.moves, 41) << "no move after the fault";
    EXPECT_EQ(arm.stops, 1);
    EXPECT_FALSE(twin.laser_on(0));
  }
  // The rail acquisition likewise, with robot 2's arm failing.
  sim::WorkcellTwin twin({});
  FaultingArm arm(twin.arm(1), 25, StatusCode::kDeviceError);
  ArmDevices d1 = Devices(twin, 0), d2 = Devices(twin, 1);
  d2.arm = &arm;
  const calib::ArmModel nominal;
  RailAcquisitionOptions ro;
  ro.readings = 60;
  RailAcquisition rail_partial;
  ro.partial = &rail_partial;
  const auto rail = AcquireRailData(d1, d2, TwinCellSetup(twin), nominal, nominal, ro);
  ASSERT_FALSE(rail.ok());
  EXPECT_EQ(rail.status().code(), StatusCode::kDeviceError) << rail.status().ToString();
  EXPECT_GT(ReadingsTakenIn(rail.status()), 0);
  EXPECT_EQ(static_cast<int>(rail_partial.readings.size()), ReadingsTakenIn(rail.status()));
  EXPECT_EQ(arm.moves, 26);
  EXPECT_EQ(arm.stops, 1);
  EXPECT_FALSE(twin.laser_on(0));
  EXPECT_FALSE(twin.laser_on(1));
}

// A joint limit in the way is a miss: the acquisition goes on (and fails only when misses are too many).
TEST(CalibrationProceduresTest, AJointLimitIsAMissNotAFault) {
  sim::WorkcellTwin twin({});
  FaultingArm arm(twin.arm(0), 0, StatusCode::kOutOfRange);
  const auto acq = AcquireWithRobotOne(twin, arm);
  ASSERT_FALSE(acq.ok());
  EXPECT_EQ(acq.status().code(), StatusCode::kNotConverged) << acq.status().ToString();
  EXPECT_EQ(arm.moves, 180) << "every configuration was tried";
  EXPECT_EQ(arm.stops, 0);
}

TEST(CalibrationProceduresTest, RailAcquisitionChoosesPointsOnMoreThanOneWall) {
  sim::WorkcellTwinOptions to;
  to.seed = 3;
  sim::WorkcellTwin twin(to);
  ArmDevices d1 = Devices(twin, 0), d2 = Devices(twin, 1);
  calib::ArmModel a1, a2;  // the true arms: this test is about the rail
  a1.robot = twin.true_robot(0);
  a1.laser = twin.true_laser(0);
  a1.rail = twin.true_rail(0);
  a2.robot = twin.true_robot(1);
  a2.laser = twin.true_laser(1);
  a2.rail = twin.true_rail(1);
  RailAcquisitionOptions o;
  o.readings = 60;
  o.points = 4;
  const auto acq = AcquireRailData(d1, d2, TwinCellSetup(twin), a1, a2, o);
  ASSERT_TRUE(acq.ok()) << acq.status().ToString();
  EXPECT_GE(acq->readings.size(), 55u);
  std::set<int> walls(acq->point_walls.begin(), acq->point_walls.end());
  EXPECT_GE(walls.size(), 2u);
  EXPECT_LT(acq->condition_number, acq->condition_number_one_wall);
  const auto r = calib::CalibrateRail(acq->readings, a1, a2, {});
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  for (std::size_t k = 0; k < 4; ++k) {
    EXPECT_LT(std::abs(r->psi.value(k) - twin.true_psi()[k]), 5.0 * r->psi.stddev(k)) << k;
  }
}

class CalibrateCommandTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // One folder per test and process: ctest runs the tests of this fixture in parallel.
    dir_ = std::filesystem::path(::testing::TempDir()) /
           ("calibrate_command_test_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) +
            "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  int Run(std::vector<std::string> args) {
    CliApp cli("test", "idi-workcell");
    AddCalibrateCommand(cli);
    args.insert(args.begin(), "idi-workcell");
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    return RunCli(cli, static_cast<int>(argv.size()), argv.data());
  }
  std::string P(const std::string& name) const { return (dir_ / name).string(); }
  std::filesystem::path dir_;
};

// An acquisition the operator stops part-way keeps what it measured: its readings go to
// obs.partial.csv (not obs.csv, which holds only complete acquisitions) and its held-out readings to
// val.partial.csv; the error names those files and the method and rail distance to calibrate with;
// the readings calibrate like any observations file; a second stopped run does not replace the first's.
TEST_F(CalibrateCommandTest, AStoppedAcquisitionSavesTheReadingsItMeasured) {
  RobotCommandOptions o;
  o.sim = true;
  o.readings = 150;
  o.observations = P("obs.csv");
  o.validate = P("val.csv");
  o.out = P("robot.yaml");
  int polls = 0;
  // Polled before each configuration: stopped during the held-out readings (60 of them), after the
  // 150 of both sets.
  o.cancelled = [&polls] { return ++polls > 180; };
  const Status s = RunCalibrateRobot(o);
  ASSERT_EQ(s.code(), StatusCode::kCancelled) << s.ToString();
  EXPECT_NE(s.message().find("saved in " + P("obs.partial.csv")), std::string::npos) << s.ToString();
  EXPECT_NE(s.message().find("saved in " + P("val.partial.csv")), std::string::npos) << s.ToString();
  for (const char* f : {"obs.csv", "val.csv", "robot.yaml"}) EXPECT_FALSE(std::filesystem::exists(P(f))) << f;
  auto readings = ReadRobotObservations(P("obs.partial.csv"));
  ASSERT_TRUE(readings.ok()) << readings.status().ToString();
  EXPECT_NE(s.message().find("the " + std::to_string(readings->size()) + " readings measured"), std::string::npos);
  EXPECT_GE(readings->size(), 140u);  // of the 150 configurations of the two sets (a few may miss)
  EXPECT_LE(readings->size(), 150u);
  EXPECT_EQ(readings->back().set, 2);
  auto held = ReadRobotObservations(P("val.partial.csv"));
  ASSERT_TRUE(held.ok()) << held.status().ToString();
  EXPECT_GE(held->size(), 25u);
  EXPECT_LE(held->size(), 30u);
  // The rail move measured between the sets, as the message gives it (the twin's 1000 mm, give or take
  // the rail's repeatability).
  const std::string key = "--distance-mm ";
  const std::size_t at = s.message().find("--method translate " + key);
  ASSERT_NE(at, std::string::npos) << s.ToString();
  const double d = std::stod(s.message().substr(at + std::string("--method translate ").size() + key.size()));
  EXPECT_NEAR(d, 1000.0, 1.0);
  RobotCommandOptions again;
  again.observations = P("obs.partial.csv");
  again.distance_mm = d;
  again.out = P("robot.yaml");
  const Status s2 = RunCalibrateRobot(again);
  EXPECT_TRUE(s2.ok()) << s2.ToString();
  EXPECT_TRUE(std::filesystem::exists(P("robot.yaml")));
  // Stopped again later: a file of its own; the first is left as it was.
  const auto first_size = std::filesystem::file_size(P("obs.partial.csv"));
  polls = 0;
  o.cancelled = [&polls] { return ++polls > 40; };
  const Status s3 = RunCalibrateRobot(o);
  EXPECT_EQ(s3.code(), StatusCode::kCancelled);
  EXPECT_NE(s3.message().find("saved in " + P("obs.partial-2.csv")), std::string::npos) << s3.ToString();
  EXPECT_EQ(std::filesystem::file_size(P("obs.partial.csv")), first_size);
  EXPECT_EQ(s3.message().find("--distance-mm"), std::string::npos) << "only set 1 measured: no calibration";
  // Stopped before any reading: nothing to save, no file.
  o.cancelled = [] { return true; };
  o.observations = P("obs2.csv");
  EXPECT_EQ(RunCalibrateRobot(o).code(), StatusCode::kCancelled);
  EXPECT_FALSE(std::filesystem::exists(P("obs2.partial.csv")));
}

// The rail calibration's acquisition stopped part-way (after both arms were calibrated in the twin):
// its readings are saved beside the observations file.
TEST_F(CalibrateCommandTest, AStoppedRailAcquisitionSavesTheReadingsItTook) {
  RtuCommandOptions o;
  o.sim = true;
  o.readings = 60;
  o.robot1 = P("robot1.yaml");
  o.robot2 = P("robot2.yaml");
  o.observations = P("rail_obs.csv");
  o.out = P("rail.yaml");
  int polls = 0;
  // Once both arms are calibrated (their files written), 25 rail readings are taken.
  o.cancelled = [&] { return std::filesystem::exists(P("robot2.yaml")) && ++polls > 25; };
  const Status s = RunCalibrateRtu(o);
  ASSERT_EQ(s.code(), StatusCode::kCancelled) << s.ToString();
  EXPECT_NE(s.message().find("saved in " + P("rail_obs.partial.csv")), std::string::npos) << s.ToString();
  EXPECT_FALSE(std::filesystem::exists(P("rail_obs.csv")));
  auto readings = ReadRailObservations(P("rail_obs.partial.csv"));
  ASSERT_TRUE(readings.ok()) << readings.status().ToString();
  EXPECT_GE(readings->size(), 20u);
  EXPECT_LE(readings->size(), 25u);
  // Stopped in the held-out acquisition, after the 60 readings: those are complete, in the
  // observations file, and the error says so.
  polls = 0;
  o.observations = P("rail_obs2.csv");
  o.cancelled = [&] { return ++polls > 65; };
  const Status held = RunCalibrateRtu(o);
  ASSERT_EQ(held.code(), StatusCode::kCancelled) << held.ToString();
  EXPECT_NE(held.message().find("(the held-out readings)"), std::string::npos) << held.ToString();
  EXPECT_NE(held.message().find("of the complete acquisition are in " + P("rail_obs2.csv")), std::string::npos)
      << held.ToString();
  auto complete = ReadRailObservations(P("rail_obs2.csv"));
  ASSERT_TRUE(complete.ok()) << complete.status().ToString();
  EXPECT_GE(complete->size(), 55u);
  EXPECT_FALSE(std::filesystem::exists(P("rail_obs2.partial.csv")));
}

// An arm the rail calibration calibrates first in the twin (no --robotK file), stopped part-way: its
// readings go beside the rail's result, not into the working directory.
TEST_F(CalibrateCommandTest, AStoppedArmAcquisitionForTheRailSavesBesideTheResult) {
  RtuCommandOptions o;
  o.sim = true;
  o.readings = 60;
  o.out = P("rail.yaml");
  int polls = 0;
  o.cancelled = [&polls] { return ++polls > 30; };
  const Status s = RunCalibrateRtu(o);
  ASSERT_EQ(s.code(), StatusCode::kCancelled) << s.ToString();
  EXPECT_NE(s.message().find("saved in " + P("robot1.partial.csv")), std::string::npos) << s.ToString();
  auto readings = ReadRobotObservations(P("robot1.partial.csv"));
  ASSERT_TRUE(readings.ok()) << readings.status().ToString();
  EXPECT_GE(readings->size(), 25u);
  EXPECT_LE(readings->size(), 30u);
}

TEST_F(CalibrateCommandTest, SimRunWritesFilesThatTheFileRunReproduces) {
  ASSERT_EQ(Run({"calibrate", "robot", "--sim", "--readings", "150", "--observations", P("obs.csv"), "--validate",
                 P("val.csv"), "--out", P("robot.yaml"), "--report", P("report.json"), "--plots", P("plots"), "-q"}),
            0);
  for (const char* f : {"obs.csv", "val.csv", "robot.yaml", "report.json", "plots/robot1_cost.png", "plots/robot1_spread.png"}) {
    EXPECT_TRUE(std::filesystem::exists(P(f))) << f;
  }
  std::ifstream in(P("report.json"));
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["method"], "translate");
  EXPECT_EQ(j["identifiability"]["singular_values_scaled"].size(), 27u);
  EXPECT_TRUE(j["params"].contains("alpha2_deg"));
  EXPECT_TRUE(j["params"]["point_x_mm"].contains("std"));
  EXPECT_GT(j["validation"][0]["nominal"]["mean_mm"].get<double>(), j["validation"][0]["calibrated"]["mean_mm"].get<double>());
  // D is the only scale: a change of D stretches each length by length / D, so the std it gives a3 and
  // d4 (about 625 mm) is their length / D times its own std, and it makes most of their variance; the
  // angles do not scale.
  const nlohmann::json& scale = j["scale_from_distance"];
  const double sd_d = scale["distance_sigma_mm"].get<double>(), d = j["distance_mm"].get<double>();
  EXPECT_NEAR(sd_d, 0.1414, 1e-9);
  ASSERT_EQ(scale["params"].size(), 27u);
  int lengths_checked = 0;
  for (const nlohmann::json& p : scale["params"]) {
    const std::string name = p["param"].get<std::string>();
    if (name == "a3_mm" || name == "d4_mm") {
      const double length = j["params"][name]["value"].get<double>();
      EXPECT_NEAR(p["std_from_distance"].get<double>(), std::abs(length) / d * sd_d, 0.03 * std::abs(length) / d * sd_d) << name;
      EXPECT_GT(p["share_of_variance"].get<double>(), 0.5) << name;
      ++lengths_checked;
    }
    if (p["unit"] == "deg") {
      EXPECT_LT(p["share_of_variance"].get<double>(), 0.01) << name;
    }
  }
  EXPECT_EQ(lengths_checked, 2);
  // The YAML loads as an arm model, and the saved observations calibrate again from the file.
  const auto arm = LoadRobotCalibration(P("robot.yaml"));
  ASSERT_TRUE(arm.ok()) << arm.status().ToString();
  // With the unknowns' correlation, which gives the arm model's covariance: its diagonal is the file's
  // std (a3 and theta_y as examples), and a3 / d4 (both scaled by D) correlate.
  ASSERT_EQ(arm->covariance.rows(), calib::kArmModelParamCount);
  const auto a3 = static_cast<Eigen::Index>(*arm->robot.Find("a3"));
  const auto d4 = static_cast<Eigen::Index>(*arm->robot.Find("d4"));
  EXPECT_NEAR(std::sqrt(arm->covariance(a3, a3)),
              arm->robot.stddev(static_cast<std::size_t>(a3)),
              1e-6 * arm->robot.stddev(static_cast<std::size_t>(a3)));
  const Eigen::Index ty = kRx130ParamCount + static_cast<Eigen::Index>(*arm->laser.Find("theta_y"));
  EXPECT_NEAR(std::sqrt(arm->covariance(ty, ty)),
              arm->laser.stddev(static_cast<std::size_t>(ty - kRx130ParamCount)),
              1e-6 * arm->laser.stddev(static_cast<std::size_t>(ty - kRx130ParamCount)));
  EXPECT_GT(arm->covariance(a3, d4) / std::sqrt(arm->covariance(a3, a3) * arm->covariance(d4, d4)), 0.5);
  {
    // A correlation that is not one on its diagonal is refused, naming the file's key.
    std::ifstream yaml(P("robot.yaml"));
    std::string text((std::istreambuf_iterator<char>(yaml)), std::istreambuf_iterator<char>());
    const std::size_t at = text.find("- [1, ");
    ASSERT_NE(at, std::string::npos);
    text.replace(at, 6, "- [0.5, ");
    std::ofstream(P("bad_corr.yaml")) << text;
    const auto bad = LoadRobotCalibration(P("bad_corr.yaml"));
    ASSERT_FALSE(bad.ok());
    EXPECT_NE(bad.status().message().find("correlation: row 1, column 1"), std::string::npos)
        << bad.status().ToString();
  }
  EXPECT_EQ(Run({"calibrate", "robot", "--observations", P("obs.csv"), "--distance-mm", "1000", "--method", "translate",
                 "--out", P("robot2.yaml"), "--validate", P("val.csv"), "-q"}),
            0);
  const auto again = LoadRobotCalibration(P("robot2.yaml"));
  ASSERT_TRUE(again.ok());
  // Same readings, same answer, apart from the noise model's plane (the file run assumes the noise
  // perpendicular to the beam): far inside the standard deviations.
  for (std::size_t i = 0; i < arm->robot.size(); ++i) {
    EXPECT_NEAR(arm->robot.value(i), again->robot.value(i), 0.5 * arm->robot.stddev(i) + 1e-12) << i;
  }
}

// The rail's psi rests on both arms' calibrations: their link lengths' uncertainty (the rail's
// repeatability is chapter 4's only scale) moves psi_x by tenths of a millimetre, against a few
// hundredths from the rail readings alone. Over seeds 2-21, psi_x's error was 12.5 times the std the
// readings alone give, and 0.82 times the std with the arms' covariance carried into it.
TEST_F(CalibrateCommandTest, RailStdCarriesTheArmsUncertainty) {
  double z_with = 0, z_given = 0;
  int n = 0;
  for (const int seed : {2, 3, 4, 5, 6}) {
    ASSERT_EQ(Run({"calibrate",
                   "rtu",
                   "--sim",
                   "--seed",
                   std::to_string(seed),
                   "--out",
                   P("rail.yaml"),
                   "--report",
                   P("rail.json"),
                   "-q"}),
              0)
        << seed;
    std::ifstream in(P("rail.json"));
    const nlohmann::json j = nlohmann::json::parse(in);
    ASSERT_TRUE(j["arms_uncertainty_included"].get<bool>());
    const double e = j["twin_truth_errors"]["psi_x_mm"].get<double>();
    const double sd = j["params"]["psi_x_mm"]["std"].get<double>(),
                 given = j["std_given_arms"]["psi_x_mm"].get<double>();
    EXPECT_GT(sd, 3.0 * given) << seed;
    z_with += (e / sd) * (e / sd);
    z_given += (e / given) * (e / given);
    ++n;
  }
  z_with = std::sqrt(z_with / n);
  z_given = std::sqrt(z_given / n);
  EXPECT_GT(z_with, 0.3);
  EXPECT_LT(z_with, 2.0);
  EXPECT_GT(z_given, 4.0);  // the readings alone understate it
}

TEST_F(CalibrateCommandTest, BadFilesFailWithExitCode2) {
  {
    std::ofstream f(P("bad.csv"));
    f << "set,j1_deg,j2_deg,j3_deg,j4_deg,j5_deg,j6_deg\n1,0,0,0,0,0\n";
  }
  EXPECT_EQ(Run({"calibrate", "robot", "--observations", P("bad.csv"), "--distance-mm", "1000", "--out", P("x.yaml"), "-q"}), 2);
  {
    std::ofstream f(P("few.csv"));
    f << "set,j1_deg,j2_deg,j3_deg,j4_deg,j5_deg,j6_deg\n";
    for (int i = 0; i < 40; ++i) f << (i % 2 + 1) << ",10,-40,80,0,30,0\n";
  }
  EXPECT_EQ(Run({"calibrate", "robot", "--observations", P("few.csv"), "--distance-mm", "1000", "--out", P("x.yaml"), "-q"}), 2);
  EXPECT_FALSE(std::filesystem::exists(P("x.yaml")));
  EXPECT_EQ(Run({"calibrate", "robot", "--observations", P("missing.csv"), "--distance-mm", "1000", "--out", P("x.yaml"), "-q"}), 2);
  EXPECT_EQ(Run({"calibrate", "rtu", "--observations", P("few.csv"), "--out", P("x.yaml"), "-q"}), 2);
}

// A joint reading the arm cannot give (far outside its range) is refused with the file, the line and
// the column named, exit 2 (before: read, and the calibration dropped it as an outlier without a word
// about the file). Readings a little past a limit (within the margin) are read.
TEST_F(CalibrateCommandTest, ImpossibleJointReadingsAreRefused) {
  {
    std::ofstream f(P("robot.csv"));
    f << kRobotCsvHeader << "\n1,10,-40,80,0,30,0\n2,9999,-40,80,0,30,0\n";
    std::ofstream edge(P("edge.csv"));
    edge << kRobotCsvHeader << "\n1,162,-40,80,0,30,0\n2,-10,-40,80,0,-107,272\n";
    std::ofstream rail(P("rail.csv"));
    rail << kRailCsvHeader << "\n10,-40,80,0,30,0,0,10,-40,80,0,30,0,0\n10,-40,80,0,30,0,0,10,-40,80,0,-360,0,0\n";
  }
  const auto robot = ReadRobotObservations(P("robot.csv"));
  ASSERT_FALSE(robot.ok());
  EXPECT_EQ(robot.status().code(), StatusCode::kOutOfRange);
  EXPECT_NE(robot.status().message().find(P("robot.csv") + ":3: column 'j1_deg': 9999 deg is outside joint 1's range "
                                                           "[-160.0, 160.0] deg"),
            std::string::npos)
      << robot.status().message();
  const auto edge = ReadRobotObservations(P("edge.csv"));
  EXPECT_TRUE(edge.ok()) << edge.status().ToString();
  const auto rail = ReadRailObservations(P("rail.csv"));
  ASSERT_FALSE(rail.ok());
  EXPECT_NE(rail.status().message().find(P("rail.csv") + ":3: column 'r2_j5_deg': -360 deg"), std::string::npos)
      << rail.status().message();
  EXPECT_EQ(Run({"calibrate",
                 "robot",
                 "--observations",
                 P("robot.csv"),
                 "--distance-mm",
                 "1000",
                 "--out",
                 P("x.yaml"),
                 "-q"}),
            2);
  EXPECT_FALSE(std::filesystem::exists(P("x.yaml")));
}

// Numbers in an observation file are decimal: strtod read "0x10" as 16 deg (a reading the arm can give),
// and "inf"/"nan" are not readings. Refused naming the file, the line and the column, exit 2.
TEST_F(CalibrateCommandTest, NonDecimalNumbersInObservationFilesAreRefused) {
  {
    std::ofstream f(P("robot.csv"));
    f << kRobotCsvHeader << "\n1,10,-40,80,0,30,0\n2,0x10,-40,80,0,30,0\n";
    std::ofstream rail(P("rail.csv"));
    rail << kRailCsvHeader << "\n10,-40,80,0,30,0,0,10,-40,80,0,30,0,0\n10,-40,80,0,30,0,0,10,-40,80,0,30,0,0X1p3\n";
  }
  const auto robot = ReadRobotObservations(P("robot.csv"));
  ASSERT_FALSE(robot.ok()) << "0x10 read as 16 deg";
  EXPECT_EQ(robot.status().code(), StatusCode::kParseError);
  EXPECT_NE(
      robot.status().message().find(P("robot.csv") + ":3: column 'j1_deg': '0x10' is not a finite decimal number"),
      std::string::npos)
      << robot.status().message();
  const auto rail = ReadRailObservations(P("rail.csv"));
  ASSERT_FALSE(rail.ok());
  EXPECT_NE(rail.status().message().find(P("rail.csv") + ":3: column 'r2_rail_mm': '0X1p3' is not a finite decimal"),
            std::string::npos)
      << rail.status().message();
  EXPECT_EQ(Run({"calibrate",
                 "robot",
                 "--observations",
                 P("robot.csv"),
                 "--distance-mm",
                 "1000",
                 "--out",
                 P("x.yaml"),
                 "-q"}),
            2);
  EXPECT_FALSE(std::filesystem::exists(P("x.yaml")));
}

// A noise std far beyond the cell's size (1e300 mm) is refused before any work with the option and the
// bound named, exit 2 (before: the twin's acquisition ran and the solve's residuals overflowed to NaN,
// Ceres printing pages of diagnostics, exit 1).
TEST_F(CalibrateCommandTest, NoiseLevelsBeyondTheCellAreRefusedUpFront) {
  RobotCommandOptions robot;
  robot.sim = true;
  robot.out = P("robot.yaml");
  robot.spot_sigma_mm = 1e300;
  Status st = RunCalibrateRobot(robot);
  EXPECT_EQ(st.code(), StatusCode::kOutOfRange) << st.ToString();
  EXPECT_NE(st.message().find("calibrate robot: --spot-sigma-mm: 1e+300 mm is out of range (a noise std is at most "
                              "1000 mm)"),
            std::string::npos)
      << st.message();
  robot.spot_sigma_mm = 0.05;
  robot.distance_sigma_mm = 2000;
  st = RunCalibrateRobot(robot);
  EXPECT_NE(st.message().find("--distance-sigma-mm: 2000 mm is out of range"), std::string::npos) << st.message();
  RtuCommandOptions rtu;
  rtu.sim = true;
  rtu.out = P("rail.yaml");
  rtu.rail_sigma_mm = 1e300;
  st = RunCalibrateRtu(rtu);
  EXPECT_NE(st.message().find("calibrate rtu: --rail-sigma-mm: 1e+300 mm is out of range"), std::string::npos)
      << st.message();
  EXPECT_EQ(Run({"calibrate", "robot", "--sim", "--spot-sigma-mm", "1e300", "--out", P("robot.yaml"), "-q"}), 2);
  EXPECT_EQ(Run({"calibrate", "rtu", "--sim", "--spot-sigma-mm", "1e300", "--out", P("rail.yaml"), "-q"}), 2);
  EXPECT_TRUE(std::filesystem::is_empty(dir_));
}

}  // namespace
}  // namespace idi::workcell
