// `idi-rmp fov`: where on the ground each fixed camera looks (the footprint the planner must keep the
// track inside, §8.12.4).
#pragma once

#include <string>
#include <vector>

#include "shared/geometry/rigid3.h"
#include "shared/runtime/cli.h"
#include "shared/util/status.h"

namespace idi::rmp {

// The command's options: the rig's geometry (640x480 images).
struct FovOptions {
  double height_m = 1.0;
  double pitch_down_deg = 40.0;
  double baseline_m = 0.30;
  double forward_m = 0.25;
  double toe_in_deg = 0.0;
  double fx_px = 600.0;
  bool json = false;

  // InvalidArgument naming the option for a value that is not finite or makes no rig.
  Status Check() const;
};

// What one camera sees of the ground.
struct CameraGroundView {
  std::string camera;        // "left" or "right"
  bool sees_ground = false;  // some of the image is below the horizon
  bool to_horizon = false;   // some of it is at or above the horizon: the ground seen has no far end
  double nearest_ground_m = 0.0, farthest_ground_m = 0.0;  // x ahead of the axle; when sees_ground
  std::vector<Vec2d> footprint_m;                          // GroundFootprint: rays at or above the horizon cut at 15 m
};

Result<std::vector<CameraGroundView>> ComputeFov(const FovOptions& options);

void AddFovCommand(CliApp& cli);

}  // namespace idi::rmp
