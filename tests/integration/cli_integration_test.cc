// The binaries' command-line contracts: --help/--version, exit codes (0 ok, 2 bad input, 1 failed
// run), JSON on stdout, messages on stderr naming what was wrong.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>
#include <vector>

#include "tests/support/run_command.h"

namespace idi::test {
namespace {

const std::string kWorkcell = IDI_WORKCELL_BIN;
const std::string kRmp = IDI_RMP_BIN;

// A size x size grey image (binary PGM), dark (40) with a bright (200) square over its middle half.
void WriteSquarePgm(const std::string& path, int size) {
  std::ofstream img(path, std::ios::binary);
  img << "P5\n" << size << " " << size << "\n255\n";
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      img.put(static_cast<char>(x >= size / 4 && x < 3 * size / 4 && y >= size / 4 && y < 3 * size / 4 ? 200 : 40));
    }
  }
}

TEST(CliIntegrationTest, HelpAndVersion) {
  for (const std::string& bin : {kWorkcell, kRmp}) {
    const auto help = RunCommand(bin + " --help");
    EXPECT_EQ(help.exit_code, 0) << bin;
    EXPECT_NE(help.out.find("Subcommands"), std::string::npos) << help.out;
    const auto version = RunCommand(bin + " --version");
    EXPECT_EQ(version.exit_code, 0);
    EXPECT_NE(version.out.find("0.1.0"), std::string::npos) << version.out;
    const auto none = RunCommand(bin);
    EXPECT_EQ(none.exit_code, 2) << "no subcommand is a usage error";
    const auto bogus = RunCommand(bin + " no-such-command");
    EXPECT_EQ(bogus.exit_code, 2);
  }
}

TEST(CliIntegrationTest, KinematicsJsonAimsTheLaser) {
  const auto r = RunCommand(kWorkcell + " kinematics --joints-deg 0,-90,90,0,0,0 --aim-mm 3000,200,900 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  // Straight up with nominal parameters: the flange is at (0, 0, 1360).
  EXPECT_NEAR(j["flange_mm"][2].get<double>(), 1360.0, 1e-9);
  EXPECT_LT(j["aim"]["miss_mm"].get<double>(), 1e-6);
}

TEST(CliIntegrationTest, BadInputExitsWithTwoAndSaysWhat) {
  auto r = RunCommand(kWorkcell + " kinematics --joints-deg 0,1,2");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--joints-deg: expected 6"), std::string::npos) << r.err;
  r = RunCommand(kWorkcell + " kinematics --joints-deg 0,-90,90,0,200,0");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("joint 5"), std::string::npos) << r.err;
  r = RunCommand(kWorkcell + " kinematics --robot /no/such/robot.yaml");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("/no/such/robot.yaml"), std::string::npos) << r.err;
}

TEST(CliIntegrationTest, ParamsFileRoundTripsThroughKinematics) {
  const std::string dir = MakeTempDir("params_cli");
  const std::string path = dir + "/robot.yaml";
  auto r = RunCommand(kWorkcell + " params rx130 --out " + path);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = RunCommand(kWorkcell + " kinematics --robot " + path + " --json");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  // Corrupt one value: the run is refused with the file and key named.
  {
    std::ofstream out(path, std::ios::app);
    out << "bogus_mm: 1\n";
  }
  r = RunCommand(kWorkcell + " kinematics --robot " + path);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("unknown key 'bogus_mm'"), std::string::npos) << r.err;
  std::filesystem::remove_all(dir);
}

// A parameter file's text with the `key: ...` line replaced by `line`.
std::string WithLine(const std::string& text, const std::string& key, const std::string& line) {
  std::istringstream in(text);
  std::string l, out;
  while (std::getline(in, l)) out += (l.rfind(key + ":", 0) == 0 ? line : l) + "\n";
  return out;
}

// Finite but absurd lengths (1.7e308 mm) overflowed the forward kinematics: the poses came out as
// null in the JSON, exit 0. They are refused, the file and the key named, before any pose is printed.
TEST(CliIntegrationTest, KinematicsRefusesAbsurdLengths) {
  const std::string dir = MakeTempDir("kinematics_lengths_cli");
  const auto robot = RunCommand(kWorkcell + " params rx130");
  const auto laser = RunCommand(kWorkcell + " params laser");
  ASSERT_EQ(robot.exit_code, 0) << robot.err;
  ASSERT_EQ(laser.exit_code, 0) << laser.err;
  std::ofstream(dir + "/robot.yaml") << WithLine(
      WithLine(robot.out, "a3_mm", "a3_mm: {value: 1.7e308}"), "d4_mm", "d4_mm: {value: 1.7e308}");
  std::ofstream(dir + "/laser.yaml") << WithLine(laser.out, "px_mm", "px_mm: {value: 1.7e308}");
  auto r = RunCommand(kWorkcell + " kinematics --robot " + dir + "/robot.yaml --json");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.err.find(dir + "/robot.yaml:7: key 'a3_mm': 1.7e+308 mm is out of range"), std::string::npos) << r.err;
  EXPECT_TRUE(r.out.empty()) << r.out;
  r = RunCommand(kWorkcell + " kinematics --laser " + dir + "/laser.yaml --json");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.err.find("laser.yaml:4: key 'px_mm'"), std::string::npos) << r.err;
  std::filesystem::remove_all(dir);
}

