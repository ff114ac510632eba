// The optics after the geometry (vignetting, PSF) and the sensor (shot and read noise, quantization).
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "shared/sim/render/render.h"

namespace idi::sim {
namespace {

// xoshiro256** seeded by splitmix64: fast, and the same seed gives the same noise everywhere.
class NoiseRng {
 public:
  explicit NoiseRng(uint64_t seed) {
    for (auto& s : s_) {
      seed += 0x9E3779B97F4A7C15ULL;
      uint64_t z = seed;
      z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
      z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
      s = z ^ (z >> 31);
    }
  }
  uint64_t Next() {
    const uint64_t result = Rotl(s_[1] * 5, 7) * 9;
    const uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = Rotl(s_[3], 45);
    return result;
  }
  // Uniform in (0, 1).
  double Uniform() { return (static_cast<double>(Next() >> 11) + 0.5) * (1.0 / 9007199254740992.0); }
  // Standard normal by inversion of its distribution function (Acklam's rational approximation,
  // relative error < 1.2e-9): one uniform per value, no trigonometry.
  double Normal() {
    const double p = Uniform();
    constexpr double a[] = {-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
                            1.383577518672690e+02, -3.066479806614716e+01, 2.506628277459239e+00};
    constexpr double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                            6.680131188771972e+01, -1.328068155288572e+01};
    constexpr double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                            -2.549732539343734e+00, 4.374664141464968e+00, 2.938163982698783e+00};
    constexpr double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                            3.754408661907416e+00};
    constexpr double kLow = 0.02425;
    if (p < kLow || p > 1 - kLow) {
      const double q = std::sqrt(-2 * std::log(p < kLow ? p : 1 - p));
      const double z = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
                       ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
      return p < kLow ? z : -z;
    }
    const double q = p - 0.5, r = q * q;
    return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
           (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
  }
  // Poisson: exact (multiplication method) for small means, normal with the same variance above.
  double Poisson(double mean) {
    if (mean <= 0) return 0;
    const double limit = std::exp(-mean);
    double prod = Uniform();
    int k = 0;
    while (prod > limit) {
      prod *= Uniform();
      ++k;
    }
    return k;
  }

 private:
  static uint64_t Rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  uint64_t s_[4];
};

// std::nearbyint for 0 <= v <= 255 under the default rounding mode (to nearest, ties to even), without
// the library call: adding 1.5 * 2^52 rounds away every fraction bit (IEEE double arithmetic, which
// the compiler keeps without -ffast-math). Clamping before rounding gives the same as after, since 0
// and 255 are integers.
inline double RoundHalfEven(double v) { return (v + 6755399441055744.0) - 6755399441055744.0; }

}  // namespace

Status SensorOptions::Check() const {
  if (!std::isfinite(gain_dn_per_electron) || gain_dn_per_electron < 0) {
    return InvalidArgument("sensor gain_dn_per_electron must be >= 0, got " + std::to_string(gain_dn_per_electron));
  }
  if (!std::isfinite(read_noise_dn) || read_noise_dn < 0) {
    return InvalidArgument("sensor read_noise_dn must be >= 0, got " + std::to_string(read_noise_dn));
  }
  if (!std::isfinite(black_level_dn) || black_level_dn < 0 || black_level_dn > 255) {
    return InvalidArgument("sensor black_level_dn must be in [0, 255], got " + std::to_string(black_level_dn));
  }
  return Status::Ok();
}

void ApplyPsf(cv::Mat* image, double sigma_px) {
  if (!(sigma_px > 0) || image->empty()) return;
  const int half = std::max(1, static_cast<int>(std::ceil(4 * sigma_px)));
  const cv::Mat k = cv::getGaussianKernel(2 * half + 1, sigma_px, CV_32F);
  cv::sepFilter2D(*image, *image, -1, k, k, cv::Point(-1, -1), 0, cv::BORDER_REFLECT_101);
}

cv::Mat ApplySensor(const cv::Mat& irradiance_dn, const SensorOptions& sensor, uint64_t seed) {
  IDI_CHECK(irradiance_dn.depth() == CV_32F, "ApplySensor needs a float image");
  const int channels = irradiance_dn.channels();
  cv::Mat out(irradiance_dn.rows, irradiance_dn.cols, CV_MAKETYPE(CV_8U, channels));
  NoiseRng rng(seed ^ 0x5EEDF00DULL);
  const bool shot = sensor.noise && sensor.gain_dn_per_electron > 0;
  const bool read = sensor.noise && sensor.read_noise_dn > 0;
  const double gain = sensor.gain_dn_per_electron;
  const double read_var = read ? sensor.read_noise_dn * sensor.read_noise_dn : 0.0;
  for (int r = 0; r < irradiance_dn.rows; ++r) {
    const float* in = irradiance_dn.ptr<float>(r);
    uint8_t* o = out.ptr<uint8_t>(r);
    const int n = irradiance_dn.cols * channels;
    for (int k = 0; k < n; ++k) {
      double v = std::max(0.0, static_cast<double>(in[k]));
      if (shot && v > 30 * gain) {
        // Many electrons: shot and read noise together are normal with the summed variance.
        v += std::sqrt(gain * v + read_var) * rng.Normal();
      } else {
        if (shot) v = gain * rng.Poisson(v / gain);
        if (read) v += sensor.read_noise_dn * rng.Normal();
      }
      v += sensor.black_level_dn;
      o[k] = static_cast<uint8_t>(RoundHalfEven(std::clamp(v, 0.0, 255.0)));
    }
  }
  return out;
}

}  // namespace idi::sim
