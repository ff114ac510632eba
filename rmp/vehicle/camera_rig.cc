#include "rmp/vehicle/camera_rig.h"

#include <cmath>

#include "shared/geometry/lines.h"

namespace idi::rmp {

Rigid3d LookAheadCameraPose(double x_m, double y_m, double height_m, double yaw_rad, double pitch_down_rad) {
  // Camera axes for a horizontal camera looking along vehicle +x: z_cam = x_veh, x_cam = -y_veh,
  // y_cam = -z_veh.
  Rigid3d level;
  level.rotation << 0, 0, 1,  //
      -1, 0, 0,               //
      0, -1, 0;
  // Pitch down is a rotation about the camera's x axis (positive tips the view down in this frame).
  return Translation(x_m, y_m, height_m) * RotZ(yaw_rad) * level * RotX(-pitch_down_rad);
}

std::vector<Vec2d> GroundFootprint(const RigCamera& camera, double step_px, double max_range_m) {
  const CameraModel& k = camera.intrinsics;
  std::vector<Vec2d> border;
  // A step that is not positive never walked the border (an endless loop that filled memory).
  if (!(step_px >= 1.0 && std::isfinite(step_px)) || !(max_range_m > 0 && std::isfinite(max_range_m))) return {};
  const double w = k.width - 0.5, h = k.height - 0.5;
  for (double x = -0.5; x < w; x += step_px) border.emplace_back(x, -0.5);
  for (double y = -0.5; y < h; y += step_px) border.emplace_back(w, y);
  for (double x = w; x > -0.5; x -= step_px) border.emplace_back(x, h);
  for (double y = h; y > -0.5; y -= step_px) border.emplace_back(-0.5, y);
  const Plane3d ground{Vec3d::UnitZ(), 0.0};
  const Vec3d centre = camera.vehicle_from_camera.translation;
  std::vector<Vec2d> polygon;
  for (const Vec2d& px : border) {
    const Vec3d dir = camera.vehicle_from_camera.RotateVector(PixelToRay(k, px));
    if (!dir.allFinite()) continue;  // a pixel the lens model cannot undistort has no ray
    const Line3d ray{centre, dir};
    const auto s = IntersectLinePlane(ray, ground);
    Vec2d hit;
    if (s && *s > 0 && (ray.PointAt(*s).head<2>() - centre.head<2>()).norm() <= max_range_m) {
      hit = ray.PointAt(*s).head<2>();
    } else {
      // Above the horizon: cut the ray's ground direction at the range limit.
      Vec2d g = dir.head<2>();
      if (g.norm() < 1e-12) continue;
      hit = centre.head<2>() + max_range_m * g.normalized();
    }
    polygon.push_back(hit);
  }
  return polygon;
}

std::optional<Vec2d> GroundPointToPixel(const RigCamera& camera, const Vec2d& ground_xy) {
  const Vec3d p_cam = camera.vehicle_from_camera.Inverse() * Vec3d(ground_xy.x(), ground_xy.y(), 0.0);
  const auto px = Project(camera.intrinsics, p_cam);
  if (!px || !camera.intrinsics.InImage(*px)) {
    return std::nullopt;
  }
  return px;
}

}  // namespace idi::rmp