// A parameter file of another model (`model: laser` with the arm's keys) was read as the arm's. It is
// refused, naming the file and the model expected; so is an arm file given as --laser.
TEST(CliIntegrationTest, KinematicsRefusesAFileOfAnotherModel) {
  const std::string dir = MakeTempDir("kinematics_model_cli");
  const auto robot = RunCommand(kWorkcell + " params rx130");
  const auto laser = RunCommand(kWorkcell + " params laser");
  ASSERT_EQ(robot.exit_code, 0) << robot.err;
  ASSERT_EQ(laser.exit_code, 0) << laser.err;
  std::ofstream(dir + "/robot.yaml") << WithLine(robot.out, "model", "model: laser");
  std::ofstream(dir + "/laser.yaml") << WithLine(laser.out, "model", "model: rx130");
  auto r = RunCommand(kWorkcell + " kinematics --robot " + dir + "/robot.yaml --json");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.err.find(dir + "/robot.yaml:1: model 'laser' is not the one expected here (expected model: rx130 or "
                             "rx130-laser-vicki)"),
            std::string::npos)
      << r.err;
  r = RunCommand(kWorkcell + " kinematics --laser " + dir + "/laser.yaml --json");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.err.find("laser.yaml:1: model 'rx130' is not the one expected here (expected model: laser or"),
            std::string::npos)
      << r.err;
  std::ofstream(dir + "/robot.yaml") << robot.out;
  std::ofstream(dir + "/laser.yaml") << laser.out;
  r = RunCommand(kWorkcell + " kinematics --robot " + dir + "/robot.yaml --laser " + dir + "/laser.yaml --json");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  std::filesystem::remove_all(dir);
}

// Numbers on the command line are decimal: "0x10" was read as 16 (by strtod for --joints-deg, by CLI11
// for numeric options). Refused with the option named; the usual forms still read.
TEST(CliIntegrationTest, NumbersOnTheCommandLineAreDecimal) {
  auto r = RunCommand(kWorkcell + " kinematics --joints-deg 0x10,0,90,0,0,0 --json");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.err.find("--joints-deg: '0x10' is not a finite decimal number"), std::string::npos) << r.err;
  r = RunCommand(kWorkcell + " kinematics --joints-deg=1,-1.5,1e-3,.5,0,0 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out).at("joints_deg"), nlohmann::json({1, -1.5, 1e-3, .5, 0, 0}));
  const std::string dir = MakeTempDir("decimal_cli");
  r = RunCommand(kWorkcell + " calibrate ptu --sim --poses 0x40 --out " + dir + "/ptu.yaml");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--poses: '0x40' is not a decimal number"), std::string::npos) << r.err;
  r = RunCommand(kWorkcell + " calibrate robot --sim --distance-mm 0x400 --out " + dir + "/robot.yaml");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--distance-mm: '0x400' is not a decimal number"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/ptu.yaml"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/robot.yaml"));
  std::filesystem::remove_all(dir);
}

// calibrate ptu --sim took 20 to 23 poses, acquired them all, and then the solve refused them (it needs
// 24 observations per camera). Refused before the acquisition, the option and its range named.
TEST(CliIntegrationTest, CalibratePtuRefusesTooFewPosesFirst) {
  const std::string dir = MakeTempDir("ptu_poses_cli");
  for (const char* poses : {"20", "23"}) {
    const auto r = RunCommand(kWorkcell + " calibrate ptu --sim --poses " + poses + " --out " + dir + "/ptu.yaml");
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find(std::string("--poses: Value ") + poses + " not in range 24 to 10000"), std::string::npos)
        << r.err;
    EXPECT_EQ(r.err.find("PTU survey"), std::string::npos) << "no acquisition before the check: " << r.err;
  }
  EXPECT_FALSE(std::filesystem::exists(dir + "/ptu.yaml"));
  std::filesystem::remove_all(dir);
}

// A --robot file that may not be read (permission denied) was a failed run (exit 1, no reason) while a
// missing one was bad input (exit 2): both are bad input, with the reason.
TEST(CliIntegrationTest, AnUnreadableRobotFileIsBadInput) {
  if (::geteuid() == 0) GTEST_SKIP() << "root reads a file without read permission";
  const std::string dir = MakeTempDir("unreadable_cli");
  auto r = RunCommand(kWorkcell + " params rx130 --out " + dir + "/robot.yaml");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::filesystem::permissions(dir + "/robot.yaml", std::filesystem::perms::none);
  r = RunCommand(kWorkcell + " kinematics --robot " + dir + "/robot.yaml --json");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find(dir + "/robot.yaml: cannot open for reading: Permission denied"), std::string::npos) << r.err;
  std::filesystem::remove_all(dir);
}

