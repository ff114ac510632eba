#include "workcell/app/reconstruct_command.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "shared/plot/png_file.h"
#include "shared/runtime/yaml_error.h"
#include "shared/util/atomic_file.h"
#include "workcell/procedures/structure.h"

namespace idi::workcell {
namespace {

namespace fs = std::filesystem;

struct ReconstructOptions {
  std::string views_file;
  bool json = false;
  std::string ply;
  std::string overlay_dir;
};

Result<std::vector<double>> Numbers(const YAML::Node& n, std::size_t count, const std::string& where) {
  if (!n || !n.IsSequence() || n.size() != count) {
    return InvalidArgument(where + ": expected a list of " + std::to_string(count) + " numbers");
  }
  std::vector<double> out;
  for (const auto& v : n) {
    double d = 0;
    try {
      d = v.as<double>();
    } catch (const YAML::Exception&) {
      return InvalidArgument(where + ": '" + v.Scalar() + "' is not a number");
    }
    if (!std::isfinite(d)) return InvalidArgument(where + ": values must be finite");
    out.push_back(d);
  }
  return out;
}

// The views of `path`, and (when not null) the image files they were read from.
Result<std::vector<StructureView>> LoadViews(const std::string& path, std::vector<std::string>* image_files) try {
  IDI_ASSIGN_OR_RETURN(const std::string text, ReadFile(path));
  const YAML::Node root = YAML::Load(text);
  if (!root.IsMap() || !root["views"] || !root["views"].IsSequence()) {
    return InvalidArgument(path + ": expected a map with a list 'views'");
  }
  for (const auto& kv : root) {
    if (kv.first.as<std::string>() != "views") {
      return InvalidArgument(fmt::format("{}:{}: unknown key '{}' (expected only 'views')",
                                         path,
                                         kv.first.Mark().line + 1,
                                         kv.first.as<std::string>()));
    }
  }
  const fs::path base = fs::path(path).parent_path();
  std::vector<StructureView> views;
  int index = 0;
  for (const auto& v : root["views"]) {
    const std::string where = fmt::format("{}:{}: views[{}]", path, v.Mark().line + 1, index);
    if (!v.IsMap()) return InvalidArgument(where + ": expected a map");
    for (const auto& kv : v) {
      const std::string key = kv.first.as<std::string>();
      if (key != "image" && key != "K" && key != "distortion" && key != "cam_from_world") {
        return InvalidArgument(where + ": unknown key '" + key + "'");
      }
    }
    if (!v["image"]) return InvalidArgument(where + ": missing 'image'");
    StructureView sv;
    const fs::path image_path = base / v["image"].as<std::string>();
    sv.name = image_path.filename().string();
    auto image = plot::ReadImageFile(image_path.string(), cv::IMREAD_GRAYSCALE);
    if (!image.ok()) return Status(image.status().code(), where + ": " + image.status().message());
    sv.image = std::move(*image);
    if (image_files) image_files->push_back(image_path.string());
    IDI_ASSIGN_OR_RETURN(const auto k, Numbers(v["K"], 9, where + ".K"));
    if (k[1] != 0 || k[3] != 0 || k[6] != 0 || k[7] != 0 || k[8] != 1 || !(k[0] > 0) || !(k[4] > 0)) {
      return InvalidArgument(where + ".K: expected [fx, 0, cx, 0, fy, cy, 0, 0, 1] with fx, fy > 0");
    }
    // The principal point of a real lens and sensor lies near the image's middle (a few percent off at
    // most). One more than a quarter of the image off its centre (pixel centres at integers) is a K for
    // another image size (1280 x 960 on 640 x 480 images puts it in a corner) or a wrong K.
    const double centre_x = 0.5 * (sv.image.cols - 1), centre_y = 0.5 * (sv.image.rows - 1);
    if (!(std::abs(k[2] - centre_x) <= 0.25 * sv.image.cols && std::abs(k[5] - centre_y) <= 0.25 * sv.image.rows)) {
      return InvalidArgument(fmt::format(
          "{}.K: the principal point ({}, {}) px is not near the middle of the {} x {} px image {} (expected within a "
          "quarter of its size of ({}, {})): is K for another image size?",
          where,
          k[2],
          k[5],
          sv.image.cols,
          sv.image.rows,
          image_path.string(),
          centre_x,
          centre_y));
    }
    sv.camera.width = sv.image.cols;
    sv.camera.height = sv.image.rows;
    sv.camera.params = {k[0], k[4], k[2], k[5], 0, 0, 0, 0, 0};
    if (v["distortion"]) {
      IDI_ASSIGN_OR_RETURN(const auto d, Numbers(v["distortion"], 5, where + ".distortion"));
      for (int j = 0; j < 5; ++j) sv.camera.params[static_cast<std::size_t>(kK1 + j)] = d[static_cast<std::size_t>(j)];
    }
    IDI_ASSIGN_OR_RETURN(const auto m, Numbers(v["cam_from_world"], 12, where + ".cam_from_world"));
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) sv.cam_from_world.rotation(r, c) = m[static_cast<std::size_t>(4 * r + c)];
      sv.cam_from_world.translation(r) = m[static_cast<std::size_t>(4 * r + 3)];
    }
    views.push_back(std::move(sv));
    ++index;
  }
  return views;
} catch (const YAML::Exception& e) {
  return YamlError(path, e);
}

