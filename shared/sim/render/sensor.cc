// The optics after the geometry (vignetting, PSF) and the sensor (shot and read noise, quantization).
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "shared/sim/render/render.h"

namespace idi::sim {
namespace {

// The ziggurat's layers: x[i] is the right edge of layer i (x[0] the base layer's width including its
// tail, x[1] = kR, x[128] = 0); ratio[i] = x[i+1] / x[i], the part of layer i under the curve for any
// height. Built at load time.
struct Ziggurat {
  static constexpr int kLayers = 128;
  static constexpr double kR = 3.442619855899;          // start of the tail for 128 layers
  static constexpr double kArea = 9.91256303526217e-3;  // each layer's area under exp(-x^2/2)
  double x[kLayers + 1];
  double ratio[kLayers];
  Ziggurat() {
    const double f_r = std::exp(-0.5 * kR * kR);
    x[0] = kArea / f_r;
    x[1] = kR;
    for (int i = 2; i < kLayers; ++i)
      x[i] = std::sqrt(-2 * std::log(kArea / x[i - 1] + std::exp(-0.5 * x[i - 1] * x[i - 1])));
    x[kLayers] = 0;
    for (int i = 0; i < kLayers; ++i) ratio[i] = x[i + 1] / x[i];
  }
};
const Ziggurat kZiggurat;
inline const Ziggurat& Zig() { return kZiggurat; }

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
  // Uniform in (-1, 1) from the top 53 bits of r.
  static double Signed(uint64_t r) { return (static_cast<double>(r >> 11) + 0.5) * (2.0 / 9007199254740992.0) - 1.0; }
  // Standard normal by the ziggurat method (Marsaglia and Tsang 2000, with Doornik's 2005 use of
  // separate bits for the layer and the value): 128 layers of equal area under exp(-x^2/2); about
  // 99 % of the values cost one random word, one table look-up and one comparison. Exact: the wedges
  // and the tail beyond the base layer are sampled by rejection.
  double Normal() {
    const Ziggurat& z = Zig();
    for (;;) {
      const uint64_t r = Next();
      const int i = static_cast<int>(r & 127);
      const double u = Signed(r);
      if (std::abs(u) < z.ratio[i]) return u * z.x[i];  // inside the layer's rectangle
      if (i == 0) {
        // The tail beyond x[1] = kR (Marsaglia's exponential rejection).
        double a, b;
        do {
          a = -std::log(Uniform()) / Ziggurat::kR;
          b = -std::log(Uniform());
        } while (b + b < a * a);
        return u < 0 ? -(Ziggurat::kR + a) : Ziggurat::kR + a;
      }
      // The wedge between the layer's rectangle and the curve.
      const double x = u * z.x[i];
      const double f0 = std::exp(-0.5 * (z.x[i] * z.x[i] - x * x));
      const double f1 = std::exp(-0.5 * (z.x[i + 1] * z.x[i + 1] - x * x));
      if (f1 + Uniform() * (f0 - f1) < 1.0) return x;
    }
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
