#include "rmp/app/sim_render_command.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <system_error>

#include "shared/sim/render/render.h"
#include "shared/util/check.h"
#include "shared/util/units.h"

namespace idi::rmp {
namespace {

// rmp/app/tracks/standard.yaml (a test keeps the two the same).
constexpr const char* kStandardTrackYaml = R"(
tape_width_m: 0.05
speed_mps: 0.5
points_m: [[0, 0], [3.0, 0], [3.0, 2.0], [3.3, 2.52], [3.82, 2.82], [4.4, 2.82], [5.5, 2.82], [5.5, 1.3]]
)";

// The point and heading at arc length s along the centre line.
void PoseAlong(const TrackSpec& track, double s, double* x, double* y, double* yaw) {
  for (std::size_t i = 1; i < track.points_m.size(); ++i) {
    const Vec2d a = track.points_m[i - 1], d = track.points_m[i] - a;
    const double len = d.norm();
    if (s <= len || i + 1 == track.points_m.size()) {
      const Vec2d p = a + std::clamp(s / len, 0.0, 1.0) * d;
      *x = p.x();
      *y = p.y();
      *yaw = std::atan2(d.y(), d.x());
      return;
    }
    s -= len;
  }
}

struct SimRenderCli {
  std::string track, out, config;
  int views = 3;
  bool json = false;
};

Status RunTrackRender(const SimRenderCli& o) {
  if (o.out.empty()) return InvalidArgument("sim render: --out DIR is required");
  RmpConfig config = DefaultRmpConfig();
  if (!o.config.empty()) {
    IDI_ASSIGN_OR_RETURN(config, LoadRmpConfig(o.config));
  }
  TrackSpec track = StandardTrack();
  if (!o.track.empty()) {
    IDI_ASSIGN_OR_RETURN(track, LoadTrackFile(o.track));
  }
  TrackRenderOptions ro;
  ro.views = o.views;
  IDI_ASSIGN_OR_RETURN(const std::vector<TrackView> views, RenderTrackViews(track, config, ro, o.out));
  if (o.json) {
    nlohmann::json j = nlohmann::json::array();
    for (const TrackView& v : views) {
      nlohmann::json images = nlohmann::json::array();
      for (const sim::WrittenImage& w : v.images) {
        images.push_back({{"png", w.png_path}, {"json", w.json_path}, {"width", w.width}, {"height", w.height},
                          {"lines", w.lines}, {"junctions", w.junctions}});
      }
      j.push_back({{"s_m", v.s_m}, {"x_m", v.x_m}, {"y_m", v.y_m}, {"yaw_deg", RadToDeg(v.yaw_rad)}, {"images", images}});
    }
    std::cout << nlohmann::json{{"track", track.source}, {"views", j}}.dump() << "\n";
    return Status::Ok();
  }
  std::cout << "track " << track.source << ":\n";
  for (const TrackView& v : views) {
    std::cout << fmt::format("  vehicle at s = {:.2f} m (x {:.2f} m, y {:.2f} m, yaw {:.1f} deg):\n", v.s_m, v.x_m,
                             v.y_m, RadToDeg(v.yaw_rad));
    for (const sim::WrittenImage& w : v.images) std::cout << "    wrote " << w.Summary() << "\n";
  }
  return Status::Ok();
}

}  // namespace

TrackSpec StandardTrack() {
  auto t = ParseTrackYaml(kStandardTrackYaml, "(standard track)");
  IDI_CHECK(t.ok(), t.status().ToString());
  return *t;
}

Result<std::vector<TrackView>> RenderTrackViews(const TrackSpec& track, const RmpConfig& config,
                                                const TrackRenderOptions& options, const std::string& out_dir) {
  IDI_RETURN_IF_ERROR(track.Check());
  IDI_RETURN_IF_ERROR(config.Check());
  if (options.views < 1 || options.views > 100) return InvalidArgument("sim render: --views must be in 1..100");
  sim::RenderOptions render = config.sim.render;
  IDI_RETURN_IF_ERROR(render.Check());
  TrackSceneOptions so = config.sim.scene;
  so.seed = config.sim.seed;
  IDI_ASSIGN_OR_RETURN(const sim::Scene scene, BuildTrackScene(track, so));
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec || !std::filesystem::is_directory(out_dir)) {
    return IoError(out_dir + ": cannot create the output folder" + (ec ? " (" + ec.message() + ")" : ""));
  }
  const double last = std::max(0.0, track.Length() - 1.0);
  std::vector<TrackView> out;
  for (int k = 0; k < options.views; ++k) {
    TrackView v;
    if (k == 0) {
      track.StartPose(&v.x_m, &v.y_m, &v.yaw_rad);
    } else {
      v.s_m = last * k / std::max(1, options.views - 1);
      PoseAlong(track, v.s_m, &v.x_m, &v.y_m, &v.yaw_rad);
    }
    const Rigid3d world_from_vehicle = Translation(v.x_m, v.y_m, 0.0) * RotZ(v.yaw_rad);
    for (int c = 0; c < 2; ++c) {
      const RigCamera& cam = c == 0 ? config.rig.left : config.rig.right;
      const std::string name = fmt::format("view{}-{}", k, c == 0 ? "left" : "right");
      render.seed = config.sim.seed * 1000003ULL + static_cast<uint64_t>(2 * k + c);
      sim::GroundTruth truth;
      auto image = sim::RenderScene(scene, cam.intrinsics, (world_from_vehicle * cam.vehicle_from_camera).Inverse(),
                                    render, &truth);
      if (!image.ok()) return image.status().WithContext(track.source + ": " + name);
      IDI_ASSIGN_OR_RETURN(sim::WrittenImage w, sim::WriteImageWithTruth(*image, truth, out_dir, name));
      v.images.push_back(std::move(w));
    }
    out.push_back(std::move(v));
  }
  return out;
}

void AddSimRenderCommand(CliApp& cli, CLI::App* sim) {
  auto o = std::make_shared<SimRenderCli>();
  CLI::App* cmd = cli.AddCommand(
      sim, "render",
      "render the vehicle twin's two cameras looking at the taped track from N places along it: "
      "<view>-<camera>.png and its ground truth <view>-<camera>.json (tape edges as lines, corners as "
      "junctions; pixel centres at integers) in DIR",
      [o] { return RunTrackRender(*o); });
  cmd->add_option("--track", o->track,
                  "TRACK.yaml (DESIGN.md §6: tape_width_m, points_m, gaps_m, ...; default: the standard track, as "
                  "rmp/app/tracks/standard.yaml)");
  cmd->add_option("--out", o->out, "output folder (created when missing)")->required();
  cmd->add_option("--views", o->views, "vehicle poses: the start, then evenly along the track (default 3)");
  cmd->add_option("--config", o->config, "rmp.yaml: the rig's cameras and the sim's render and floor options");
  cmd->add_flag("--json", o->json, "print the written files as one JSON object on stdout");
}

}  // namespace idi::rmp
