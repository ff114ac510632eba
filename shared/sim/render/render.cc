#include "shared/sim/render/render.h"

#include <opencv2/imgproc.hpp>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <cmath>
#include <thread>

#include "shared/sim/render/raster_internal.h"

namespace idi::sim {

Status RenderOptions::Check() const {
  // Bounded so that exposure x radiance stays a float (an infinite pixel plus its shot noise was NaN,
  // which became 0: saturated pixels turned black).
  if (!std::isfinite(exposure_dn) || exposure_dn < 0 || exposure_dn > 1e6) {
    return InvalidArgument("render exposure_dn must be in [0, 1e6], got " + FormatNumber(exposure_dn));
  }
  if (!std::isfinite(psf_sigma_px) || psf_sigma_px < 0 || psf_sigma_px > 20) {
    return InvalidArgument("render psf_sigma_px must be in [0, 20], got " + FormatNumber(psf_sigma_px));
  }
  if (!std::isfinite(vignetting) || vignetting < 0 || vignetting >= 1) {
    return InvalidArgument("render vignetting must be in [0, 1), got " + FormatNumber(vignetting));
  }
  if (!(near_clip > 0) || !std::isfinite(near_clip)) {
    return InvalidArgument("render near_clip must be positive, got " + FormatNumber(near_clip));
  }
  if (!std::isfinite(truth_min_contrast_dn) || truth_min_contrast_dn < 0) {
    return InvalidArgument("render truth_min_contrast_dn must be >= 0");
  }
  if (!std::isfinite(shading_tolerance_dn) || shading_tolerance_dn < 0 || shading_tolerance_dn > 1) {
    return InvalidArgument("render shading_tolerance_dn must be in [0, 1], got " + FormatNumber(shading_tolerance_dn));
  }
  if (threads < 0 || threads > 64) return InvalidArgument("render threads must be in 0..64, got " + std::to_string(threads));
  return sensor.Check();
}

namespace {

Status CheckCamera(const CameraModel& camera, const Rigid3d& cam_from_world) {
  if (camera.width <= 0 || camera.height <= 0 || camera.width > 16384 || camera.height > 16384) {
    return InvalidArgument("camera size must be within 1..16384 pixels, got " + std::to_string(camera.width) + "x" +
                           std::to_string(camera.height));
  }
  for (const double p : camera.params) {
    if (!std::isfinite(p)) return InvalidArgument("camera intrinsics must be finite");
  }
  if (!(camera.fx() > 0) || !(camera.fy() > 0)) return InvalidArgument("camera fx and fy must be positive");
  IDI_RETURN_IF_ERROR(CheckDistortionCoversImage(camera).WithContext("camera"));
  if (!cam_from_world.rotation.allFinite() || !cam_from_world.translation.allFinite()) {
    return InvalidArgument("cam_from_world must be finite");
  }
  const Mat3d rtr = cam_from_world.rotation.transpose() * cam_from_world.rotation;
  if ((rtr - Mat3d::Identity()).norm() > 1e-6 || cam_from_world.rotation.determinant() < 0) {
    return InvalidArgument("cam_from_world rotation is not a rotation matrix");
  }
  return Status::Ok();
}

#if defined(__x86_64__)
// ScaleRow's leading multiple of 8 values with AVX-512: the same conversions and product, so the same
// floats. Returns how many it did. (GCC 12's AVX-512 conversions pass an undefined merge source, which
// its uninitialised-use analysis reports once they are inlined.)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
[[gnu::target("avx512f")]] int ScaleRowAvx512(float* v, int n, double gain) {
  const __m512d g = _mm512_set1_pd(gain);
  int k = 0;
  for (; k + 8 <= n; k += 8) {
    const __m512d x = _mm512_cvtps_pd(_mm256_loadu_ps(v + k));
    _mm256_storeu_ps(v + k, _mm512_cvtpd_ps(_mm512_mul_pd(x, g)));
  }
  return k;
}
#pragma GCC diagnostic pop

// The same on AVX2, four values at a time.
[[gnu::target("avx2")]] int ScaleRowAvx2(float* v, int n, double gain) {
  const __m256d g = _mm256_set1_pd(gain);
  int k = 0;
  for (; k + 4 <= n; k += 4) {
    const __m256d x = _mm256_cvtps_pd(_mm_loadu_ps(v + k));
    _mm_storeu_ps(v + k, _mm256_cvtpd_ps(_mm256_mul_pd(x, g)));
  }
  return k;
}
#endif

// v[k] = float(double(v[k]) * gain) for k < n: the product in double, rounded to float once.
void ScaleRow(float* v, int n, double gain) {
  int k = 0;
#if defined(__x86_64__)
  static const bool avx512 = __builtin_cpu_supports("avx512f") != 0;
  static const bool avx2 = __builtin_cpu_supports("avx2") != 0;
  if (avx512) {
    k = ScaleRowAvx512(v, n, gain);
  } else if (avx2) {
    k = ScaleRowAvx2(v, n, gain);
  }
#endif
  for (; k < n; ++k) v[k] = static_cast<float>(static_cast<double>(v[k]) * gain);
}

// Vignetting and exposure in place.
void ApplyExposure(cv::Mat& radiance, const internal::PixelGrid& grid, const CameraModel& camera,
                   const RenderOptions& options) {
  const int ch = radiance.channels();
  if (!(options.vignetting > 0)) {
    // One gain everywhere: each row scaled as one run of values.
    for (int j = 0; j < radiance.rows; ++j) ScaleRow(radiance.ptr<float>(j), radiance.cols * ch, options.exposure_dn);
    return;
  }
  const double corner2 =
      std::max({std::pow(camera.cx() + 0.5, 2) + std::pow(camera.cy() + 0.5, 2),
                std::pow(camera.width - 0.5 - camera.cx(), 2) + std::pow(camera.cy() + 0.5, 2),
                std::pow(camera.cx() + 0.5, 2) + std::pow(camera.height - 0.5 - camera.cy(), 2),
                std::pow(camera.width - 0.5 - camera.cx(), 2) + std::pow(camera.height - 0.5 - camera.cy(), 2)});
  for (int j = 0; j < radiance.rows; ++j) {
    float* row = radiance.ptr<float>(j);
    const double dy = grid.y0 + j - camera.cy();
    for (int i = 0; i < radiance.cols; ++i) {
      double gain = options.exposure_dn;
      const double dx = grid.x0 + i - camera.cx();
      gain *= std::max(0.0, 1 - options.vignetting * (dx * dx + dy * dy) / corner2);
      for (int c = 0; c < ch; ++c) row[i * ch + c] = static_cast<float>(row[i * ch + c] * gain);
    }
  }
}

// The surfaces blurred by the PSF plus the spot layer (its PSF already included), cropped. With
// `own` false a gray image is a view into `radiance` (no copy: valid until it is rendered into again).
cv::Mat FinishOptics(cv::Mat& radiance,
                     const cv::Mat* spots,
                     const internal::PixelGrid& grid,
                     const CameraModel& camera,
                     const RenderOptions& options,
                     bool own) {
  const int ch = radiance.channels();
  ApplyExposure(radiance, grid, camera, options);
  ApplyPsf(&radiance, options.psf_sigma_px);
  cv::Mat crop = radiance(cv::Rect(-grid.x0, -grid.y0, camera.width, camera.height));
  if (own && ch != 3) crop = crop.clone();
  if (spots != nullptr) {
    cv::Mat sp = spots->clone();
    ApplyExposure(sp, grid, camera, options);
    crop += sp(cv::Rect(-grid.x0, -grid.y0, camera.width, camera.height));
  }
  if (ch == 3) {
    cv::Mat bgr;
    cv::cvtColor(crop, bgr, cv::COLOR_RGB2BGR);
    return bgr;
  }
  return crop;
}

// RenderIrradiance, its gray image a view into this thread's raster buffer unless `own`.
Result<cv::Mat> Irradiance(const Scene& scene,
                           const CameraModel& camera,
                           const Rigid3d& cam_from_world,
                           const RenderOptions& options,
                           GroundTruth* truth,
                           bool own) {
  IDI_RETURN_IF_ERROR(options.Check());
  IDI_RETURN_IF_ERROR(CheckCamera(camera, cam_from_world));
  IDI_RETURN_IF_ERROR(scene.Check());
  const int margin = options.psf_sigma_px > 0 ? static_cast<int>(std::ceil(4 * options.psf_sigma_px)) + 1 : 0;
  IDI_ASSIGN_OR_RETURN(const internal::Prepared prep, internal::Prepare(scene, camera, cam_from_world, options, margin));
  // The raster buffer is reused between frames of one thread (a fresh one costs page faults).
  thread_local cv::Mat radiance;
  const int threads =
      options.threads > 0 ? options.threads : std::clamp(static_cast<int>(std::thread::hardware_concurrency()), 1, 4);
  internal::RasterizeRadiance(prep, options.color, threads, &radiance);
  cv::Mat spots;
  const bool have_spots = internal::RasterizeSpots(prep, options.color, &spots);
  if (truth != nullptr) internal::ComputeGroundTruth(prep, options, truth);
  return FinishOptics(radiance, have_spots ? &spots : nullptr, *prep.grid, camera, options, own);
}

}  // namespace

Result<cv::Mat> RenderIrradiance(const Scene& scene,
                                 const CameraModel& camera,
                                 const Rigid3d& cam_from_world,
                                 const RenderOptions& options,
                                 GroundTruth* truth) {
  return Irradiance(scene, camera, cam_from_world, options, truth, /*own=*/true);
}

Result<cv::Mat> RenderScene(const Scene& scene, const CameraModel& camera, const Rigid3d& cam_from_world,
                            const RenderOptions& options, GroundTruth* truth) {
  // The sensor reads the irradiance in place: it need not be copied out of the raster buffer.
  IDI_ASSIGN_OR_RETURN(const cv::Mat irradiance,
                       Irradiance(scene, camera, cam_from_world, options, truth, /*own=*/false));
  return ApplySensor(irradiance, options.sensor, options.seed);
}

}  // namespace idi::sim
