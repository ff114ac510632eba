#include "workcell/app/scan_command.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include "shared/util/atomic_file.h"

namespace idi::workcell {
namespace {

namespace fs = std::filesystem;

class ScanCommandTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("scan_cmd_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  // A calibration folder the scan refuses at once (made in the twin of another seed), so that no test
  // here calibrates (minutes): a run that gets that far passed the --out check.
  void MakeOtherSeedCalibration(const std::string& dir) const {
    fs::create_directories(dir);
    ASSERT_TRUE(WriteFileAtomically(dir + "/twin.json", "{\"seed\": 7}\n").ok());
    ASSERT_TRUE(WriteFileAtomically(dir + "/robot1.yaml", "model: rx130-laser-vicki\n").ok());
  }
  // Runs `idi-workcell scan --sim ARGS...`; returns the exit code, and stderr in `err`.
  int Run(std::vector<std::string> args, std::string* err) const {
    CliApp cli("test", "idi-workcell");
    AddScanCommand(cli);
    args.insert(args.begin(), {"idi-workcell", "scan", "--sim"});
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    ::testing::internal::CaptureStderr();
    const int code = RunCli(cli, static_cast<int>(argv.size()), argv.data());
    *err = ::testing::internal::GetCapturedStderr();
    return code;
  }
  fs::path dir_;
};

// An --out folder holding an earlier run's results is refused before any work (exit 2, the folder and
// an entry named): before, the new images, overlays and report were mixed into it. Only the calibration
// folder a run without --calibration keeps in OUT may be there.
TEST_F(ScanCommandTest, AnOutFolderWithResultsIsRefused) {
  MakeOtherSeedCalibration(Path("cal"));
  fs::create_directories(Path("out"));
  ASSERT_TRUE(WriteFileAtomically(Path("out/report.json"), "{}\n").ok());
  std::string err;
  EXPECT_EQ(Run({"--calibration", Path("cal"), "--out", Path("out")}, &err), 2) << err;
  EXPECT_NE(err.find("scan: --out " + Path("out") + ": the folder is not empty (it holds 'report.json'"),
            std::string::npos)
      << err;
  // OUT/calibration alone is the calibration a run without --calibration reuses: the run goes on (to
  // the calibration's own check here).
  MakeOtherSeedCalibration(Path("out2/calibration"));
  EXPECT_EQ(Run({"--out", Path("out2")}, &err), 2) << err;
  EXPECT_EQ(err.find("not empty"), std::string::npos) << err;
  EXPECT_NE(err.find("made in the twin of seed 7, not 1"), std::string::npos) << err;
  // --calibration naming that folder (README's way to reuse it) is the same run.
  EXPECT_EQ(Run({"--calibration", Path("out2/calibration"), "--out", Path("out2")}, &err), 2) << err;
  EXPECT_EQ(err.find("not empty"), std::string::npos) << err;
  EXPECT_NE(err.find("made in the twin of seed 7, not 1"), std::string::npos) << err;
  // With --calibration elsewhere, OUT/calibration is not the run's.
  EXPECT_EQ(Run({"--calibration", Path("cal"), "--out", Path("out2")}, &err), 2) << err;
  EXPECT_NE(err.find("it holds 'calibration'"), std::string::npos) << err;
  // A new folder and an empty one pass the check.
  fs::create_directories(Path("empty"));
  for (const std::string& out : {Path("new"), Path("empty")}) {
    EXPECT_EQ(Run({"--calibration", Path("cal"), "--out", out}, &err), 2) << err;
    EXPECT_NE(err.find("made in the twin of seed 7, not 1"), std::string::npos) << err;
  }
}

}  // namespace
}  // namespace idi::workcell
