// The optics after the geometry (vignetting, PSF) and the sensor (shot and read noise, quantization).
#include <opencv2/imgproc.hpp>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "shared/sim/render/noise_rng.h"
#include "shared/sim/render/render.h"

namespace idi::sim {

namespace internal {
const Ziggurat kZiggurat;
}  // namespace internal

namespace {

using internal::NormalFrom;
using internal::NormalInRectangle;
using internal::PoissonFrom;
using internal::Xoshiro256;

// The generator's words drawn ahead in blocks and handed out in the generator's order: a pixel that
// draws from here takes the same words as it would from the generator itself, and a run of pixels can
// look at its next words before taking them.
class WordBlock {
 public:
  explicit WordBlock(uint64_t seed) : rng_(seed) {}
  uint64_t Next() {
    if (pos_ == end_) Refill();
    return words_[pos_++];
  }
  // The next n (<= kSize) words, without taking them.
  const uint64_t* Peek(int n) {
    if (end_ - pos_ < n) Refill();
    return words_ + pos_;
  }
  void Take(int n) { pos_ += n; }

 private:
  static constexpr int kSize = 1024;
  void Refill() {
    // Keep the words not yet taken, then draw the rest of the block.
    int k = 0;
    for (int i = pos_; i < end_; ++i) words_[k++] = words_[i];
    for (; k < kSize; ++k) words_[k] = rng_.Next();
    pos_ = 0;
    end_ = kSize;
  }
  Xoshiro256 rng_;
  uint64_t words_[kSize];
  int pos_ = 0, end_ = 0;
};

// std::nearbyint for 0 <= v <= 255 under the default rounding mode (to nearest, ties to even), without
// the library call: adding 1.5 * 2^52 rounds away every fraction bit (IEEE double arithmetic, which
// the compiler keeps without -ffast-math). Clamping before rounding gives the same as after, since 0
// and 255 are integers.
inline double RoundHalfEven(double v) { return (v + 6755399441055744.0) - 6755399441055744.0; }

// What a run of pixels needs of the sensor options.
struct RunParams {
  bool shot = false;             // shot noise: each pixel's normal is scaled by sqrt(gain v + read_var)
  double many_electrons_dn = 0;  // above this a pixel's shot and read noise are one normal value
  double gain = 0, read_var = 0, read_noise_dn = 0, black_level_dn = 0;
};

// The black level, clipping to [0, 255] and rounding of a pixel's value.
inline uint8_t Finish(double v, const RunParams& p) {
  v += p.black_level_dn;
  return static_cast<uint8_t>(RoundHalfEven(std::clamp(v, 0.0, 255.0)));
}

// The leading pixels of the next kRun (in[0..kRun), their irradiance) that need one normal value each
// and whose words (w[0..kRun), the next ones) fall in their ziggurat rectangles: writes their values and
// returns how many they are. The pixel after them (if any) needs Poisson draws or a word beyond the
// rectangle, and is left to the one-at-a-time path.
constexpr int kRun = 8;
int LeadingRun(const float* in, const uint64_t* w, const RunParams& p, uint8_t* out) {
  for (int j = 0; j < kRun; ++j) {
    const double v = std::max(0.0, static_cast<double>(in[j]));
    if (p.shot && !(v > p.many_electrons_dn)) return j;
    double z;
    if (!NormalInRectangle(w[j], &z)) return j;
    const double scale = p.shot ? std::sqrt(p.gain * v + p.read_var) : p.read_noise_dn;
    out[j] = Finish(v + scale * z, p);
  }
  return kRun;
}

#if defined(__x86_64__)
// GCC 12's AVX-512 intrinsics pass _mm512_undefined_pd() as the unused merge source, which its
// uninitialized-value warnings flag.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
// LeadingRun on AVX-512 (F and DQ), 8 pixels at once: the same operations in the same order (the renderer
// is built without fused multiply-adds), so every value is the same. It may write past the leading run;
// those values are written again by whatever takes the pixels next.
[[gnu::target("avx512f,avx512dq")]] int LeadingRunAvx512(const float* in,
                                                         const uint64_t* w,
                                                         const RunParams& p,
                                                         uint8_t* out) {
  const __m512d zero = _mm512_setzero_pd();
  // std::max(0.0, x): vmaxpd returns its second operand for NaN and for two zeros, as std::max its first.
  const __m512d v = _mm512_max_pd(_mm512_cvtps_pd(_mm256_loadu_ps(in)), zero);
  __m512d scale = _mm512_set1_pd(p.read_noise_dn);
  __mmask8 ok = 0xFF;
  if (p.shot) {
    ok = _mm512_cmp_pd_mask(v, _mm512_set1_pd(p.many_electrons_dn), _CMP_GT_OQ);
    scale = _mm512_sqrt_pd(_mm512_add_pd(_mm512_mul_pd(_mm512_set1_pd(p.gain), v), _mm512_set1_pd(p.read_var)));
  }
  // SignedOf and NormalInRectangle.
  const __m512i words = _mm512_loadu_si512(w);
  const __m512i layer = _mm512_and_si512(words, _mm512_set1_epi64(127));
  const __m512d u =
      _mm512_sub_pd(_mm512_mul_pd(_mm512_add_pd(_mm512_cvtepu64_pd(_mm512_srli_epi64(words, 11)), _mm512_set1_pd(0.5)),
                                  _mm512_set1_pd(2.0 / 9007199254740992.0)),
                    _mm512_set1_pd(1.0));
  const internal::Ziggurat& zig = internal::Zig();
  ok &= _mm512_cmp_pd_mask(_mm512_abs_pd(u), _mm512_i64gather_pd(layer, zig.ratio, 8), _CMP_LT_OQ);
  const int leading = ok == 0xFF ? kRun : __builtin_ctz(~static_cast<unsigned>(ok));
  if (leading == 0) return 0;
  const __m512d z = _mm512_mul_pd(u, _mm512_i64gather_pd(layer, zig.x, 8));
  // v + scale z and Finish: the black level, std::clamp to [0, 255] (the values that count are finite)
  // and RoundHalfEven.
  __m512d o = _mm512_add_pd(_mm512_add_pd(v, _mm512_mul_pd(scale, z)), _mm512_set1_pd(p.black_level_dn));
  o = _mm512_min_pd(_mm512_max_pd(o, zero), _mm512_set1_pd(255.0));
  const __m512d round = _mm512_set1_pd(6755399441055744.0);
  o = _mm512_sub_pd(_mm512_add_pd(o, round), round);
  _mm_storel_epi64(reinterpret_cast<__m128i*>(out),
                   _mm512_cvtepi32_epi8(_mm512_castsi256_si512(_mm512_cvttpd_epi32(o))));
  return leading;
}
#pragma GCC diagnostic pop

// LeadingRun on AVX2, the eight pixels as two groups of four: the same operations in the same order as
// LeadingRun, so every value is the same (AVX2 has no 64-bit integer to double conversion; a word's top
// 53 bits are converted in two exact halves, whose sum is exact below 2^53). Like LeadingRunAvx512 it may
// write past the leading run.
[[gnu::target("avx2")]] int LeadingFourAvx2(const float* in, const uint64_t* w, const RunParams& p, uint8_t* out) {
  const __m256d zero = _mm256_setzero_pd();
  // std::max(0.0, x): vmaxpd returns its second operand for NaN and for two zeros, as std::max its first.
  const __m256d v = _mm256_max_pd(_mm256_cvtps_pd(_mm_loadu_ps(in)), zero);
  __m256d scale = _mm256_set1_pd(p.read_noise_dn);
  int ok = 0xF;
  if (p.shot) {
    ok = _mm256_movemask_pd(_mm256_cmp_pd(v, _mm256_set1_pd(p.many_electrons_dn), _CMP_GT_OQ));
    scale = _mm256_sqrt_pd(_mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(p.gain), v), _mm256_set1_pd(p.read_var)));
  }
  const __m256i words = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(w));
  const __m256i layer = _mm256_and_si256(words, _mm256_set1_epi64x(127));
  // double(word >> 11): the high 21 and low 32 bits of the 53, each placed in a double's mantissa.
  const __m256i top = _mm256_srli_epi64(words, 11);
  const __m256d lo =
      _mm256_sub_pd(_mm256_castsi256_pd(_mm256_or_si256(_mm256_and_si256(top, _mm256_set1_epi64x(0xFFFFFFFFLL)),
                                                        _mm256_set1_epi64x(0x4330000000000000LL))),
                    _mm256_set1_pd(4503599627370496.0));  // 2^52
  const __m256d hi = _mm256_sub_pd(
      _mm256_castsi256_pd(_mm256_or_si256(_mm256_srli_epi64(top, 32), _mm256_set1_epi64x(0x4530000000000000LL))),
      _mm256_set1_pd(19342813113834066795298816.0));  // 2^84
  const __m256d top_d = _mm256_add_pd(hi, lo);
  // SignedOf and NormalInRectangle.
  const __m256d u =
      _mm256_sub_pd(_mm256_mul_pd(_mm256_add_pd(top_d, _mm256_set1_pd(0.5)), _mm256_set1_pd(2.0 / 9007199254740992.0)),
                    _mm256_set1_pd(1.0));
  const internal::Ziggurat& zig = internal::Zig();
  const __m256d all = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
  const __m256d abs_u = _mm256_andnot_pd(_mm256_set1_pd(-0.0), u);
  ok &= _mm256_movemask_pd(_mm256_cmp_pd(abs_u, _mm256_mask_i64gather_pd(zero, zig.ratio, layer, all, 8), _CMP_LT_OQ));
  const int leading = ok == 0xF ? 4 : __builtin_ctz(~static_cast<unsigned>(ok));
  if (leading == 0) return 0;
  const __m256d z = _mm256_mul_pd(u, _mm256_mask_i64gather_pd(zero, zig.x, layer, all, 8));
  // v + scale z and Finish: the black level, std::clamp to [0, 255] (the values that count are finite)
  // and RoundHalfEven.
  __m256d o = _mm256_add_pd(_mm256_add_pd(v, _mm256_mul_pd(scale, z)), _mm256_set1_pd(p.black_level_dn));
  o = _mm256_min_pd(_mm256_max_pd(o, zero), _mm256_set1_pd(255.0));
  const __m256d round = _mm256_set1_pd(6755399441055744.0);
  o = _mm256_sub_pd(_mm256_add_pd(o, round), round);
  const __m128i i32 = _mm256_cvttpd_epi32(o);
  const __m128i bytes = _mm_packus_epi16(_mm_packus_epi32(i32, i32), _mm_setzero_si128());
  const int packed = _mm_cvtsi128_si32(bytes);
  std::memcpy(out, &packed, 4);
  return leading;
}

