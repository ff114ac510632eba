#include "shared/camera/pinhole.h"

#include <Eigen/Dense>

namespace idi {

std::vector<ParamSpec> CameraParamSpecs(const CameraModel& nominal) {
  const auto& p = nominal.params;
  return {
      {"fx", Unit::kPixel, p[kFx], "focal length times horizontal pixel density (f*px)"},
      {"fy", Unit::kPixel, p[kFy], "focal length times vertical pixel density (f*py)"},
      {"cx", Unit::kPixel, p[kCx], "principal point u0 (pixel-centre convention)"},
      {"cy", Unit::kPixel, p[kCy], "principal point v0 (pixel-centre convention)"},
      {"k1", Unit::kUnitless, p[kK1], "radial distortion r^2"},
      {"k2", Unit::kUnitless, p[kK2], "radial distortion r^4"},
      {"p1", Unit::kUnitless, p[kP1], "tangential distortion"},
      {"p2", Unit::kUnitless, p[kP2], "tangential distortion"},
      {"k3", Unit::kUnitless, p[kK3], "radial distortion r^6"},
  };
}

ParamSet CameraToParamSet(const CameraModel& camera) { return ParamSet(CameraParamSpecs(camera)); }

CameraModel CameraFromParamSet(const ParamSet& set, int width, int height) {
  CameraModel c;
  c.width = width;
  c.height = height;
  const CameraModel nominal;
  const auto specs = CameraParamSpecs(nominal);
  for (int i = 0; i < kCameraParamCount; ++i) {
    c.params[static_cast<std::size_t>(i)] = set.Get(specs[static_cast<std::size_t>(i)].name);
  }
  return c;
}

std::optional<Vec2d> Project(const CameraModel& camera, const Vec3d& point_in_cam, double min_depth) {
  if (!(point_in_cam.z() > min_depth)) {
    return std::nullopt;
  }
  return ProjectToPixel(camera.params.data(), point_in_cam);
}

Vec2d PixelToNormalized(const CameraModel& camera, const Vec2d& pixel) {
  const double* p = camera.params.data();
  const Vec2d xd((pixel.x() - p[kCx]) / p[kFx], (pixel.y() - p[kCy]) / p[kFy]);
  if (!camera.HasDistortion()) {
    return xd;
  }
  // Gauss-Newton on Distort(xn) = xd, starting from xn = xd; the Jacobian by central differences
  // is accurate enough because the map is smooth and the step only needs to contract.
  Vec2d xn = xd;
  for (int iter = 0; iter < 20; ++iter) {
    const Vec2d r = Distort(p, xn) - xd;
    if (r.norm() < 1e-14) {
      break;
    }
    Eigen::Matrix2d j;
    const double h = 1e-7;
    for (int k = 0; k < 2; ++k) {
      Vec2d dp = xn, dm = xn;
      dp(k) += h;
      dm(k) -= h;
      j.col(k) = (Distort(p, dp) - Distort(p, dm)) / (2 * h);
    }
    xn -= j.inverse() * r;
  }
  return xn;
}

Vec3d PixelToRay(const CameraModel& camera, const Vec2d& pixel) {
  const Vec2d xn = PixelToNormalized(camera, pixel);
  return Vec3d(xn.x(), xn.y(), 1.0).normalized();
}

Vec2d UndistortPixel(const CameraModel& camera, const Vec2d& pixel) {
  const Vec2d xn = PixelToNormalized(camera, pixel);
  return {camera.fx() * xn.x() + camera.cx(), camera.fy() * xn.y() + camera.cy()};
}

}  // namespace idi
