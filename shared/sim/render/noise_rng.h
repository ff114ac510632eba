// The sensor model's random numbers (internal to the renderer; sensor.cc and its tests): xoshiro256**
// words, and uniform, normal and Poisson draws made from any source of such words. The draws are
// templates on the word source so that a pixel takes exactly the same words whether it draws them one at
// a time from the generator or from a block drawn ahead (ApplySensor): the noise an image gets for a
// seed does not depend on how it is computed.
#pragma once

#include <cmath>
#include <cstdint>

namespace idi::sim::internal {

// The ziggurat's layers: x[i] is the right edge of layer i (x[0] the base layer's width including its
// tail, x[1] = kR, x[128] = 0); ratio[i] = x[i+1] / x[i], the part of layer i under the curve for any
// height.
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
extern const Ziggurat kZiggurat;  // built at load time (sensor.cc)
inline const Ziggurat& Zig() { return kZiggurat; }

// xoshiro256** seeded by splitmix64: fast, and the same seed gives the same noise everywhere.
class Xoshiro256 {
 public:
  explicit Xoshiro256(uint64_t seed) {
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

 private:
  static uint64_t Rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  uint64_t s_[4];
};

// Uniform in (0, 1) from the top 53 bits of a word.
inline double UniformOf(uint64_t r) { return (static_cast<double>(r >> 11) + 0.5) * (1.0 / 9007199254740992.0); }
// Uniform in (-1, 1) from the top 53 bits of a word.
inline double SignedOf(uint64_t r) { return (static_cast<double>(r >> 11) + 0.5) * (2.0 / 9007199254740992.0) - 1.0; }

// The ziggurat's common case: the word's layer (its low 7 bits) and value (its top 53 bits) fall inside
// the layer's rectangle, and the normal value is u * x[layer]. False for the rest (about 1.2 % of words),
// which NormalFrom finishes by rejection.
inline bool NormalInRectangle(uint64_t r, double* z) {
  const Ziggurat& zig = Zig();
  const int i = static_cast<int>(r & 127);
  const double u = SignedOf(r);
  *z = u * zig.x[i];
  return std::abs(u) < zig.ratio[i];
}

// The ziggurat's rejection steps after a first word `r` that missed its rectangle: the tail beyond the
// base layer (Marsaglia's exponential rejection) or the wedge between a layer's rectangle and the curve;
// on a rejection, new words from `words` until a value is accepted.
template <class Words>
double NormalAfterMiss(Words& words, uint64_t r) {
  const Ziggurat& zig = Zig();
  for (;;) {
    const int i = static_cast<int>(r & 127);
    const double u = SignedOf(r);
    if (std::abs(u) < zig.ratio[i]) return u * zig.x[i];
    if (i == 0) {
      double a, b;
      do {
        a = -std::log(UniformOf(words.Next())) / Ziggurat::kR;
        b = -std::log(UniformOf(words.Next()));
      } while (b + b < a * a);
      return u < 0 ? -(Ziggurat::kR + a) : Ziggurat::kR + a;
    }
    const double x = u * zig.x[i];
    const double f0 = std::exp(-0.5 * (zig.x[i] * zig.x[i] - x * x));
    const double f1 = std::exp(-0.5 * (zig.x[i + 1] * zig.x[i + 1] - x * x));
    if (f1 + UniformOf(words.Next()) * (f0 - f1) < 1.0) return x;
    r = words.Next();
  }
}

// Standard normal by the ziggurat method (Marsaglia and Tsang 2000, with Doornik's 2005 use of separate
// bits for the layer and the value): 128 layers of equal area under exp(-x^2/2); about 99 % of the values
// cost one word, one table look-up and one comparison. Exact: the wedges and the tail beyond the base
// layer are sampled by rejection.
template <class Words>
double NormalFrom(Words& words) {
  const uint64_t r = words.Next();
  double z;
  if (NormalInRectangle(r, &z)) return z;
  return NormalAfterMiss(words, r);
}

// Poisson: exact (multiplication method); used for small means only.
template <class Words>
double PoissonFrom(Words& words, double mean) {
  if (mean <= 0) return 0;
  const double limit = std::exp(-mean);
  double prod = UniformOf(words.Next());
  int k = 0;
  while (prod > limit) {
    prod *= UniformOf(words.Next());
    ++k;
  }
  return k;
}

}  // namespace idi::sim::internal