[[gnu::target("avx2")]] int LeadingRunAvx2(const float* in, const uint64_t* w, const RunParams& p, uint8_t* out) {
  const int first = LeadingFourAvx2(in, w, p, out);
  if (first < 4) return first;
  return 4 + LeadingFourAvx2(in + 4, w + 4, p, out + 4);
}
#endif

}  // namespace

Status SensorOptions::Check() const {
  if (!std::isfinite(gain_dn_per_electron) || gain_dn_per_electron < 0) {
    return InvalidArgument("sensor gain_dn_per_electron must be >= 0, got " + FormatNumber(gain_dn_per_electron));
  }
  if (!std::isfinite(read_noise_dn) || read_noise_dn < 0) {
    return InvalidArgument("sensor read_noise_dn must be >= 0, got " + FormatNumber(read_noise_dn));
  }
  if (!std::isfinite(black_level_dn) || black_level_dn < 0 || black_level_dn > 255) {
    return InvalidArgument("sensor black_level_dn must be in [0, 255], got " + FormatNumber(black_level_dn));
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
  WordBlock words(seed ^ 0x5EEDF00DULL);
  const bool shot = sensor.noise && sensor.gain_dn_per_electron > 0;
  const bool read = sensor.noise && sensor.read_noise_dn > 0;
  const double gain = sensor.gain_dn_per_electron;
  const double read_var = read ? sensor.read_noise_dn * sensor.read_noise_dn : 0.0;
  RunParams params;
  params.shot = shot;
  params.many_electrons_dn = 30 * gain;
  params.gain = gain;
  params.read_var = read_var;
  params.read_noise_dn = sensor.read_noise_dn;
  params.black_level_dn = sensor.black_level_dn;
  // One pixel, its words taken one at a time.
  const auto pixel = [&](float x) {
    double v = std::max(0.0, static_cast<double>(x));
    if (shot && v > params.many_electrons_dn) {
      // Many electrons: shot and read noise together are normal with the summed variance.
      v += std::sqrt(gain * v + read_var) * NormalFrom(words);
    } else {
      if (shot) v = gain * PoissonFrom(words, v / gain);
      if (read) v += sensor.read_noise_dn * NormalFrom(words);
    }
    return Finish(v, params);
  };
#if defined(__x86_64__)
  static const bool avx512 = __builtin_cpu_supports("avx512f") != 0 && __builtin_cpu_supports("avx512dq") != 0;
  static const bool avx2 = __builtin_cpu_supports("avx2") != 0;
#endif
  for (int r = 0; r < irradiance_dn.rows; ++r) {
    const float* in = irradiance_dn.ptr<float>(r);
    uint8_t* o = out.ptr<uint8_t>(r);
    const int n = irradiance_dn.cols * channels;
    int k = 0;
    if (shot || read) {
      // Pixels that need one normal value whose word falls in its ziggurat rectangle (about 99 % of
      // them) are taken a run at a time, with their words; the others one at a time. Either way every
      // pixel gets the words it would get alone.
      while (k + kRun <= n) {
        const uint64_t* w = words.Peek(kRun);
#if defined(__x86_64__)
        const int done = avx512 ? LeadingRunAvx512(in + k, w, params, o + k)
                         : avx2 ? LeadingRunAvx2(in + k, w, params, o + k)
                                : LeadingRun(in + k, w, params, o + k);
#else
        const int done = LeadingRun(in + k, w, params, o + k);
#endif
        words.Take(done);
        k += done;
        if (done < kRun) {
          o[k] = pixel(in[k]);
          ++k;
        }
      }
    }
    for (; k < n; ++k) o[k] = pixel(in[k]);
  }
  return out;
}

}  // namespace idi::sim
