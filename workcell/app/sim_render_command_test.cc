#include "workcell/app/sim_render_command.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "shared/util/atomic_file.h"

namespace idi::workcell {
namespace {

namespace fs = std::filesystem;

std::string SourceDir() {
  const char* dir = std::getenv("IDI_SOURCE_DIR");
  return dir != nullptr ? dir : ".";
}

class SimRenderCommandTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("idi-sim-render-" + std::to_string(::getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  // Runs `idi-workcell sim render ARGS...` and returns its exit code.
  int Run(std::vector<std::string> args) {
    CliApp cli("test", "idi-workcell");
    AddSimRenderCommand(cli);
    args.insert(args.begin(), {"idi-workcell", "-q", "sim", "render"});
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    return RunCli(cli, static_cast<int>(argv.size()), argv.data());
  }
  fs::path dir_;
};

TEST_F(SimRenderCommandTest, StandardSceneFileIsTheBuiltInDefault) {
  const std::string path = SourceDir() + "/workcell/app/scenes/standard.yaml";
  auto file = sim::LoadWorkcellSceneFile(path);
  ASSERT_TRUE(file.ok()) << file.status().ToString();
  const sim::WorkcellSceneSpec std_scene = sim::StandardWorkcellScene();
  EXPECT_EQ(file->seed, std_scene.seed);
  EXPECT_EQ(file->clutter, std_scene.clutter);
  EXPECT_EQ(file->tiled_floor, std_scene.tiled_floor);
  EXPECT_EQ(file->table.top_centre_world, std_scene.table.top_centre_world);
  EXPECT_EQ(file->table.radius_mm, std_scene.table.radius_mm);
  ASSERT_EQ(file->objects.size(), std_scene.objects.size());
  for (std::size_t i = 0; i < std_scene.objects.size(); ++i) {
    const sim::TableObjectSpec &a = file->objects[i], &b = std_scene.objects[i];
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.shape.kind, b.shape.kind);
    EXPECT_EQ(Vec3d(a.shape.size_x, a.shape.size_y, a.shape.size_z), Vec3d(b.shape.size_x, b.shape.size_y, b.shape.size_z));
    EXPECT_EQ(a.shape.radius, b.shape.radius);
    EXPECT_EQ(a.shape.thickness, b.shape.thickness);
    EXPECT_EQ(a.shape.face_albedos, b.shape.face_albedos);
    EXPECT_EQ(a.at_mm, b.at_mm);
    EXPECT_EQ(a.yaw_deg, b.yaw_deg);
  }
  ASSERT_EQ(file->cameras.size(), std_scene.cameras.size());
  for (std::size_t i = 0; i < std_scene.cameras.size(); ++i) {
    EXPECT_EQ(file->cameras[i].name, std_scene.cameras[i].name);
    EXPECT_EQ(file->cameras[i].camera.params, std_scene.cameras[i].camera.params);
    EXPECT_EQ(file->cameras[i].position_mm, std_scene.cameras[i].position_mm);
    EXPECT_EQ(file->cameras[i].look_at_mm, std_scene.cameras[i].look_at_mm);
  }
  EXPECT_EQ(file->lighting.ambient, std_scene.lighting.ambient);
  ASSERT_EQ(file->lighting.directional.size(), std_scene.lighting.directional.size());
  EXPECT_EQ(file->lighting.directional[0].direction_to_light, std_scene.lighting.directional[0].direction_to_light);
  EXPECT_EQ(file->render.exposure_dn, std_scene.render.exposure_dn);
  EXPECT_EQ(file->render.psf_sigma_px, std_scene.render.psf_sigma_px);
  EXPECT_EQ(file->render.sensor.read_noise_dn, std_scene.render.sensor.read_noise_dn);
  EXPECT_EQ(file->render.sensor.gain_dn_per_electron, std_scene.render.sensor.gain_dn_per_electron);
}

TEST_F(SimRenderCommandTest, WritesOnePngWithItsTruthPerCamera) {
  // A small camera keeps the test fast; the box faces it.
  const std::string scene = dir_.string() + "-scene.yaml";
  ASSERT_TRUE(WriteFileAtomically(scene, R"(
objects: [{name: box, kind: box, size_mm: [110, 80, 70], face_albedos: [0.5, 0.75, 0.9, 0.55, 0.65, 0.8]}]
clutter: 1
cameras:
  - {name: small, width_px: 160, height_px: 120, fx_px: 300, fy_px: 300, cx_px: 79.5, cy_px: 59.5,
     position_mm: [1906, -500, 421], look_at_mm: [2825, -500, -370]}
  - {name: colour, width_px: 96, height_px: 64, fx_px: 200, fy_px: 200, cx_px: 47.5, cy_px: 31.5,
     position_mm: [1906, -600, 421], look_at_mm: [2825, -500, -370]}
image: {color: true}
)").ok());
  ASSERT_EQ(Run({"--scene", scene, "--out", dir_.string()}), 0);
  fs::remove(scene);
  for (const auto& [name, w, h] : {std::tuple<const char*, int, int>{"small", 160, 120}, {"colour", 96, 64}}) {
    const cv::Mat png = cv::imread((dir_ / (std::string(name) + ".png")).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(png.empty()) << name;
    EXPECT_EQ(png.cols, w);
    EXPECT_EQ(png.rows, h);
    EXPECT_EQ(png.channels(), 3);
    std::ifstream in(dir_ / (std::string(name) + ".json"));
    ASSERT_TRUE(in.good()) << name;
    const nlohmann::json truth = nlohmann::json::parse(in);
    EXPECT_EQ(truth["width"], png.cols);
    EXPECT_EQ(truth["height"], png.rows);
    // The box's corners are in the truth, inside the image, where the image is not flat.
    int box_corners = 0;
    for (const auto& j : truth["junctions"]) {
      if (j["object"] != "box" || !j["is_vertex"].get<bool>()) continue;
      const double x = j["xy"][0], y = j["xy"][1];
      EXPECT_TRUE(x > -0.5 && x < w - 0.5 && y > -0.5 && y < h - 0.5);
      ++box_corners;
    }
    EXPECT_GE(box_corners, 4) << name;
  }
}

TEST_F(SimRenderCommandTest, BadInputExitsWithTwoAndWritesNothing) {
  const std::string scene = dir_.string() + "-bad.yaml";
  ASSERT_TRUE(WriteFileAtomically(scene, "noise: {read_noise_dn: -1}\n").ok());
  EXPECT_EQ(Run({"--scene", scene, "--out", dir_.string()}), 2);
  ASSERT_TRUE(WriteFileAtomically(scene, "objects: [{kind: box, size_mm: [50, 50, 50], shiny: true}]\n").ok());
  EXPECT_EQ(Run({"--scene", scene, "--out", dir_.string()}), 2);
  fs::remove(scene);
  EXPECT_EQ(Run({"--scene", "/nonexistent/scene.yaml", "--out", dir_.string()}), 2);
  EXPECT_EQ(Run({"--scene", scene}), 2) << "--out is required";
  EXPECT_FALSE(fs::exists(dir_));
}

// A ground truth that cannot be written (here a folder where small.json goes) fails the run and leaves no
// PNG without its JSON: before, small.png stayed behind.
TEST_F(SimRenderCommandTest, AFailedTruthWriteLeavesNoImageWithoutIt) {
  const std::string scene = dir_.string() + "-scene.yaml";
  ASSERT_TRUE(WriteFileAtomically(scene, R"(
cameras:
  - {name: small, width_px: 96, height_px: 64, fx_px: 200, fy_px: 200, cx_px: 47.5, cy_px: 31.5,
     position_mm: [1906, -500, 421], look_at_mm: [2825, -500, -370]}
)")
                  .ok());
  fs::create_directories(dir_ / "small.json");
  EXPECT_EQ(Run({"--scene", scene, "--out", dir_.string()}), 2);
  fs::remove(scene);
  EXPECT_FALSE(fs::exists(dir_ / "small.png"));
  EXPECT_TRUE(fs::is_directory(dir_ / "small.json")) << "a folder in the way is the user's, not removed";
}

TEST_F(SimRenderCommandTest, HelpNamesTheOptions) {
  CliApp cli("test", "idi-workcell");
  AddSimRenderCommand(cli);
  CLI::App* render = cli.app.get_subcommand("sim")->get_subcommand("render");
  const std::string help = render->help();
  EXPECT_NE(help.find("--scene"), std::string::npos);
  EXPECT_NE(help.find("--out"), std::string::npos);
  EXPECT_NE(help.find("standard workcell scene"), std::string::npos);
}

}  // namespace
}  // namespace idi::workcell
