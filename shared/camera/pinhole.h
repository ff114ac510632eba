// Pinhole camera with Brown-Conrady radial/tangential distortion (OpenCV's model), templated on the
// scalar so Ceres Jets flow through.
//
// Conventions (stated once, used everywhere):
// - Camera frame: origin at the optical centre, x right, y down, z forward along the optical axis
//   (the dissertation's Fig. 1.2 and 3.10).
// - Pixel coordinates: x right, y down; integer values are pixel centres (OpenCV's convention), so
//   the top-left pixel covers [-0.5, 0.5] x [-0.5, 0.5] and an image of width W spans [-0.5, W-0.5].
// - Intrinsics vector, OpenCV's order: fx, fy, cx, cy, k1, k2, p1, p2, k3.
//
// Mapping from the dissertation's internal parameters (§1.5 eqs. 1.2-1.3, §6.2.2): the dissertation
// writes the focal length f (mm) and pixel densities px, py (pixels/mm) separately, but images only
// ever see the products: fx = f*px, fy = f*py; (u0, v0) = (cx, cy). Its image-plane frame sits on the
// CCD, f in front of the optical centre; the constant offset f along the optical axis is absorbed by
// the last Biclops link's d2, so calibrating f, px, py separately is neither possible nor needed.
#pragma once

#include <array>
#include <cmath>
#include <optional>

#include "shared/geometry/rigid3.h"
#include "shared/util/param_set.h"
#include "shared/util/status.h"

namespace idi {

enum CameraParam : int { kFx = 0, kFy, kCx, kCy, kK1, kK2, kP1, kP2, kK3 };
inline constexpr int kCameraParamCount = kK3 + 1;

struct CameraModel {
  int width = 640;
  int height = 480;
  std::array<double, kCameraParamCount> params{800.0, 800.0, 319.5, 239.5, 0, 0, 0, 0, 0};

  double fx() const { return params[kFx]; }
  double fy() const { return params[kFy]; }
  double cx() const { return params[kCx]; }
  double cy() const { return params[kCy]; }
  bool HasDistortion() const {
    return params[kK1] != 0 || params[kK2] != 0 || params[kP1] != 0 || params[kP2] != 0 || params[kK3] != 0;
  }
  // True when the pixel lies on the image (pixel-centre convention).
  bool InImage(const Vec2d& px, double margin = 0) const {
    return px.x() >= -0.5 + margin && px.y() >= -0.5 + margin && px.x() <= width - 0.5 - margin &&
           px.y() <= height - 0.5 - margin;
  }
  Mat3d K() const {
    Mat3d k;
    k << fx(), 0, cx(), 0, fy(), cy(), 0, 0, 1;
    return k;
  }
};

// Parameter specs (fx_px, fy_px, cx_px, cy_px, k1, k2, p1, p2, k3) with the given nominal values.
std::vector<ParamSpec> CameraParamSpecs(const CameraModel& nominal);
ParamSet CameraToParamSet(const CameraModel& camera);
// Reads intrinsics from a ParamSet holding CameraParamSpecs (by name).
CameraModel CameraFromParamSet(const ParamSet& set, int width, int height);

// Distortion of normalised image coordinates (x/z, y/z).
template <typename T>
Vec2<T> Distort(const T* p, const Vec2<T>& xn) {
  const T x = xn.x(), y = xn.y();
  const T r2 = x * x + y * y;
  const T radial = T(1) + r2 * (p[kK1] + r2 * (p[kK2] + r2 * p[kK3]));
  const T dx = T(2) * p[kP1] * x * y + p[kP2] * (r2 + T(2) * x * x);
  const T dy = p[kP1] * (r2 + T(2) * y * y) + T(2) * p[kP2] * x * y;
  return Vec2<T>(x * radial + dx, y * radial + dy);
}

// Projects a point given in the camera frame to pixels. The caller guarantees z > 0.
template <typename T>
Vec2<T> ProjectToPixel(const T* p, const Vec3<T>& point_in_cam) {
  const Vec2<T> xn(point_in_cam.x() / point_in_cam.z(), point_in_cam.y() / point_in_cam.z());
  const Vec2<T> xd = Distort(p, xn);
  return Vec2<T>(p[kFx] * xd.x() + p[kCx], p[kFy] * xd.y() + p[kCy]);
}

// The undistorted radius (of x/z, y/z) up to which the radial model r (1 + k1 r^2 + k2 r^4 + k3 r^6)
// still grows with r: beyond it the model folds back, and a point there would land on the pixel of a
// point nearer the axis. Infinity when it grows out to r = 10 (84 deg off axis; no distortion, or a real
// lens's values); found on a grid of 0.025 in r^2, so a dip narrower than that is not seen. The
// tangential terms are left out (they are small where a model is valid).
double MonotonicRadius(const CameraModel& camera);

// Projection with a visibility check: nullopt when the point is not in front of the camera, or lies
// beyond MonotonicRadius (where the model's pixel is not where the lens would put it).
std::optional<Vec2d> Project(const CameraModel& camera, const Vec3d& point_in_cam, double min_depth = 1e-9);

// Removes distortion: pixel to normalised undistorted coordinates (x/z, y/z). Iterative (Gauss-Newton
// on the forward model), accurate to ~1e-12 for distortion a real lens has. NaN for a pixel the model
// cannot invert: no undistorted point within MonotonicRadius distorts onto it (a corner of an image
// with more barrel distortion than the model can hold), or the iteration did not converge.
Vec2d PixelToNormalized(const CameraModel& camera, const Vec2d& pixel);
// InvalidArgument when a pixel of the image (its four corners, the farthest from the axis) cannot be
// undistorted: the distortion is beyond what the model can hold for this image and focal length.
Status CheckDistortionCoversImage(const CameraModel& camera);
// The unit ray (camera frame) through a pixel.
Vec3d PixelToRay(const CameraModel& camera, const Vec2d& pixel);
// Pixel with distortion removed, expressed in the same K (an ideal pinhole image).
Vec2d UndistortPixel(const CameraModel& camera, const Vec2d& pixel);

}  // namespace idi
