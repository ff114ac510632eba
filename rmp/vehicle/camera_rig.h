// The RMP's fixed stereo cameras: where they sit on the vehicle and what of the ground they see.
//
// Vehicle frame (SI units): origin on the ground midway between the wheels, x forward, y left, z up.
// Each camera looks ahead and down; its pose comes from a pan-tilt head held at fixed angles
// (§8.12.4), summarised here as a rigid vehicle_from_camera transform.
#pragma once

#include <vector>

#include "shared/camera/pinhole.h"
#include "shared/geometry/rigid3.h"

namespace idi::rmp {

struct RigCamera {
  CameraModel intrinsics;
  Rigid3d vehicle_from_camera;
};

// A camera at (x, y, height) looking forward (+x), turned by yaw about z (left positive) and pitched
// down by `pitch_down_rad` (0 = horizontal). Camera axes: x right, y down, z forward.
Rigid3d LookAheadCameraPose(double x_m, double y_m, double height_m, double yaw_rad, double pitch_down_rad);

// The polygon (vehicle frame, z = 0) where the image border's rays meet the ground, sampled every
// `step_px` along the border. Rays at or above the horizon are cut at `max_range_m` along the ground.
std::vector<Vec2d> GroundFootprint(const RigCamera& camera, double step_px = 16.0, double max_range_m = 15.0);

// Pixel where a ground point (vehicle frame, z = 0) appears; nullopt if behind or outside the image.
std::optional<Vec2d> GroundPointToPixel(const RigCamera& camera, const Vec2d& ground_xy);

}  // namespace idi::rmp
