#include "workcell/app/calibrate_ptu_command.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "shared/calib/ptu/ptu_simulation.h"
#include "shared/util/atomic_file.h"
#include "workcell/procedures/ptu_files.h"

namespace idi::workcell {
namespace {

namespace fs = std::filesystem;

class CalibratePtuCommandTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("ptu_cmd_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    calib::PtuSyntheticOptions so;
    so.seed = 12;
    so.plan.candidates = 120;
    so.plan.validation_poses = 20;
    auto d = calib::SimulatePtuDataset(so);
    ASSERT_TRUE(d.ok()) << d.status().ToString();
    data_ = *d;
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  CalibratePtuOptions FileRun() const {
    CalibratePtuOptions o;
    o.observations = Path("obs.csv");
    o.validate = Path("val.csv");
    o.out = Path("ptu.yaml");
    o.report = Path("report.json");
    o.plots = Path("plots");
    return o;
  }
  void ExpectNothingWritten() const {
    EXPECT_FALSE(fs::exists(Path("ptu.yaml")));
    EXPECT_FALSE(fs::exists(Path("report.json")));
    EXPECT_FALSE(fs::exists(Path("plots")));
  }
  fs::path dir_;
  calib::PtuSyntheticData data_;
};

TEST_F(CalibratePtuCommandTest, CalibratesFromFilesAndWritesEverything) {
  ASSERT_TRUE(WritePtuObservations(Path("obs.csv"), data_.calibration).ok());
  ASSERT_TRUE(WritePtuObservations(Path("val.csv"), data_.validation).ok());
  const Status st = RunCalibratePtu(FileRun());
  ASSERT_TRUE(st.ok()) << st.ToString();
  // The YAML reads back: both cameras, parameters near the truth.
  const auto models = LoadPtuCalibration(Path("ptu.yaml"));
  ASSERT_TRUE(models.ok()) << models.status().ToString();
  ASSERT_EQ(models->size(), 2u);
  for (const auto& m : *models) {
    const calib::PtuCameraModel& t = data_.truth[m.side == BiclopsSide::kLeft ? 0 : 1];
    EXPECT_NEAR(m.ptu.value(kPtuTheta1), t.ptu.value(kPtuTheta1), DegToRad(1.0));
    EXPECT_NEAR(m.intrinsics.value(kFx), t.intrinsics.value(kFx), 10.0);
  }
  const auto yaml = ReadFile(Path("ptu.yaml"));
  ASSERT_TRUE(yaml.ok());
  EXPECT_NE(yaml->find("theta1_deg: {value: "), std::string::npos);
  EXPECT_NE(yaml->find("point_y_mm: {value: "), std::string::npos);
  EXPECT_NE(yaml->find("validation_rms_px"), std::string::npos);
  const auto text = ReadFile(Path("report.json"));
  ASSERT_TRUE(text.ok());
  const nlohmann::json report = nlohmann::json::parse(*text);
  ASSERT_EQ(report["point_mm"].size(), 3u);
  EXPECT_NEAR(report["point_mm"][1].get<double>(), data_.point_mm.y(), 1.0);
  EXPECT_LT(report["residual_rms_px"].get<double>(), 0.3);
  EXPECT_LT(report["validation_rms_px"].get<double>(), 0.3);
  EXPECT_EQ(report["cameras"].size(), 2u);
  EXPECT_TRUE(fs::exists(Path("plots/ptu_left_errors.png")));
  EXPECT_TRUE(fs::exists(Path("plots/ptu_right_errors.png")));
  // A previous result as start values gives the same answer.
  CalibratePtuOptions again = FileRun();
  again.start = Path("ptu.yaml");
  again.out = Path("ptu2.yaml");
  ASSERT_TRUE(RunCalibratePtu(again).ok());
}

TEST_F(CalibratePtuCommandTest, BadDataGivesAClearMessageAndWritesNothing) {
  const std::string csv = calib::FormatPtuObservationsCsv(data_.calibration);
  ASSERT_TRUE(WritePtuObservations(Path("val.csv"), data_.validation).ok());
  struct Case {
    std::string name, text, expect;
  };
  // Line 6 of the file is observation 5 (header on line 1).
  std::vector<std::string> lines;
  for (std::size_t pos = 0, end; pos < csv.size(); pos = end + 1) {
    end = csv.find('\n', pos);
    lines.push_back(csv.substr(pos, end - pos));
  }
  auto join = [](const std::vector<std::string>& ls) {
    std::string s;
    for (const auto& l : ls) s += l + "\n";
    return s;
  };
  std::vector<Case> cases;
  {  // the spot missing in an image
    auto ls = lines;
    ls[5] = ls[5].substr(0, ls[5].rfind(',', ls[5].rfind(',') - 1)) + ",,";
    cases.push_back({"missing", join(ls), "obs.csv:6: u_px is empty: the spot was not found"});
  }
  {  // the spot doubled in an image
    auto ls = lines;
    ls.insert(ls.begin() + 6, ls[5].substr(0, ls[5].rfind(',')) + ",1.5");
    cases.push_back({"doubled", join(ls), "obs.csv:7: a second spot in the same"});
  }
  {  // a pose outside the PTU's range
    calib::PtuObservation far = data_.calibration[3];
    far.pan_rad = DegToRad(175.0);
    auto obs = data_.calibration;
    obs[3] = far;
    cases.push_back({"range", calib::FormatPtuObservationsCsv(obs), "obs.csv:5: pan = 175.0000 deg is outside"});
  }
  {  // too few poses
    std::vector<calib::PtuObservation> few(data_.calibration.begin(), data_.calibration.begin() + 30);
    cases.push_back({"few", calib::FormatPtuObservationsCsv(few), "too few poses"});
  }
  for (const Case& c : cases) {
    ASSERT_TRUE(WriteFileAtomically(Path("obs.csv"), c.text).ok());
    const Status st = RunCalibratePtu(FileRun());
    ASSERT_FALSE(st.ok()) << c.name;
    EXPECT_NE(st.message().find(c.expect), std::string::npos) << c.name << ": " << st.message();
    ExpectNothingWritten();
  }
  // A missing file and a missing --out.
  CalibratePtuOptions o = FileRun();
  o.observations = Path("nope.csv");
  EXPECT_EQ(RunCalibratePtu(o).code(), StatusCode::kNotFound);
  o.out.clear();
  EXPECT_EQ(RunCalibratePtu(o).code(), StatusCode::kInvalidArgument);
  ExpectNothingWritten();
}

// A result file of another model (a robot calibration given as --start, a file edited by hand) is refused,
// naming the file, the line and both models, as LoadParamFile refuses one; a file without `model` is read.
TEST_F(CalibratePtuCommandTest, AStartFileOfAnotherModelIsRefused) {
  calib::PtuCalibrationResult r;
  calib::PtuCameraCalibration left;
  left.model = calib::PtuCameraModel::Nominal(BiclopsSide::kLeft);
  r.cameras.push_back(left);
  ASSERT_TRUE(WritePtuCalibration(Path("ptu.yaml"), r, nullptr).ok());
  auto text = ReadFile(Path("ptu.yaml"));
  ASSERT_TRUE(text.ok());
  ASSERT_EQ(text->rfind("model: biclops-ptu\n", 0), 0u) << *text;
  ASSERT_TRUE(LoadPtuCalibration(Path("ptu.yaml")).ok());
  const std::string body = text->substr(text->find('\n') + 1);
  ASSERT_TRUE(WriteFileAtomically(Path("other.yaml"), "model: rx130-laser-vicki\n" + body).ok());
  const auto other = LoadPtuCalibration(Path("other.yaml"));
  ASSERT_FALSE(other.ok());
  EXPECT_EQ(other.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(other.status().message().find(Path("other.yaml") +
                                          ":1: model 'rx130-laser-vicki' is not the one expected here (expected "
                                          "model: biclops-ptu)"),
            std::string::npos)
      << other.status().message();
  ASSERT_TRUE(WriteFileAtomically(Path("bare.yaml"), body).ok());
  EXPECT_TRUE(LoadPtuCalibration(Path("bare.yaml")).ok());
}

TEST_F(CalibratePtuCommandTest, SimRunsTheProcedureInTheTwin) {
  CalibratePtuOptions o;
  o.sim = true;
  o.seed = 3;
  o.poses = 40;
  o.validation_poses = 20;
  o.out = Path("ptu.yaml");
  o.report = Path("report.json");
  o.observations = Path("acquired.csv");
  o.validate = Path("held_out.csv");
  const Status st = RunCalibratePtu(o);
  ASSERT_TRUE(st.ok()) << st.ToString();
  const auto text = ReadFile(Path("report.json"));
  ASSERT_TRUE(text.ok());
  const nlohmann::json report = nlohmann::json::parse(*text);
  EXPECT_LT(report["twin"]["point_error_mm"].get<double>(), 1.0);
  EXPECT_EQ(report["plan"]["poses"].get<int>(), 40);
  // The acquired data are the contract's CSV and calibrate again from the file.
  const auto acquired = ReadPtuObservations(Path("acquired.csv"));
  ASSERT_TRUE(acquired.ok()) << acquired.status().ToString();
  EXPECT_EQ(acquired->size(), 80u);
  CalibratePtuOptions again;
  again.observations = Path("acquired.csv");
  again.validate = Path("held_out.csv");
  again.out = Path("again.yaml");
  EXPECT_TRUE(RunCalibratePtu(again).ok());
}

}  // namespace
}  // namespace idi::workcell
