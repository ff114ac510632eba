#include "shared/runtime/param_file.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>

#include "shared/kinematics/rx130.h"
#include "shared/util/atomic_file.h"

namespace idi {
namespace {

namespace fs = std::filesystem;

class ParamFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("idi_param_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A valid robot file, with `replace` substituted for the line starting with `key`.
  std::string WriteRobotFile(const std::string& key = "", const std::string& replace = "") {
    ParamSet robot = Rx130Nominal();
    robot.set_file_value(kA3, 625.5);
    robot.set_stddev(kA3, 0.002);
    const std::string path = (dir_ / "robot.yaml").string();
    EXPECT_TRUE(SaveParamFile(path, robot, "rx130").ok());
    if (key.empty()) {
      return path;
    }
    std::ifstream in(path);
    std::string line, text;
    while (std::getline(in, line)) {
      if (line.rfind(key + ":", 0) == 0) {
        line = replace;
      }
      text += line + "\n";
    }
    EXPECT_TRUE(WriteFileAtomically(path, text).ok());
    return path;
  }

  fs::path dir_;
};

TEST_F(ParamFileTest, RoundTripKeepsValuesAndStd) {
  const std::string path = WriteRobotFile();
  const auto r = LoadParamFile(path, Rx130ParamSpecs());
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_NEAR(r->file_value(kA3), 625.5, 1e-12);
  EXPECT_NEAR(r->file_stddev(kA3), 0.002, 1e-15);
  EXPECT_NEAR(r->file_value(kAlpha4), -90.0, 1e-12);
  EXPECT_TRUE(std::isnan(r->stddev(kA2)));
}

// What the loader would refuse is not written: a value that is not finite, a length beyond the
// loader's bound, or a parameter whose std is infinite (the data did not determine it). An unknown std (NaN) is left
// out, as before.
TEST_F(ParamFileTest, AnUndeterminedParameterIsNotWritten) {
  ParamSet robot = Rx130Nominal();
  robot.set_stddev(kA3, std::numeric_limits<double>::infinity());
  robot.set_stddev(kD4, std::numeric_limits<double>::infinity());
  const std::string path = (dir_ / "robot.yaml").string();
  Status st = SaveParamFile(path, robot, "rx130");
  EXPECT_EQ(st.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(st.message().find("robot.yaml: not written: the data do not determine a3_mm, d4_mm"), std::string::npos)
      << st.ToString();
  EXPECT_FALSE(fs::exists(path));
  robot.set_stddev(kA3, 0.1);
  robot.set_stddev(kD4, 0.1);
  robot.set_value(kA2, std::numeric_limits<double>::quiet_NaN());
  st = SaveParamFile(path, robot, "rx130");
  EXPECT_NE(st.message().find("the values of a2_mm are not finite"), std::string::npos) << st.ToString();
  robot.set_value(kA2, 0.0);
  // A length the loader refuses (beyond kMaxParamLengthM; 1e6 in either internal unit).
  robot.set_value(kA3, 1e6);
  st = SaveParamFile(path, robot, "rx130");
  EXPECT_NE(st.message().find("the lengths a3_mm are beyond 100 m"), std::string::npos) << st.ToString();
  EXPECT_FALSE(fs::exists(path));
  robot.set_value(kA3, Rx130Nominal().value(kA3));
  robot.set_stddev(kA2, std::numeric_limits<double>::quiet_NaN());
  ASSERT_TRUE(SaveParamFile(path, robot, "rx130").ok());
  EXPECT_TRUE(LoadParamFile(path, Rx130ParamSpecs()).ok());
}

TEST_F(ParamFileTest, MissingKeyIsRejectedNamingFileAndKey) {
  const std::string path = WriteRobotFile("d4_mm", "");
  const auto r = LoadParamFile(path, Rx130ParamSpecs());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("robot.yaml"), std::string::npos) << r.status().message();
  EXPECT_NE(r.status().message().find("missing key 'd4_mm'"), std::string::npos) << r.status().message();
}

TEST_F(ParamFileTest, UnknownKeyIsRejected) {
  const std::string path = WriteRobotFile("d4_mm", "d4_mm: 625\nd7_mm: 3");
  const auto r = LoadParamFile(path, Rx130ParamSpecs());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("unknown key 'd7_mm'"), std::string::npos) << r.status().message();
  EXPECT_NE(r.status().message().find("robot.yaml:"), std::string::npos) << r.status().message();
}

TEST_F(ParamFileTest, WrongUnitSuffixIsRejected) {
  const std::string path = WriteRobotFile("a3_mm", "a3_deg: 625");
  const auto r = LoadParamFile(path, Rx130ParamSpecs());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("key 'a3_deg': wrong unit, a3 is in mm (expected key 'a3_mm')"),
            std::string::npos)
      << r.status().message();
}