// Each view's overlay file: <stem>_model.png, views of the same file name (left/0001.png,
// right/0001.png) numbered <stem>_2_model.png and on (UniqueOutputNames).
std::vector<std::string> OverlayFiles(const std::vector<StructureView>& views, const std::string& dir) {
  std::vector<std::string> names;
  for (const StructureView& v : views) names.push_back(v.name);
  std::vector<std::string> files;
  for (const std::string& name : UniqueOutputNames(names, "_model.png"))
    files.push_back((fs::path(dir) / name).string());
  return files;
}

Status RunReconstruct(const ReconstructOptions& o) {
  std::vector<std::string> image_files;
  IDI_ASSIGN_OR_RETURN(const std::vector<StructureView> views, LoadViews(o.views_file, &image_files));
  const std::vector<std::string> overlays =
      o.overlay_dir.empty() ? std::vector<std::string>() : OverlayFiles(views, o.overlay_dir);
  {
    // Before the work, no output may replace an input (the views file, an image) or another output.
    std::vector<NamedFile> inputs = {{"--views", o.views_file}};
    for (const std::string& f : image_files) inputs.push_back({"image", f});
    std::vector<NamedFile> outputs = {{"--ply", o.ply}};
    for (const std::string& f : overlays) outputs.push_back({"--overlay", f});
    IDI_RETURN_IF_ERROR(CheckDistinctFiles(inputs, outputs, "reconstruct"));
    IDI_RETURN_IF_ERROR(CheckOutputFile(o.ply, "reconstruct: --ply"));
  }
  if (!o.overlay_dir.empty()) {
    // Before the work: a folder that cannot be made is known now, not after the reconstruction.
    std::error_code ec;
    fs::create_directories(o.overlay_dir, ec);
    if (ec) return IoError(fmt::format("--overlay {}: cannot create the folder: {}", o.overlay_dir, ec.message()));
  }
  spdlog::info("reconstruct: {} views from {}", views.size(), o.views_file);
  IDI_ASSIGN_OR_RETURN(const StructureResult r, ReconstructStructure(views, StructureOptions{}));
  spdlog::info("reconstruct: {} points, {} edges; features {:.1f} ms, correspondence {:.1f} ms, adjustment {:.1f} ms "
               "(reprojection RMS {:.3f} -> {:.3f} px)",
               r.model.points.size(), r.model.edges.size(), r.features_ms, r.correspondence_ms, r.adjustment_ms,
               r.adjustment.initial_rms_px, r.adjustment.final_rms_px);
  const nlohmann::json out = StructureModelJson(r.model);
  if (!o.ply.empty()) IDI_RETURN_IF_ERROR(WriteFileAtomically(o.ply, ModelToPly(r.model)));
  for (std::size_t v = 0; v < overlays.size(); ++v) {
    IDI_RETURN_IF_ERROR(plot::WritePngFile(overlays[v], DrawModelOverlay(views[v], r.model, &r.features[v])));
  }
  if (o.json) {
    std::cout << out.dump() << "\n";
  } else {
    for (const ModelPoint& p : r.model.points) {
      std::cout << fmt::format("point {:3d}  {:10.3f} {:10.3f} {:10.3f} mm  views {}  rms {:.3f} px\n", p.id, p.xyz.x(),
                               p.xyz.y(), p.xyz.z(), p.observations.size(), p.reprojection_rms_px);
    }
    std::cout << fmt::format("{} edges\n", r.model.edges.size());
  }
  return Status::Ok();
}

}  // namespace

void AddReconstructCommand(CliApp& cli) {
  auto o = std::make_shared<ReconstructOptions>();
  CLI::App* cmd = cli.AddCommand(&cli.app, "reconstruct",
                                 "3D points and edges from several calibrated views (EMPL lines, IDI points, bundle "
                                 "correspondence, triangulation, bundle adjustment)",
                                 [o] { return RunReconstruct(*o); });
  cmd->add_option("--views", o->views_file,
                  "VIEWS.yaml: views: [{image, K: [9], distortion: [k1,k2,p1,p2,k3], cam_from_world: [12, 3x4 mm]}]")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_flag("--json", o->json, "print {points, edges} as JSON on stdout");
  cmd->add_option("--ply", o->ply, "write the model as PLY (vertices and edges)");
  cmd->add_option("--overlay", o->overlay_dir, "write each view with the model drawn into it (PNG)");
}

}  // namespace idi::workcell
