#include "shared/camera/pinhole.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

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

double MonotonicRadius(const CameraModel& camera) {
  const double k1 = camera.params[kK1], k2 = camera.params[kK2], k3 = camera.params[kK3];
  // d/dr of r (1 + k1 s + k2 s^2 + k3 s^3), s = r^2: 1 + 3 k1 s + 5 k2 s^2 + 7 k3 s^3. Its first zero
  // in s, found on a grid out to r = 10 (84 deg off axis) and then by bisection.
  auto slope = [&](double s) { return 1 + s * (3 * k1 + s * (5 * k2 + s * 7 * k3)); };
  if (k1 >= 0 && k2 >= 0 && k3 >= 0) return std::numeric_limits<double>::infinity();
  // Project and PixelToNormalized call this per point: the last camera's answer is kept (per thread).
  thread_local std::array<double, 3> last_k = {std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0};
  thread_local double last_radius = 0;
  if (last_k[0] == k1 && last_k[1] == k2 && last_k[2] == k3) return last_radius;
  last_k = {k1, k2, k3};
  last_radius = std::numeric_limits<double>::infinity();
  constexpr int kSteps = 4000;
  constexpr double kMaxS = 100.0;
  double prev = 0;
  for (int i = 1; i <= kSteps; ++i) {
    const double s = kMaxS * i / kSteps;
    if (slope(s) <= 0) {
      double lo = prev, hi = s;
      for (int k = 0; k < 60; ++k) {
        const double mid = 0.5 * (lo + hi);
        (slope(mid) > 0 ? lo : hi) = mid;
      }
      last_radius = std::sqrt(lo);
      break;
    }
    prev = s;
  }
  return last_radius;
}

std::optional<Vec2d> Project(const CameraModel& camera, const Vec3d& point_in_cam, double min_depth) {
  if (!(point_in_cam.z() > min_depth)) {
    return std::nullopt;
  }
  if (camera.HasDistortion()) {
    const double r_max = MonotonicRadius(camera);
    if (std::isfinite(r_max) &&
        !(point_in_cam.head<2>().squaredNorm() <= r_max * r_max * point_in_cam.z() * point_in_cam.z())) {
      return std::nullopt;
    }
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
  // Started within the valid radius: from beyond it (pincushion distortion that folds further out), the
  // iteration can settle on the fold's branch although a valid inverse exists.
  const double r_max = MonotonicRadius(camera);
  Vec2d xn = xd;
  if (std::isfinite(r_max) && xd.norm() > 0.9 * r_max) xn = xd * (0.9 * r_max / xd.norm());
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
  // Not a solution, or the one of a fold of the model (a ray beyond its valid radius): no ray.
  if (!((Distort(p, xn) - xd).norm() <= 1e-9 * std::max(1.0, xd.norm())) ||
      (std::isfinite(r_max) && !(xn.norm() <= r_max))) {
    return Vec2d::Constant(std::numeric_limits<double>::quiet_NaN());
  }
  return xn;
}

Status CheckDistortionCoversImage(const CameraModel& camera) {
  if (!camera.HasDistortion()) return Status::Ok();
  for (const double u : {-0.5, camera.width - 0.5}) {
    for (const double v : {-0.5, camera.height - 0.5}) {
      if (!PixelToNormalized(camera, Vec2d(u, v)).allFinite()) {
        return InvalidArgument("the lens distortion (k1 " + FormatNumber(camera.params[kK1]) + ", k2 " +
                               FormatNumber(camera.params[kK2]) + ", k3 " + FormatNumber(camera.params[kK3]) +
                               ") cannot be undistorted at the image corner (" + FormatNumber(u) + ", " +
                               FormatNumber(v) +
                               "): the model folds back before that radius; less distortion or a longer focal "
                               "length is needed");
      }
    }
  }
  return Status::Ok();
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