// What `calibrate robot` writes, `kinematics --robot` reads (its correlation matrix is skipped there).
TEST(CliIntegrationTest, RobotCalibrationFeedsKinematics) {
  const std::string dir = MakeTempDir("calib_kin_cli");
  const std::string path = dir + "/robot1.yaml";
  auto r = RunCommand(kWorkcell + " calibrate robot --sim --readings 200 --out " + path);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = RunCommand(kWorkcell + " kinematics --robot " + path + " --joints-deg 0,-90,90,0,0,0 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // The calibrated laser of that file is used (before: the nominal one, without a word), and the same
  // file is a valid --laser (before: refused for its arm keys), giving the same line.
  const auto calibrated = nlohmann::json::parse(r.out);
  EXPECT_EQ(calibrated.at("laser"), path);
  r = RunCommand(kWorkcell + " kinematics --joints-deg 0,-90,90,0,0,0 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto nominal = nlohmann::json::parse(r.out);
  EXPECT_EQ(nominal.at("laser"), "nominal");
  r = RunCommand(kWorkcell + " kinematics --robot " + path + " --laser " + path +
                 " --joints-deg 0,-90,90,0,0,0 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out).at("laser_direction"), calibrated.at("laser_direction"));
  // The file records the twin it was made in; a rail calibration in another twin refuses it (before, it
  // solved that twin's rail with this twin's arm), before acquiring anything.
  std::ifstream in(path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("sim_seed: 1\n"), std::string::npos) << text.substr(0, 200);
  r = RunCommand(kWorkcell + " calibrate rtu --sim --seed 2 --robot1 " + path + " --out " + dir + "/rail.yaml");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("was made in the twin of seed 1, this run's twin is seed 2"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/rail.yaml"));
  std::filesystem::remove_all(dir);
}

// Noise levels and distances that are not numbers, or negative, are refused with exit 2 and the option
// named, before the twin is made (whose constructor would abort on them).
TEST(CliIntegrationTest, CalibrateRefusesBadNoiseAndDistance) {
  const std::string dir = MakeTempDir("calib_bad_cli");
  for (const std::string& args : {std::string("robot --sim --spot-sigma-mm nan"),
                                  std::string("robot --sim --spot-sigma-mm=-0.1"),
                                  std::string("rtu --sim --spot-sigma-mm nan"),
                                  std::string("rtu --sim --rail-sigma-mm=-1")}) {
    const auto r = RunCommand(kWorkcell + " calibrate " + args + " --out " + dir + "/x.yaml");
    EXPECT_EQ(r.exit_code, 2) << args << ": " << r.err;
    EXPECT_NE(r.err.find("sigma-mm must be a finite number >= 0"), std::string::npos) << args << ": " << r.err;
  }
  const auto r = RunCommand(kWorkcell + " calibrate robot --sim --distance-mm=-500 --out " + dir + "/x.yaml");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--distance-mm must be a positive distance"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/x.yaml"));
  std::filesystem::remove_all(dir);
}

// A calibration's outputs are checked before its acquisition and solve: a folder that does not exist,
// or a folder given as the file, is known at once (before, after minutes of work).
TEST(CliIntegrationTest, CalibrationOutputsAreCheckedFirst) {
  const std::string dir = MakeTempDir("calibrate_out_cli");
  std::ofstream(dir + "/p.yaml") << "x: 1\n";  // a file where --plots wants a folder
  for (const std::string& args : {"calibrate robot --sim --out " + dir + "/no/such/robot1.yaml",
                                  "calibrate robot --sim --out " + dir,
                                  "calibrate robot --sim --out " + dir + "/r.yaml --report " + dir + "/none/r.json",
                                  "calibrate ptu --sim --out " + dir + "/none/ptu.yaml",
                                  "calibrate ptu --sim --out " + dir + "/p.yaml --validate " + dir + "/none/v.csv",
                                  "calibrate ptu --sim --out " + dir + "/q.yaml --plots " + dir + "/p.yaml/plots"}) {
    const auto r = RunCommand(kWorkcell + " " + args);
    EXPECT_EQ(r.exit_code, 2) << args << ": " << r.err;
    EXPECT_TRUE(r.err.find("does not exist") != std::string::npos || r.err.find("is a folder") != std::string::npos ||
                r.err.find("is not a folder") != std::string::npos)
        << r.err;
    EXPECT_EQ(r.err.find("acquir"), std::string::npos) << "no acquisition before the check: " << r.err;
  }
  std::filesystem::remove_all(dir);
}

std::string FileText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// An output that is an input (or another output) is refused before any work, and the input is left as
// it was (before: the readings were replaced by the calibration, robot 1's file by the rail's).
TEST(CliIntegrationTest, CalibrationOutputsMayNotReplaceInputs) {
  const std::string dir = MakeTempDir("calibrate_same_cli");
  for (const char* name : {"obs.csv", "r1.yaml", "r2.yaml"}) std::ofstream(dir + "/" + name) << name << "\n";
  const std::string d = dir + "/";
  for (const std::string& args :
       {"robot --observations " + d + "obs.csv --distance-mm 1000 --out " + d + "obs.csv",
        "robot --observations " + d + "obs.csv --distance-mm 1000 --out " + d + "x.yaml --report " + d + "../" +
            std::filesystem::path(dir).filename().string() + "/obs.csv",
        "robot --sim --out " + d + "r.yaml --report " + d + "./r.yaml",
        "rtu --robot1 " + d + "r1.yaml --robot2 " + d + "r2.yaml --observations " + d + "obs.csv --out " + d +
            "r1.yaml",
        "rtu --robot1 " + d + "r1.yaml --robot2 " + d + "r1.yaml --observations " + d + "obs.csv --out " + d + "x.yaml",
        "rtu --sim --robot1 " + d + "new.yaml --robot2 " + d + "new.yaml --out " + d + "x.yaml",
        "ptu --observations " + d + "obs.csv --out " + d + "x.yaml --report " + d + "obs.csv"}) {
    const auto r = RunCommand(kWorkcell + " calibrate " + args);
    EXPECT_EQ(r.exit_code, 2) << args << ": " << r.err;
    EXPECT_TRUE(r.err.find("is the same file as the input") != std::string::npos ||
                r.err.find("are the same file") != std::string::npos)
        << args << ": " << r.err;
    EXPECT_EQ(r.err.find("acquir"), std::string::npos) << "no acquisition before the check: " << r.err;
  }
  for (const char* name : {"obs.csv", "r1.yaml", "r2.yaml"}) EXPECT_EQ(FileText(d + name), std::string(name) + "\n");
  for (const char* name : {"x.yaml", "r.yaml", "new.yaml"}) EXPECT_FALSE(std::filesystem::exists(d + name)) << name;
  std::filesystem::remove_all(dir);
}

// Readings that cannot determine the model (here a rail distance given as 0.001 mm, as if in metres for
// 1 m) give a calibration with infinite standard deviations: it is not written (the loader refuses such
// a file), the parameters are named, and the exit code says the run failed. Before: written, exit 0.
TEST(CliIntegrationTest, AnUndeterminedCalibrationIsNotWritten) {
  const std::string dir = MakeTempDir("calibrate_undetermined_cli");
  auto r = RunCommand(kWorkcell + " calibrate robot --sim --readings 200 --observations " + dir + "/obs.csv --out " +
                      dir + "/a.yaml");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = RunCommand(kWorkcell + " calibrate robot --observations " + dir + "/obs.csv --distance-mm 0.001 --out " + dir +
                 "/b.yaml --report " + dir + "/b.json");
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("b.yaml: not written: the data do not determine"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/b.yaml"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/b.json"));
  // Fewer readings than the solve needs are refused before the acquisition.
  r = RunCommand(kWorkcell + " calibrate robot --sim --readings 135 --out " + dir + "/c.yaml");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("136"), std::string::npos) << r.err;
  std::filesystem::remove_all(dir);
}

