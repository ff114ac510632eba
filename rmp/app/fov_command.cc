#include "rmp/app/fov_command.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "rmp/vehicle/camera_rig.h"
#include "shared/util/units.h"

namespace idi::rmp {
namespace {

// The footprint's border cut at GroundFootprint's usual range (what the planner keeps the track inside).
constexpr double kFootprintRangeM = 15.0;
// The same border cut this far away: a ray that meets no ground closer (at most 100 m up, within 2e-5 rad
// of the horizon or above it) sees to the horizon.
constexpr double kHorizonRangeM = 1e7;

// `value` within the interval from lo to hi, each end open or closed; otherwise InvalidArgument naming the
// option (a non-finite value is in no interval).
Status CheckRange(const char* option, double value, double lo, bool lo_open, double hi, bool hi_open) {
  const bool above_lo = lo_open ? value > lo : value >= lo;
  const bool below_hi = hi_open ? value < hi : value <= hi;
  if (std::isfinite(value) && above_lo && below_hi) return Status::Ok();
  return InvalidArgument(fmt::format("{} must be a finite number in {}{:g}, {:g}{}, got {}",
                                     option,
                                     lo_open ? "(" : "[",
                                     lo,
                                     hi,
                                     hi_open ? ")" : "]",
                                     value));
}

Status RunFov(const FovOptions& o) {
  IDI_ASSIGN_OR_RETURN(const std::vector<CameraGroundView> views, ComputeFov(o));
  nlohmann::json out = nlohmann::json::array();
  for (const CameraGroundView& v : views) {
    nlohmann::json cam_json;
    cam_json["camera"] = v.camera;
    cam_json["sees_ground"] = v.sees_ground;
    cam_json["to_horizon"] = v.to_horizon;
    // null: no such distance (no ground seen, or ground seen to the horizon).
    cam_json["nearest_ground_m"] = v.sees_ground ? nlohmann::json(v.nearest_ground_m) : nlohmann::json();
    cam_json["farthest_ground_m"] =
        v.sees_ground && !v.to_horizon ? nlohmann::json(v.farthest_ground_m) : nlohmann::json();
    nlohmann::json pts = nlohmann::json::array();
    for (const Vec2d& p : v.footprint_m) pts.push_back({p.x(), p.y()});
    cam_json["footprint_m"] = pts;
    out.push_back(cam_json);
    if (o.json) continue;
    if (!v.sees_ground) {
      std::cout << fmt::format("{} camera: does not see the ground (the whole image is at or above the horizon)\n",
                               v.camera);
    } else if (v.to_horizon) {
      std::cout << fmt::format(
          "{} camera: sees the ground from {:.2f} m ahead to the horizon\n", v.camera, v.nearest_ground_m);
    } else {
      std::cout << fmt::format("{} camera: sees the ground from {:.2f} m to {:.2f} m ahead ({} footprint points)\n",
                               v.camera,
                               v.nearest_ground_m,
                               v.farthest_ground_m,
                               v.footprint_m.size());
    }
  }
  if (o.json) {
    std::cout << out.dump() << "\n";
  }
  return Status::Ok();
}

}  // namespace

namespace {
constexpr double kMinFxPx = 50.0;
}  // namespace

Status FovOptions::Check() const {
  // Non-finite values went through to a footprint "from 1000000000.00 m to -1000000000.00 m".
  IDI_RETURN_IF_ERROR(CheckRange("--height-m", height_m, 0.0, true, 100.0, false));
  IDI_RETURN_IF_ERROR(CheckRange("--pitch-down-deg", pitch_down_deg, -89.0, true, 89.0, true));
  IDI_RETURN_IF_ERROR(CheckRange("--baseline-m", baseline_m, 0.0, false, 100.0, false));
  IDI_RETURN_IF_ERROR(CheckRange("--forward-m", forward_m, -100.0, false, 100.0, false));
  IDI_RETURN_IF_ERROR(CheckRange("--toe-in-deg", toe_in_deg, -89.0, true, 89.0, true));
  // A rectilinear (pinhole) lens on a 640 px wide image: below 50 px the field of view would pass 162 deg
  // across, which no such lens gives (1e-300 was taken, and neither camera "saw" the ground).
  return CheckRange("--fx-px", fx_px, kMinFxPx, false, 1e6, false);
}

Result<std::vector<CameraGroundView>> ComputeFov(const FovOptions& o) {
  IDI_RETURN_IF_ERROR(o.Check());
  std::vector<CameraGroundView> views;
  for (const double side : {+1.0, -1.0}) {
    RigCamera cam;
    cam.intrinsics.params = {o.fx_px, o.fx_px, 319.5, 239.5, 0, 0, 0, 0, 0};
    cam.vehicle_from_camera = LookAheadCameraPose(
        o.forward_m, side * o.baseline_m / 2, o.height_m, -side * DegToRad(o.toe_in_deg), DegToRad(o.pitch_down_deg));
    CameraGroundView v;
    v.camera = side > 0 ? "left" : "right";
    v.footprint_m = GroundFootprint(cam, 16.0, kFootprintRangeM);
    // GroundFootprint cuts rays that miss the ground at its range: cut far away, they tell the border
    // rays at or above the horizon from those that meet the ground.
    const Vec2d centre = cam.vehicle_from_camera.translation.head<2>();
    v.nearest_ground_m = 1e300;
    v.farthest_ground_m = -1e300;
    for (const Vec2d& p : GroundFootprint(cam, 16.0, kHorizonRangeM)) {
      if ((p - centre).norm() > 0.5 * kHorizonRangeM) {
        v.to_horizon = true;
        continue;
      }
      v.sees_ground = true;
      v.nearest_ground_m = std::min(v.nearest_ground_m, p.x());
      v.farthest_ground_m = std::max(v.farthest_ground_m, p.x());
    }
    if (!v.sees_ground) {
      v.nearest_ground_m = v.farthest_ground_m = 0.0;
      v.footprint_m.clear();  // only range cuts: no ground
    }
    views.push_back(std::move(v));
  }
  return views;
}

void AddFovCommand(CliApp& cli) {
  auto o = std::make_shared<FovOptions>();
  CLI::App* cmd =
      cli.AddCommand(&cli.app, "fov", "ground footprint of the two fixed cameras", [o] { return RunFov(*o); });
  cmd->add_option("--height-m", o->height_m, "camera height above the ground, (0, 100]")->capture_default_str();
  cmd->add_option("--pitch-down-deg", o->pitch_down_deg, "camera pitch below horizontal, (-89, 89)")
      ->capture_default_str();
  cmd->add_option("--baseline-m", o->baseline_m, "distance between the cameras, [0, 100]")->capture_default_str();
  cmd->add_option("--forward-m", o->forward_m, "cameras ahead of the wheel axle, [-100, 100]")->capture_default_str();
  cmd->add_option("--toe-in-deg", o->toe_in_deg, "each camera turned towards the centre line, (-89, 89)")
      ->capture_default_str();
  cmd->add_option("--fx-px", o->fx_px, "focal length in pixels (640x480 images), [50, 1e6]")->capture_default_str();
  cmd->add_flag("--json", o->json, "print JSON on stdout");
}

}  // namespace idi::rmp