TEST_F(ParamFileTest, NanIsRejected) {
  for (const std::string bad : {"alpha5_deg: .nan", "alpha5_deg: {value: .inf}", "alpha5_deg: {value: 90, std: .nan}"}) {
    const std::string path = WriteRobotFile("alpha5_deg", bad);
    const auto r = LoadParamFile(path, Rx130ParamSpecs());
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_NE(r.status().message().find("alpha5_deg"), std::string::npos) << r.status().message();
    EXPECT_NE(r.status().message().find("not a finite number"), std::string::npos) << r.status().message();
  }
}

// A finite but absurd length (1.7e308 mm) overflowed the forward kinematics into inf and NaN poses: a
// length beyond 100 m is refused, naming the file, the line and the key.
TEST_F(ParamFileTest, ALengthBeyondAHundredMetresIsRejected) {
  for (const std::string bad : {"a3_mm: {value: 1.7e308, std: 0.1}", "a3_mm: -100000.5"}) {
    const std::string path = WriteRobotFile("a3_mm", bad);
    const auto r = LoadParamFile(path, Rx130ParamSpecs());
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_EQ(r.status().code(), StatusCode::kOutOfRange) << r.status().ToString();
    EXPECT_NE(r.status().message().find("robot.yaml:7: key 'a3_mm': "), std::string::npos) << r.status().message();
    EXPECT_NE(r.status().message().find("a length is at most 100000 mm, 100 m,"), std::string::npos)
        << r.status().message();
  }
  // Up to the bound, and any angle, are read.
  EXPECT_TRUE(LoadParamFile(WriteRobotFile("a3_mm", "a3_mm: -100000"), Rx130ParamSpecs()).ok());
  EXPECT_TRUE(LoadParamFile(WriteRobotFile("theta3_deg", "theta3_deg: 1e300"), Rx130ParamSpecs()).ok());
}

// A file of another model (a laser file given for the arm) is refused naming the file and the model
// expected; a file without a model is read.
TEST_F(ParamFileTest, AFileOfAnotherModelIsRejected) {
  const std::string path = WriteRobotFile();  // model: rx130
  ParamFileOptions o;
  o.models = {"laser", "rx130-laser-vicki"};
  const auto r = LoadParamFile(path, Rx130ParamSpecs(), o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(
      r.status().message().find(
          "robot.yaml:1: model 'rx130' is not the one expected here (expected model: laser or rx130-laser-vicki)"),
      std::string::npos)
      << r.status().message();
  o.models = {"rx130"};
  EXPECT_TRUE(LoadParamFile(path, Rx130ParamSpecs(), o).ok());
  const std::string unnamed = WriteRobotFile("model", "");
  o.models = {"laser"};
  EXPECT_TRUE(LoadParamFile(unnamed, Rx130ParamSpecs(), o).ok());
}

TEST_F(ParamFileTest, NonNumberAndMalformedYamlAreRejected) {
  std::string path = WriteRobotFile("a2_mm", "a2_mm: twelve");
  auto r = LoadParamFile(path, Rx130ParamSpecs());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("'twelve' is not a number"), std::string::npos) << r.status().message();
  path = WriteRobotFile("a2_mm", "a2_mm: [1, 2");
  r = LoadParamFile(path, Rx130ParamSpecs());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("malformed YAML"), std::string::npos) << r.status().message();
  r = LoadParamFile((dir_ / "absent.yaml").string(), Rx130ParamSpecs());
  EXPECT_EQ(r.status().code(), StatusCode::kNotFound);
  // A key that is not a name (a list): an error naming the file, not a YAML exception.
  path = WriteRobotFile("a2_mm", "[a2_mm]: 3");
  r = LoadParamFile(path, Rx130ParamSpecs());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find(path), std::string::npos) << r.status().message();
}

}  // namespace
}  // namespace idi
