#include "rmp/app/fov_command.h"

#include <fmt/format.h>

#include <algorithm>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "rmp/vehicle/camera_rig.h"
#include "shared/util/units.h"

namespace idi::rmp {
namespace {

struct FovOptions {
  double height_m = 1.0;
  double pitch_down_deg = 40.0;
  double baseline_m = 0.30;
  double forward_m = 0.25;
  double toe_in_deg = 0.0;
  double fx_px = 600.0;
  bool json = false;
};

Status RunFov(const FovOptions& o) {
  if (!(o.height_m > 0) || !(o.fx_px > 0) || !(o.pitch_down_deg > -89 && o.pitch_down_deg < 89)) {
    return InvalidArgument("--height-m and --fx-px must be positive and --pitch-down-deg within (-89, 89)");
  }
  nlohmann::json out = nlohmann::json::array();
  for (const double side : {+1.0, -1.0}) {
    RigCamera cam;
    cam.intrinsics.params = {o.fx_px, o.fx_px, 319.5, 239.5, 0, 0, 0, 0, 0};
    cam.vehicle_from_camera = LookAheadCameraPose(o.forward_m, side * o.baseline_m / 2, o.height_m,
                                                  -side * DegToRad(o.toe_in_deg), DegToRad(o.pitch_down_deg));
    const auto poly = GroundFootprint(cam);
    double near_x = 1e9, far_x = -1e9;
    for (const Vec2d& p : poly) {
      near_x = std::min(near_x, p.x());
      far_x = std::max(far_x, p.x());
    }
    nlohmann::json cam_json;
    cam_json["camera"] = side > 0 ? "left" : "right";
    cam_json["nearest_ground_m"] = near_x;
    cam_json["farthest_ground_m"] = far_x;
    nlohmann::json pts = nlohmann::json::array();
    for (const Vec2d& p : poly) pts.push_back({p.x(), p.y()});
    cam_json["footprint_m"] = pts;
    out.push_back(cam_json);
    if (!o.json) {
      std::cout << fmt::format("{} camera: sees the ground from {:.2f} m to {:.2f} m ahead ({} footprint points)\n",
                               cam_json["camera"].get<std::string>(), near_x, far_x, poly.size());
    }
  }
  if (o.json) {
    std::cout << out.dump() << "\n";
  }
  return Status::Ok();
}

}  // namespace

void AddFovCommand(CliApp& cli) {
  auto o = std::make_shared<FovOptions>();
  CLI::App* cmd = cli.AddCommand(&cli.app, "fov", "ground footprint of the two fixed cameras",
                                 [o] { return RunFov(*o); });
  cmd->add_option("--height-m", o->height_m, "camera height above the ground")->capture_default_str();
  cmd->add_option("--pitch-down-deg", o->pitch_down_deg, "camera pitch below horizontal")->capture_default_str();
  cmd->add_option("--baseline-m", o->baseline_m, "distance between the cameras")->capture_default_str();
  cmd->add_option("--forward-m", o->forward_m, "cameras ahead of the wheel axle")->capture_default_str();
  cmd->add_option("--toe-in-deg", o->toe_in_deg, "each camera turned towards the centre line")->capture_default_str();
  cmd->add_option("--fx-px", o->fx_px, "focal length in pixels (640x480 images)")->capture_default_str();
  cmd->add_flag("--json", o->json, "print JSON on stdout");
}

}  // namespace idi::rmp