// features --camera: a K that is not [fx, 0, cx, 0, fy, cy, 0, 0, 1] row-major (here transposed, which
// would put the principal point at (0, 0)) is refused with the file named; the same K in order is used.
TEST(CliIntegrationTest, FeaturesRefusesATransposedK) {
  const std::string dir = MakeTempDir("features_k_cli");
  WriteSquarePgm(dir + "/square.pgm", 64);
  {
    std::ofstream k(dir + "/transposed.yaml");
    k << "K: [60, 0, 0, 0, 60, 0, 31.5, 31.5, 1]\ndistortion: [-0.1, 0, 0, 0, 0]\n";
    std::ofstream good(dir + "/good.yaml");
    good << "K: [60, 0, 31.5, 0, 60, 31.5, 0, 0, 1]\ndistortion: [-0.1, 0, 0, 0, 0]\n";
  }
  auto r = RunCommand(kWorkcell + " features " + dir + "/square.pgm --camera " + dir + "/transposed.yaml --json");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("transposed.yaml: K: expected [fx, 0, cx, 0, fy, cy, 0, 0, 1]"), std::string::npos) << r.err;
  r = RunCommand(kWorkcell + " features " + dir + "/square.pgm --camera " + dir + "/good.yaml --json");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  std::filesystem::remove_all(dir);
}

