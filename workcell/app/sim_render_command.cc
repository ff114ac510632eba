#include "workcell/app/sim_render_command.h"

#include <filesystem>
#include <iostream>
#include <memory>
#include <system_error>

#include <nlohmann/json.hpp>

namespace idi::workcell {
namespace {

struct SimRenderCli {
  std::string scene, out;
  bool json = false;
};

Status RunSimRender(const SimRenderCli& o) {
  if (o.out.empty()) return InvalidArgument("sim render: --out DIR is required");
  sim::WorkcellSceneSpec spec = sim::StandardWorkcellScene();
  if (!o.scene.empty()) {
    IDI_ASSIGN_OR_RETURN(spec, sim::LoadWorkcellSceneFile(o.scene));
  }
  IDI_ASSIGN_OR_RETURN(const std::vector<sim::WrittenImage> written, RenderWorkcellScene(spec, o.out));
  if (o.json) {
    nlohmann::json j = nlohmann::json::array();
    for (const sim::WrittenImage& w : written) {
      j.push_back({{"png", w.png_path}, {"json", w.json_path}, {"width", w.width}, {"height", w.height},
                   {"color", w.color}, {"lines", w.lines}, {"junctions", w.junctions}});
    }
    std::cout << nlohmann::json{{"scene", spec.source}, {"images", j}}.dump() << "\n";
  } else {
    std::cout << "scene " << spec.source << ":\n";
    for (const sim::WrittenImage& w : written) std::cout << "  wrote " << w.Summary() << "\n";
  }
  return Status::Ok();
}

}  // namespace

Result<std::vector<sim::WrittenImage>> RenderWorkcellScene(const sim::WorkcellSceneSpec& spec,
                                                           const std::string& out_dir) {
  IDI_ASSIGN_OR_RETURN(const sim::BuiltWorkcellScene built, sim::BuildWorkcellScene(spec));
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec || !std::filesystem::is_directory(out_dir)) {
    return IoError(out_dir + ": cannot create the output folder" + (ec ? " (" + ec.message() + ")" : ""));
  }
  std::vector<sim::WrittenImage> written;
  for (const sim::SceneView& v : built.views) {
    sim::GroundTruth truth;
    auto image = sim::RenderScene(built.scene, v.camera, v.cam_from_world, v.render, &truth);
    if (!image.ok()) return image.status().WithContext(spec.source + ": camera '" + v.name + "'");
    IDI_ASSIGN_OR_RETURN(sim::WrittenImage w, sim::WriteImageWithTruth(*image, truth, out_dir, v.name));
    written.push_back(std::move(w));
  }
  return written;
}

void AddSimRenderCommand(CliApp& cli) {
  CLI::App* sim = nullptr;
  for (CLI::App* sub : cli.app.get_subcommands([](CLI::App* a) { return a->get_name() == "sim"; })) sim = sub;
  if (sim == nullptr) {
    sim = cli.app.add_subcommand("sim", "tools of the digital twin (rendered example images)");
    sim->require_subcommand(1);
  }
  auto o = std::make_shared<SimRenderCli>();
  CLI::App* cmd = cli.AddCommand(
      sim, "render",
      "render the workcell twin's scene from each of its cameras: <camera>.png and its ground truth "
      "<camera>.json (lines, junctions, spots, curves; pixel centres at integers) in DIR",
      [o] { return RunSimRender(*o); });
  cmd->add_option("--scene", o->scene,
                  "scene YAML: table objects (box, prism, bracket, cylinder), clutter, cameras, lighting, optics, "
                  "noise, seed; keys not given keep the standard scene's values (default: the standard workcell "
                  "scene, as workcell/app/scenes/standard.yaml)");
  cmd->add_option("--out", o->out, "output folder (created when missing)")->required();
  cmd->add_flag("--json", o->json, "print the written files as one JSON object on stdout");
}

}  // namespace idi::workcell
