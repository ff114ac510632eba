#include "rmp/app/sim_render_command.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "rmp/app/rmp_commands.h"
#include "shared/util/atomic_file.h"

namespace idi::rmp {
namespace {

namespace fs = std::filesystem;

class RmpSimRenderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("idi-rmp-sim-render-" + std::to_string(::getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  int Run(std::vector<std::string> args) {
    CliApp cli("test", "idi-rmp");
    AddSimRenderCommand(cli, AddSimRunCommand(cli));
    args.insert(args.begin(), {"idi-rmp", "-q", "sim", "render"});
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    return RunCli(cli, static_cast<int>(argv.size()), argv.data());
  }
  fs::path dir_;
};

TEST_F(RmpSimRenderTest, BuiltInStandardTrackIsTheFile) {
  const char* src = std::getenv("IDI_SOURCE_DIR");
  auto file = LoadTrackFile(std::string(src != nullptr ? src : ".") + "/rmp/app/tracks/standard.yaml");
  ASSERT_TRUE(file.ok()) << file.status().ToString();
  const TrackSpec built_in = StandardTrack();
  EXPECT_EQ(built_in.points_m, file->points_m);
  EXPECT_EQ(built_in.tape_width_m, file->tape_width_m);
  EXPECT_EQ(built_in.speed_mps, file->speed_mps);
  EXPECT_EQ(built_in.gaps_m, file->gaps_m);
}

TEST_F(RmpSimRenderTest, WritesBothCamerasPerViewWithMatchingTruth) {
  // A short straight track with small cameras keeps the test fast.
  const std::string track = dir_.string() + "-track.yaml";
  ASSERT_TRUE(WriteFileAtomically(track, "tape_width_m: 0.05\npoints_m: [[0, 0], [4, 0]]\n").ok());
  const std::string config = dir_.string() + "-rmp.yaml";
  ASSERT_TRUE(WriteFileAtomically(config, R"(
rig:
  width_px: 160
  height_px: 120
  left: {fx_px: 80, fy_px: 80, cx_px: 79.5, cy_px: 59.5, x_m: 0, y_m: 0.15, z_m: 1.2, yaw_deg: 0, pitch_down_deg: 55}
  right: {fx_px: 80, fy_px: 80, cx_px: 79.5, cy_px: 59.5, x_m: 0, y_m: -0.15, z_m: 1.2, yaw_deg: 0, pitch_down_deg: 55}
)").ok());
  const int rc = Run({"--track", track, "--config", config, "--out", dir_.string(), "--views", "2"});
  fs::remove(track);
  fs::remove(config);
  ASSERT_EQ(rc, 0);
  int files = 0;
  for (const char* stem : {"view0-left", "view0-right", "view1-left", "view1-right"}) {
    const cv::Mat png = cv::imread((dir_ / (std::string(stem) + ".png")).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(png.empty()) << stem;
    EXPECT_EQ(png.type(), CV_8UC1);
    std::ifstream in(dir_ / (std::string(stem) + ".json"));
    ASSERT_TRUE(in.good()) << stem;
    const nlohmann::json truth = nlohmann::json::parse(in);
    EXPECT_EQ(truth["width"], png.cols);
    EXPECT_EQ(truth["height"], png.rows);
    EXPECT_EQ(png.cols, 160);
    // The tape ahead is in view: its long edges are truth lines, and the tape is brighter than the floor
    // at the truth's edges' midpoints' inner side is not asserted; the lines must lie in the image.
    int tape_lines = 0;
    for (const auto& l : truth["lines"]) {
      if (l["object"].get<std::string>().find("tape") == std::string::npos) continue;
      ++tape_lines;
      for (const char* end : {"p1", "p2"}) {
        EXPECT_GT(l[end][0].get<double>(), -1.0);
        EXPECT_LT(l[end][0].get<double>(), 160.0);
      }
    }
    EXPECT_GE(tape_lines, 2) << stem;
    ++files;
  }
  EXPECT_EQ(files, 4);
}

TEST_F(RmpSimRenderTest, BadInputExitsWithTwo) {
  const std::string track = dir_.string() + "-bad.yaml";
  ASSERT_TRUE(WriteFileAtomically(track, "tape_width_m: 0.05\npoints_m: [[0, 0], [.nan, 1]]\n").ok());
  EXPECT_EQ(Run({"--track", track, "--out", dir_.string()}), 2);
  ASSERT_TRUE(WriteFileAtomically(track, "tape_width_m: 0.05\npoints_m: [[0, 0], [3, 0]]\ncolour: red\n").ok());
  EXPECT_EQ(Run({"--track", track, "--out", dir_.string()}), 2);
  fs::remove(track);
  EXPECT_EQ(Run({"--track", "/nonexistent/track.yaml", "--out", dir_.string()}), 2);
  EXPECT_EQ(Run({"--views", "0", "--out", dir_.string()}), 2);
  EXPECT_EQ(Run({}), 2) << "--out is required";
  EXPECT_FALSE(fs::exists(dir_ / "view0-left.png"));
}

}  // namespace
}  // namespace idi::rmp