// features with --camera over several images: one that does not fit the camera (too small for the
// detector) is that image's error line, and the images after it are still processed; two images with
// the same file name get two overlays.
TEST(CliIntegrationTest, FeaturesReportsABadImageAndGoesOn) {
  const std::string dir = MakeTempDir("features_many_cli");
  std::filesystem::create_directories(dir + "/a");
  std::filesystem::create_directories(dir + "/b");
  WriteSquarePgm(dir + "/tiny.pgm", 8);
  WriteSquarePgm(dir + "/a/square.pgm", 64);
  WriteSquarePgm(dir + "/b/square.pgm", 64);
  std::ofstream(dir + "/cam.yaml") << "K: [60, 0, 31.5, 0, 60, 31.5, 0, 0, 1]\ndistortion: [-0.1, 0, 0, 0, 0]\n";
  const auto r = RunCommand(kWorkcell + " features " + dir + "/tiny.pgm " + dir + "/a/square.pgm " + dir +
                            "/b/square.pgm --camera " + dir + "/cam.yaml --json --overlay " + dir + "/out");
  EXPECT_EQ(r.exit_code, 2) << r.err;  // one image failed
  EXPECT_NE(r.out.find("tiny.pgm: camera image size 8 x 8 is too small\",\"image\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("a/square.pgm\",\"lines\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("b/square.pgm\",\"lines\""), std::string::npos) << r.out;
  EXPECT_NE(r.err.find("1 of 3 images"), std::string::npos) << r.err;
  EXPECT_TRUE(std::filesystem::exists(dir + "/out/square_features.png"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/out/square_2_features.png"));
  std::filesystem::remove_all(dir);
}

// replay: an image event whose camera is not a string, or whose pose holds a null (how the JSON
// writer records a NaN), is refused with the event named and exit 2 (before: an uncaught JSON
// type_error, exit 1, nothing named).
TEST(CliIntegrationTest, ReplayRefusesEventFieldsOfTheWrongType) {
  const std::string dir = MakeTempDir("replay_types_cli");
  std::ofstream(dir + "/recording.json")
      << R"({"format": "idi-recording", "version": 1, "kind": "scan", "cameras": {"left": {"width": 64, "height": 64,)"
      << R"( "params": [60, 60, 31.5, 31.5, 0, 0, 0, 0, 0]}}})"
      << "\n";
  const std::string pose = "[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 1000]";
  std::ofstream(dir + "/events.jsonl") << R"({"t_ns": 1, "type": "image", "camera": 3, "file": "images/a.png", )"
                                       << R"("cam_from_world": )" << pose << "}\n";
  auto r = RunCommand(kWorkcell + " replay " + dir);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("events.jsonl event 1: 'camera' is not a string"), std::string::npos) << r.err;

  std::ofstream(dir + "/events.jsonl") << R"({"t_ns": 1, "type": "image", "camera": "left", "file": "images/a.png", )"
                                       << R"("cam_from_world": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, null]})"
                                       << "\n";
  r = RunCommand(kWorkcell + " replay " + dir);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("events.jsonl event 1: image event without a 12-number cam_from_world"), std::string::npos)
      << r.err;
  std::filesystem::remove_all(dir);
}

// features --camera: a parameter file must give the intrinsics (a missing principal point was taken
// as 319.5, 239.5 without a word), a key beside K that is not read is refused, and width comes with
// height.
TEST(CliIntegrationTest, FeaturesCameraFileMustBeWhole) {
  const std::string dir = MakeTempDir("features_cam_cli");
  WriteSquarePgm(dir + "/square.pgm", 64);
  std::ofstream(dir + "/no_centre.yaml") << "fx_px: 60\nfy_px: 60\nk1: -0.1\n";
  std::ofstream(dir + "/dist_coeffs.yaml")
      << "K: [60, 0, 31.5, 0, 60, 31.5, 0, 0, 1]\ndist_coeffs: [-0.1, 0, 0, 0, 0]\n";
  std::ofstream(dir + "/width_only.yaml") << "K: [60, 0, 31.5, 0, 60, 31.5, 0, 0, 1]\nwidth: 64\n";
  std::ofstream(dir + "/whole.yaml") << "fx_px: 60\nfy_px: 60\ncx_px: 31.5\ncy_px: 31.5\nk1: -0.1\n";
  const std::pair<const char*, const char*> refused[] = {{"no_centre.yaml", "no_centre.yaml: missing cx_px"},
                                                         {"dist_coeffs.yaml", "unknown key 'dist_coeffs'"},
                                                         {"width_only.yaml", "width and height go together"}};
  for (const auto& [file, message] : refused) {
    const auto r = RunCommand(kWorkcell + " features " + dir + "/square.pgm --camera " + dir + "/" + file + " --json");
    EXPECT_EQ(r.exit_code, 2) << file << ": " << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
  }
  const auto r = RunCommand(kWorkcell + " features " + dir + "/square.pgm --camera " + dir + "/whole.yaml --json");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  std::filesystem::remove_all(dir);
}

// features --overlay: an overlay that cannot be written (here a folder stands where it goes) is that
// image's error, in its own JSON line beside its features; the next image is still processed.
TEST(CliIntegrationTest, FeaturesReportsAFailedOverlayOnItsImage) {
  const std::string dir = MakeTempDir("features_overlay_cli");
  WriteSquarePgm(dir + "/blocked.pgm", 64);
  WriteSquarePgm(dir + "/fine.pgm", 64);
  std::filesystem::create_directories(dir + "/out/blocked_features.png");
  const auto r =
      RunCommand(kWorkcell + " features " + dir + "/blocked.pgm " + dir + "/fine.pgm --json --overlay " + dir + "/out");
  EXPECT_NE(r.exit_code, 0) << r.err;
  std::istringstream lines(r.out);
  std::string line;
  ASSERT_TRUE(std::getline(lines, line));
  const auto blocked = nlohmann::json::parse(line);
  EXPECT_TRUE(blocked.contains("lines")) << line;
  EXPECT_NE(blocked.value("error", "").find("blocked_features.png"), std::string::npos) << line;
  ASSERT_TRUE(std::getline(lines, line));
  EXPECT_FALSE(nlohmann::json::parse(line).contains("error")) << line;
  EXPECT_TRUE(std::filesystem::exists(dir + "/out/fine_features.png"));
  EXPECT_NE(r.err.find("1 of 2 images"), std::string::npos) << r.err;
  std::filesystem::remove_all(dir);
}

// features with one image whose overlay cannot be written: the error is printed once (before: twice,
// as the image's error and again as the run's).
TEST(CliIntegrationTest, FeaturesPrintsAnOverlayErrorOnce) {
  const std::string dir = MakeTempDir("features_overlay_once_cli");
  WriteSquarePgm(dir + "/blocked.pgm", 64);
  std::filesystem::create_directories(dir + "/out/blocked_features.png");
  for (const std::string json : {"", " --json"}) {
    const auto r = RunCommand(kWorkcell + " features " + dir + "/blocked.pgm --overlay " + dir + "/out" + json);
    EXPECT_NE(r.exit_code, 0) << r.err;
    const std::string message = "the overlay of " + dir + "/blocked.pgm: ";
    const std::size_t first = r.err.find(message);
    ASSERT_NE(first, std::string::npos) << r.err;
    EXPECT_EQ(r.err.find(message, first + 1), std::string::npos) << "printed twice: " << r.err;
  }
  std::filesystem::remove_all(dir);
}

// features --laser-spot: the spot of a short-exposure image (a Gaussian spot on a dark, slightly noisy
// background) is found at its centre; an image without one says no_spot.
TEST(CliIntegrationTest, FeaturesFindsTheLaserSpot) {
  const std::string dir = MakeTempDir("features_spot_cli");
  auto pgm = [](const std::string& path, bool with_spot) {
    std::ofstream img(path, std::ios::binary);
    img << "P5\n96 96\n255\n";
    for (int y = 0; y < 96; ++y) {
      for (int x = 0; x < 96; ++x) {
        const double dx = x - 40.3, dy = y - 57.6;
        const double v = 20.0 + ((x * 7 + y * 13) % 5 - 2) +
                         (with_spot ? 180.0 * std::exp(-(dx * dx + dy * dy) / (2 * 1.6 * 1.6)) : 0.0);
        img.put(static_cast<char>(static_cast<unsigned char>(std::lround(v))));
      }
    }
  };
  pgm(dir + "/spot.pgm", true);
  pgm(dir + "/dark.pgm", false);
  const auto r = RunCommand(kWorkcell + " features " + dir + "/spot.pgm " + dir + "/dark.pgm --laser-spot --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::istringstream lines(r.out);
  std::string line;
  ASSERT_TRUE(std::getline(lines, line));
  const auto spot = nlohmann::json::parse(line).at("laser_spot");
  EXPECT_EQ(spot.at("status"), "found") << line;
  ASSERT_EQ(spot.at("spots").size(), 1u) << line;
  EXPECT_NEAR(spot["spots"][0]["xy"][0].get<double>(), 40.3, 0.05) << line;
  EXPECT_NEAR(spot["spots"][0]["xy"][1].get<double>(), 57.6, 0.05) << line;
  ASSERT_TRUE(std::getline(lines, line));
  EXPECT_EQ(nlohmann::json::parse(line).at("laser_spot").at("status"), "no_spot") << line;
  const auto without = RunCommand(kWorkcell + " features " + dir + "/spot.pgm --json");
  EXPECT_FALSE(nlohmann::json::parse(without.out).contains("laser_spot")) << "only with --laser-spot";
  std::filesystem::remove_all(dir);
}

// reconstruct from the twin's two head cameras (`sim render`, with the calibration its JSON gives):
// views of the same file name in two folders get two overlays (before, the second overwrote the
// first), and an overlay folder that cannot be made is an error before the reconstruction runs.
TEST(CliIntegrationTest, ReconstructWritesAnOverlayPerView) {
  namespace fs = std::filesystem;
  const std::string dir = MakeTempDir("reconstruct_cli");
  auto r = RunCommand(kWorkcell + " sim render --out " + dir + "/render");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::ofstream views(dir + "/views.yaml");
  views << "views:\n";
  for (const auto& [side, folder] : {std::pair{"left", "a"}, std::pair{"right", "b"}}) {
    fs::create_directories(dir + "/" + folder);
    fs::copy_file(dir + "/render/" + side + ".png", dir + "/" + folder + "/view.png");
    std::ifstream truth(dir + "/render/" + side + ".json");
    const auto camera = nlohmann::json::parse(truth).at("camera");
    const auto& k = camera.at("intrinsics");
    const nlohmann::json kk = {k[0], 0, k[2], 0, k[1], k[3], 0, 0, 1};
    views << "  - {image: " << folder << "/view.png, K: " << kk.dump()
          << ", cam_from_world: " << camera.at("cam_from_world").dump() << "}\n";
  }
  views.close();
  r = RunCommand(kWorkcell + " reconstruct --views " + dir + "/views.yaml --json --overlay " + dir + "/out");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_GE(nlohmann::json::parse(r.out).at("points").size(), 10u) << r.out;
  EXPECT_TRUE(fs::exists(dir + "/out/view_model.png"));
  EXPECT_TRUE(fs::exists(dir + "/out/view_2_model.png"));
  r = RunCommand(kWorkcell + " reconstruct --views " + dir + "/views.yaml --json --overlay " + dir + "/views.yaml/out");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("cannot create the folder"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("reconstruct: 2 views"), std::string::npos) << "no reconstruction before the check: " << r.err;
  EXPECT_TRUE(r.out.empty()) << r.out;
  // An output may not replace an input or another output: refused before the reconstruction.
  const std::string views_text = FileText(dir + "/views.yaml");
  for (const std::string& args : {"--ply " + dir + "/views.yaml",
                                  "--ply " + dir + "/a/view.png",
                                  "--ply " + dir + "/out/view_model.png --overlay " + dir + "/out"}) {
    r = RunCommand(kWorkcell + " reconstruct --views " + dir + "/views.yaml --json " + args);
    EXPECT_EQ(r.exit_code, 2) << args << ": " << r.err;
    EXPECT_NE(r.err.find("same file"), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("reconstruct: 2 views"), std::string::npos) << "no reconstruction before the check: " << r.err;
  }
  EXPECT_EQ(FileText(dir + "/views.yaml"), views_text);
  fs::remove_all(dir);
}

// reconstruct: a K whose principal point is far from the image's middle (here the K of a 1280 x 960
// camera with 640 x 480 images, and a principal point outside the image) is refused naming the views
// file, the view and the image (before: reconstructed with it without a word).
TEST(CliIntegrationTest, ReconstructRefusesAKForAnotherImageSize) {
  namespace fs = std::filesystem;
  const std::string dir = MakeTempDir("reconstruct_k_cli");
  auto r = RunCommand(kWorkcell + " sim render --out " + dir);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  auto views = [&dir](double scale, double cx_shift) {
    std::ofstream out(dir + "/views.yaml");
    out << "views:\n";
    for (const std::string side : {"left", "right"}) {
      std::ifstream truth(dir + "/" + side + ".json");
      const auto camera = nlohmann::json::parse(truth).at("camera");
      const auto& k = camera.at("intrinsics");
      const double fx = k[0].get<double>() * scale, fy = k[1].get<double>() * scale;
      const double cx = (k[2].get<double>() + 0.5) * scale - 0.5 + cx_shift,
                   cy = (k[3].get<double>() + 0.5) * scale - 0.5;
      const nlohmann::json kk = {fx, 0, cx, 0, fy, cy, 0, 0, 1};
      out << "  - {image: " << side << ".png, K: " << kk.dump()
          << ", cam_from_world: " << camera.at("cam_from_world").dump() << "}\n";
    }
  };
  views(2.0, 0.0);  // K for twice the size: the principal point in the image's corner
  r = RunCommand(kWorkcell + " reconstruct --views " + dir + "/views.yaml --json");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find(dir +
                       "/views.yaml:2: views[0].K: the principal point (639.5, 479.5) px is not near the middle "
                       "of the 640 x 480 px image " +
                       dir + "/left.png"),
            std::string::npos)
      << r.err;
  EXPECT_TRUE(r.out.empty()) << r.out;
  views(1.0, 5000.0);
  r = RunCommand(kWorkcell + " reconstruct --views " + dir + "/views.yaml --json");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("is K for another image size?"), std::string::npos) << r.err;
  views(1.0, 0.0);
  r = RunCommand(kWorkcell + " reconstruct --views " + dir + "/views.yaml --json");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  fs::remove_all(dir);
}

// An image whose header claims 100000 x 100000 px: OpenCV's imread throws (CV_IO_MAX_IMAGE_PIXELS).
void WriteHugeHeaderPgm(const std::string& path) {
  std::ofstream(path, std::ios::binary) << "P5\n100000 100000\n255\nabcd";
}

// A scan recording of one 64 x 64 image event (images/000001_left.png, written by `image`).
void WriteScanRecording(const std::string& dir, const std::function<void(const std::string&)>& image) {
  std::filesystem::create_directories(dir + "/images");
  std::ofstream(dir + "/recording.json")
      << R"({"format": "idi-recording", "version": 1, "kind": "scan", "cameras": {"left": {"width": 64, "height": 64,)"
      << R"( "params": [60, 60, 31.5, 31.5, 0, 0, 0, 0, 0]}}})"
      << "\n";
  std::ofstream(dir + "/events.jsonl") << R"({"t_ns": 1, "type": "image", "camera": "left", "seq": 1, )"
                                       << R"("file": "images/000001_left.png", )"
                                       << R"("cam_from_world": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 1000]})"
                                       << "\n";
  image(dir + "/images/000001_left.png");
}

// features --overlay: an overlay that would be written over one of the images (fo/a.png's overlay is
// fo/a_features.png, also an input) is refused before any image is read (before, a.png's overlay
// replaced the second image, which was then read as an input).
TEST(CliIntegrationTest, FeaturesRefusesAnOverlayOverAnInput) {
  const std::string dir = MakeTempDir("features_same_cli");
  std::filesystem::create_directories(dir + "/fo");
  WriteSquarePgm(dir + "/fo/a.png", 64);
  WriteSquarePgm(dir + "/fo/a_features.png", 48);
  const std::string before = FileText(dir + "/fo/a_features.png");
  const auto r = RunCommand(kWorkcell + " features " + dir + "/fo/a.png " + dir +
                            "/fo/a_features.png --json --overlay " + dir + "/fo");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("a_features.png is the same file as the input"), std::string::npos) << r.err;
  EXPECT_TRUE(r.out.empty()) << "refused before any image: " << r.out;
  EXPECT_EQ(FileText(dir + "/fo/a_features.png"), before);
  std::filesystem::remove_all(dir);
}

// export-rawlog: an OUT that is the recording's header, its events or one of its images is refused before
// anything is written (before, the export replaced it: the recording was destroyed).
TEST(CliIntegrationTest, ExportRawlogRefusesToWriteOverTheRecording) {
  if (RunCommand(kWorkcell + " --help").out.find("export-rawlog") == std::string::npos) {
    GTEST_SKIP() << "built without MRPT";
  }
  const std::string dir = MakeTempDir("export_same_cli");
  WriteScanRecording(dir + "/rec", [](const std::string& path) { WriteSquarePgm(path, 64); });
  for (const std::string file : {"recording.json", "events.jsonl", "images/000001_left.png"}) {
    const std::string path = dir + "/rec/" + file;
    const std::string before = FileText(path);
    const auto r = RunCommand(kWorkcell + " export-rawlog " + dir + "/rec " + path);
    EXPECT_EQ(r.exit_code, 2) << file << ": " << r.err;
    EXPECT_NE(r.err.find("is the same file as the input"), std::string::npos) << r.err;
    EXPECT_TRUE(FileText(path) == before) << file << " was changed";
  }
  const auto r = RunCommand(kWorkcell + " export-rawlog " + dir + "/rec " + dir + "/out.rawlog");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  std::filesystem::remove_all(dir);
}

// An image OpenCV refuses with an exception (a header claiming 100000 x 100000 px) is that image's error,
// naming it, and the images after it are processed (before: "fatal", exit 1, the batch stopped there).
TEST(CliIntegrationTest, FeaturesReportsAnImageOpenCvRefusesAndGoesOn) {
  const std::string dir = MakeTempDir("features_huge_cli");
  WriteSquarePgm(dir + "/box.pgm", 64);
  WriteHugeHeaderPgm(dir + "/bigdim.pgm");
  const auto r =
      RunCommand(kWorkcell + " features " + dir + "/box.pgm " + dir + "/bigdim.pgm " + dir + "/box.pgm --json");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_EQ(r.err.find("fatal"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("1 of 3 images"), std::string::npos) << r.err;
  std::istringstream lines(r.out);
  std::string line;
  std::vector<nlohmann::json> results;
  while (std::getline(lines, line)) results.push_back(nlohmann::json::parse(line));
  ASSERT_EQ(results.size(), 3u) << r.out;
  EXPECT_TRUE(results[0].contains("lines")) << r.out;
  EXPECT_NE(results[1].value("error", "").find("bigdim.pgm: cannot read the image"), std::string::npos) << r.out;
  EXPECT_TRUE(results[2].contains("lines")) << r.out;
  std::filesystem::remove_all(dir);
}

// replay and export-rawlog: a recorded image OpenCV refuses is an error naming it (before: "fatal").
TEST(CliIntegrationTest, ReplayNamesARecordedImageOpenCvRefuses) {
  const std::string dir = MakeTempDir("replay_huge_cli");
  WriteScanRecording(dir, WriteHugeHeaderPgm);
  std::vector<std::string> commands = {"replay " + dir};
  if (RunCommand(kWorkcell + " --help").out.find("export-rawlog") != std::string::npos) {
    commands.push_back("export-rawlog " + dir + " " + dir + "/out.rawlog");
  }
  for (const std::string& command : commands) {
    const auto r = RunCommand(kWorkcell + " " + command);
    EXPECT_EQ(r.exit_code, 2) << command << ": " << r.err;
    EXPECT_EQ(r.err.find("fatal"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("images/000001_left.png: cannot read the image"), std::string::npos) << r.err;
  }
  EXPECT_FALSE(std::filesystem::exists(dir + "/out.rawlog"));
  std::filesystem::remove_all(dir);
}

// replay: a header whose meta is not an object, or whose meta.points is not a count, is refused naming
// recording.json and the key (before: an uncaught JSON type_error, "fatal", exit 1).
TEST(CliIntegrationTest, ReplayRefusesAMetaOfTheWrongType) {
  const std::string dir = MakeTempDir("replay_meta_cli");
  WriteScanRecording(dir, [](const std::string& path) { WriteSquarePgm(path, 64); });
  for (const std::string meta : {R"("x")", R"({"points": "many"})"}) {
    std::ofstream(dir + "/recording.json")
        << R"({"format": "idi-recording", "version": 1, "kind": "scan", "meta": )" << meta << "}\n";
    const auto r = RunCommand(kWorkcell + " replay " + dir);
    EXPECT_EQ(r.exit_code, 2) << meta << ": " << r.err;
    EXPECT_EQ(r.err.find("fatal"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("recording.json: meta"), std::string::npos) << r.err;
  }
  std::filesystem::remove_all(dir);
}

TEST(CliIntegrationTest, RmpFootprint) {
  const auto r = RunCommand(kRmp + " fov --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j.size(), 2u);
  EXPECT_GT(j[0]["nearest_ground_m"].get<double>(), 0.25);
  const auto bad = RunCommand(kRmp + " fov --height-m -1");
  EXPECT_EQ(bad.exit_code, 2);
}

}  // namespace
}  // namespace idi::test
