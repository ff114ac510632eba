// Lambertian shading with procedural textures filtered over the pixel footprint.
#include <algorithm>
#include <cmath>
#include <array>
#include <cstdint>
#include <limits>
#include <utility>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "shared/sim/render/raster_internal.h"

namespace idi::sim::internal {
namespace {

uint64_t MixBits(uint64_t x) {
  x ^= x >> 33;
  x *= 0xff51afd7ed558ccdULL;
  x ^= x >> 33;
  x *= 0xc4ceb9fe1a85ec53ULL;
  x ^= x >> 33;
  return x;
}

// Lattice values for value noise: a fixed random permutation and value table (Perlin's construction);
// a texture's seed and octave shift the lattice, so every texture gets its own pattern.
struct NoiseTables {
  std::array<uint8_t, 256> perm;
  std::array<double, 256> value;
  // The lattice value of every cell (i, j) mod 256, looked up once: lattice[256 i + j] =
  // value[perm[(perm[i] + j) & 255]] (512 KB; the cells one tile of pixels reads stay in L1).
  std::array<double, 256 * 256> lattice;
  NoiseTables() {
    uint64_t state = 0x1D1C0FFEEULL;
    for (int i = 0; i < 256; ++i) perm[static_cast<std::size_t>(i)] = static_cast<uint8_t>(i);
    for (int i = 255; i > 0; --i) {
      state = MixBits(state + 0x9E3779B97F4A7C15ULL);
      std::swap(perm[static_cast<std::size_t>(i)], perm[static_cast<std::size_t>(state % static_cast<uint64_t>(i + 1))]);
    }
    for (int i = 0; i < 256; ++i) {
      state = MixBits(state + 0x9E3779B97F4A7C15ULL);
      value[static_cast<std::size_t>(i)] = static_cast<double>(state >> 11) * (2.0 / 9007199254740992.0) - 1.0;
    }
    for (std::size_t i = 0; i < 256; ++i) {
      for (std::size_t j = 0; j < 256; ++j) lattice[i * 256 + j] = value[perm[(perm[i] + j) & 255]];
    }
  }
};

// Built at load time (no initialisation guard in the per-pixel path).
const NoiseTables kNoiseTables;
inline const NoiseTables& Tables() { return kNoiseTables; }

// Hash of a lattice point to [-1, 1] (period 256 cells).
inline double LatticeValue(int64_t i, int64_t j, const NoiseTables& t) {
  const uint8_t a = t.perm[static_cast<std::size_t>(i & 255)];
  return t.value[t.perm[static_cast<std::size_t>((a + j) & 255)]];
}

double Quintic(double t) { return t * t * t * (t * (t * 6 - 15) + 10); }

// floor() without a libm call (the default x86-64 target has no SSE4.1 rounding instruction).
inline double FastFloor(double x) {
  const double t = static_cast<double>(static_cast<int64_t>(x));
  return t > x ? t - 1 : t;
}

// Smooth value noise in [-1, 1] with unit lattice spacing; `shift` moves the lattice (per seed/octave).
// The four corner values are looked up every time (one load each from the lattice table): cheaper
// than remembering the last cell, whose hit-or-miss branch the octaves' varying cell sizes make
// unpredictable, and the octaves' work stays independent so that they overlap. ShadeBatch's vector
// code does the same operations in the same order.
inline double ValueNoise(double x, double y, int64_t shift_x, int64_t shift_y, const NoiseTables& t) {
  const double fx = FastFloor(x), fy = FastFloor(y);
  const auto ix = static_cast<int64_t>(fx) + shift_x, iy = static_cast<int64_t>(fy) + shift_y;
  const double tx = Quintic(x - fx), ty = Quintic(y - fy);
  const auto i0 = static_cast<std::size_t>(ix & 255) * 256, i1 = static_cast<std::size_t>((ix + 1) & 255) * 256;
  const auto j0 = static_cast<std::size_t>(iy & 255), j1 = static_cast<std::size_t>((iy + 1) & 255);
  const double a = t.lattice[i0 + j0], b = t.lattice[i1 + j0];
  const double c = t.lattice[i0 + j1], d = t.lattice[i1 + j1];
  const double ab = a + (b - a) * tx;
  return ab + ((c + (d - c) * tx) - ab) * ty;
}

// Length of grout within (-inf, x] measured from 0, for grout lines of width g centred on multiples of
// the period p: the integral of the pulse train, so a box filter is a difference of two values.
inline double GroutIntegral(double x, double p, double inv_p, double g) {
  const double s = x + g / 2;
  const double k = FastFloor(s * inv_p);
  return k * g + std::min(s - k * p, g);
}

// Fraction of [x - f/2, x + f/2] covered by grout.
inline double FilteredGrout(double x, double f, double p, double inv_p, double g) {
  if (g <= 0) return 0;
  if (f < 1e-9 * p) {
    const double s = x + g / 2;
    return s - FastFloor(s * inv_p) * p < g ? 1.0 : 0.0;
  }
  return (GroutIntegral(x + f / 2, p, inv_p, g) - GroutIntegral(x - f / 2, p, inv_p, g)) / f;
}

}  // namespace

TexturePlan MakeTexturePlan(const Texture& t) {
  TexturePlan plan;
  plan.texture = &t;
  plan.octaves = std::min(t.noise_octaves, static_cast<int>(plan.inv_wavelength.size()));
  double amp = 1, norm = 0, wavelength = t.noise_scale;
  for (int o = 0; o < plan.octaves; ++o) {
    const uint64_t h = MixBits(t.seed * 31 + static_cast<uint64_t>(o));
    plan.shift_x[static_cast<std::size_t>(o)] = static_cast<int64_t>(h & 255);
    plan.shift_y[static_cast<std::size_t>(o)] = static_cast<int64_t>((h >> 8) & 255);
    plan.inv_wavelength[static_cast<std::size_t>(o)] = 1 / wavelength;
    plan.amplitude[static_cast<std::size_t>(o)] = amp;
    norm += amp;
    amp *= 0.5;
    wavelength *= 0.5;
  }
  for (int o = 0; o < plan.octaves; ++o) plan.amplitude[static_cast<std::size_t>(o)] *= t.noise_amplitude / norm;
  if (t.tile_size > 0) plan.inv_tile = 1 / t.tile_size;
  plan.tile_shift = static_cast<int64_t>(MixBits(t.seed ^ 0x7715ULL) & 255);
  return plan;
}

namespace {

// The texture's albedo at (u, v) averaged over a footprint fu x fv.
Vec3d TexturedAlbedo(const TexturePlan& plan, const Vec3d& base, double u, double v, double fu, double fv) {
  const Texture& t = *plan.texture;
  Vec3d albedo = base;
  if (t.tile_size > 0) {
    const double p = t.tile_size;
    if (t.tile_jitter > 0) {
      // Per-tile brightness; faded out when the footprint spans several tiles (its average is 1).
      const double fade = std::clamp(2.0 - 2.0 * std::max(fu, fv) * plan.inv_tile, 0.0, 1.0);
      if (fade > 0) {
        const double h = LatticeValue(static_cast<int64_t>(FastFloor(u * plan.inv_tile + 0.5)) + plan.tile_shift,
                                      static_cast<int64_t>(FastFloor(v * plan.inv_tile + 0.5)), Tables());
        albedo *= 1 + fade * t.tile_jitter * h;
      }
    }
    const double gu = FilteredGrout(u, fu, p, plan.inv_tile, t.grout_width);
    const double gv = FilteredGrout(v, fv, p, plan.inv_tile, t.grout_width);
    const double g = 1 - (1 - gu) * (1 - gv);
    albedo = (1 - g) * albedo + g * t.grout_albedo;
  }
  if (plan.octaves > 0 && t.noise_amplitude > 0) {
    const NoiseTables& tables = Tables();
    const double f = std::max(fu, fv);
    double sum = 0;
    for (int o = 0; o < plan.octaves; ++o) {
      const std::size_t k = static_cast<std::size_t>(o);
      // Octaves finer than the footprint average to zero: fade them out (frequency clamping).
      const double fade = std::clamp(2.0 - 4.0 * f * plan.inv_wavelength[k], 0.0, 1.0);
      if (fade <= 0) break;  // every finer octave is faded out too
      sum +=
          fade * plan.amplitude[k] *
          ValueNoise(u * plan.inv_wavelength[k], v * plan.inv_wavelength[k], plan.shift_x[k], plan.shift_y[k], tables);
    }
    albedo *= std::max(0.0, 1 + sum);
  }
  return albedo;
}

// A surface point's texture coordinates and the footprint of `footprint_px` pixels in texture units:
// the derivative of the surface point along x and y, dp/dx = (e_x / fx) / w - ray (dw/dx) / w^2 (and
// likewise for y), dotted with the texture axes. inv_w = z on the face's plane (w = 1/z); the ray is
// (rx, ry, 1). Per shaded point: reciprocals are multiplied, not divided by. Written out term by term
// (no Eigen reductions) so that ShadeBatch's vector code can do the same operations in the same order.
struct TexturePoint {
  double u, v, fu, fv;
};
[[gnu::always_inline]] inline TexturePoint TextureAt(
    const Prepared& prep, const Surface& s, double rx, double ry, double inv_w, double footprint_px) {
  const double dw_dx = s.normal.x() * prep.inv_fx * s.inv_d * inv_w * inv_w;
  const double dw_dy = s.normal.y() * prep.inv_fy * s.inv_d * inv_w * inv_w;
  const double tu_r = s.tex_u.x() * rx + s.tex_u.y() * ry + s.tex_u.z();
  const double tv_r = s.tex_v.x() * rx + s.tex_v.y() * ry + s.tex_v.z();
  const double zx = inv_w * prep.inv_fx, zy = inv_w * prep.inv_fy;
  TexturePoint tp;
  tp.fu = footprint_px * (std::abs(s.tex_u.x() * zx - tu_r * dw_dx) + std::abs(s.tex_u.y() * zy - tu_r * dw_dy));
  tp.fv = footprint_px * (std::abs(s.tex_v.x() * zx - tv_r * dw_dx) + std::abs(s.tex_v.y() * zy - tv_r * dw_dy));
  tp.u = tu_r * inv_w + s.tex_u0;
  tp.v = tv_r * inv_w + s.tex_v0;
  return tp;
}

// z on the face's plane along the ray (rx, ry, 1).
inline double DepthAlong(const Surface& s, double rx, double ry) {
  return 1 / ((s.normal.x() * rx + s.normal.y() * ry + s.normal.z()) * s.inv_d);
}

// The illumination gradient's factor at the surface point (px, py, pz).
inline double GradientFactor(const IlluminationGradient& g, double px, double py, double pz) {
  const double dot = g.gradient.x() * (px - g.origin.x()) + g.gradient.y() * (py - g.origin.y()) +
                     g.gradient.z() * (pz - g.origin.z());
  return std::max(g.min_factor, 1 + dot);
}

}  // namespace

Vec3d Shade(const Prepared& prep, const Surface& s, double x, double y, double footprint_px) {
  if (s.constant) return s.radiance;
  const double rx = (x - prep.cx) * prep.inv_fx, ry = (y - prep.cy) * prep.inv_fy;
  const double inv_w = DepthAlong(s, rx, ry);  // z on the face's plane
  const Vec3d p(rx * inv_w, ry * inv_w, inv_w);
  double irradiance = s.flat_irradiance;
  Vec3d n = s.normal;
  if (s.cylinder) {
    const Vec3d rel = p - s.axis_point;
    n = (rel - rel.dot(s.axis_dir) * s.axis_dir).normalized();
    irradiance = prep.ambient;
    for (std::size_t k = 0; k < prep.light_dirs.size(); ++k) {
      irradiance += prep.light_intensity[k] * std::max(0.0, n.dot(prep.light_dirs[k]));
    }
  }
  for (const SpotLight& sl : prep.spotlights) {
    const Vec3d to_light = sl.position - p;
    const double dist = to_light.norm();
    if (!(dist > 0)) continue;
    const Vec3d l = to_light / dist;
    const double cos_inc = n.dot(l);
    if (cos_inc <= 0) continue;
    const double cos_axis = -l.dot(sl.direction);
    // Prepare stored the cone's cosine in cone_half_angle_rad (see Prepare).
    const double cos_cone = sl.cone_half_angle_rad;
    if (cos_axis <= cos_cone) continue;
    // cos^m falloff inside the cone, and a smooth edge over the outer 10% of the cone.
    const double edge = std::clamp((cos_axis - cos_cone) / (0.1 * (1 - cos_cone)), 0.0, 1.0);
    const double r = sl.reference_distance / dist;
    const double m = sl.falloff_exponent;
    double falloff = 1;
    if (m == FastFloor(m) && m <= 16) {
      for (int k = 0; k < static_cast<int>(m); ++k) falloff *= cos_axis;
    } else {
      falloff = std::pow(cos_axis, m);
    }
    irradiance += sl.intensity * cos_inc * r * r * falloff * edge * edge * (3 - 2 * edge);
  }
  if (prep.has_gradient) irradiance *= GradientFactor(prep.gradient, p.x(), p.y(), p.z());
  Vec3d albedo = s.albedo;
  if (s.texture != nullptr) {
    const TexturePoint tp = TextureAt(prep, s, rx, ry, inv_w, footprint_px);
    albedo = TexturedAlbedo(prep.texture_plans[static_cast<std::size_t>(s.texture_plan)], albedo, tp.u, tp.v, tp.fu, tp.fv);
  }
  return irradiance * albedo;
}

#if defined(__x86_64__)
namespace {

#define IDI_AVX2 [[gnu::target("avx2"), gnu::always_inline]] inline
// a u + b v + c, summed left to right as the scalar expression is.
IDI_AVX2 __m256d Lin(double a, __m256d u, double b, __m256d v, double c) {
  return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(a), u), _mm256_mul_pd(_mm256_set1_pd(b), v)),
                       _mm256_set1_pd(c));
}
IDI_AVX2 __m256d Abs(__m256d v) { return _mm256_andnot_pd(_mm256_set1_pd(-0.0), v); }
// |a zx - t_r dw| as in TextureAt.
IDI_AVX2 __m256d Extent(double a, __m256d z, __m256d t_r, __m256d dw) {
  return Abs(_mm256_sub_pd(_mm256_mul_pd(_mm256_set1_pd(a), z), _mm256_mul_pd(t_r, dw)));
}
IDI_AVX2 __m256d Quintic4(__m256d t) {
  const __m256d t3 = _mm256_mul_pd(_mm256_mul_pd(t, t), t);
  const __m256d inner = _mm256_sub_pd(_mm256_mul_pd(t, _mm256_set1_pd(6.0)), _mm256_set1_pd(15.0));
  return _mm256_mul_pd(t3, _mm256_add_pd(_mm256_mul_pd(t, inner), _mm256_set1_pd(10.0)));
}
// table[idx[k]] for the four lanes (the masked form: the plain one trips GCC 12's uninitialised-use
// warning on its undefined source operand).
IDI_AVX2 __m256d Gather(const double* table, __m128i idx) {
  return _mm256_mask_i32gather_pd(_mm256_setzero_pd(), table, idx, _mm256_castsi256_pd(_mm256_set1_epi64x(-1)), 8);
}
// (a < b) ? b : a, i.e. std::max(a, b).
IDI_AVX2 __m256d Max(__m256d a, __m256d b) { return _mm256_blendv_pd(a, b, _mm256_cmp_pd(a, b, _CMP_LT_OQ)); }

// Four points of one surface at once with AVX2 (no FMA: the same roundings as Shade, operation for
// operation, so the image does not depend on the path). For what ShadeBatch hands it: not constant,
// not a cylinder, no spotlights, no tiles. Writes the radiance to rgb, or its luma to luma when that is
// not null. False (nothing written) when a noise coordinate is beyond what 32-bit lattice indices
// hold; the caller then shades those points one by one.
[[gnu::target("avx2")]] bool ShadeFourAvx2(const Prepared& prep,
                                           const Surface& s,
                                           const TexturePlan* plan,
                                           const double* x,
                                           const double* y,
                                           const double* footprint,
                                           Vec3d* rgb,
                                           float* luma) {
  const __m256d rx =
      _mm256_mul_pd(_mm256_sub_pd(_mm256_loadu_pd(x), _mm256_set1_pd(prep.cx)), _mm256_set1_pd(prep.inv_fx));
  const __m256d ry =
      _mm256_mul_pd(_mm256_sub_pd(_mm256_loadu_pd(y), _mm256_set1_pd(prep.cy)), _mm256_set1_pd(prep.inv_fy));
  const __m256d one = _mm256_set1_pd(1.0);
  const __m256d inv_w =
      _mm256_div_pd(one, _mm256_mul_pd(Lin(s.normal.x(), rx, s.normal.y(), ry, s.normal.z()), _mm256_set1_pd(s.inv_d)));
  __m256d irradiance = _mm256_set1_pd(s.flat_irradiance);
  if (prep.has_gradient) {
    const IlluminationGradient& g = prep.gradient;
    const __m256d px = _mm256_mul_pd(rx, inv_w), py = _mm256_mul_pd(ry, inv_w);
    const __m256d dot = _mm256_add_pd(
        _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(g.gradient.x()), _mm256_sub_pd(px, _mm256_set1_pd(g.origin.x()))),
                      _mm256_mul_pd(_mm256_set1_pd(g.gradient.y()), _mm256_sub_pd(py, _mm256_set1_pd(g.origin.y())))),
        _mm256_mul_pd(_mm256_set1_pd(g.gradient.z()), _mm256_sub_pd(inv_w, _mm256_set1_pd(g.origin.z()))));
    // std::max(min_factor, v) = (min_factor < v) ? v : min_factor.
    const __m256d v = _mm256_add_pd(one, dot), lo = _mm256_set1_pd(g.min_factor);
    irradiance = _mm256_mul_pd(irradiance, Max(lo, v));
  }
  __m256d factor = one;  // the noise's albedo factor
  if (plan != nullptr) {
    const __m256d dw_dx =
        _mm256_mul_pd(_mm256_mul_pd(_mm256_set1_pd(s.normal.x() * prep.inv_fx * s.inv_d), inv_w), inv_w);
    const __m256d dw_dy =
        _mm256_mul_pd(_mm256_mul_pd(_mm256_set1_pd(s.normal.y() * prep.inv_fy * s.inv_d), inv_w), inv_w);
    const __m256d tu_r = Lin(s.tex_u.x(), rx, s.tex_u.y(), ry, s.tex_u.z());
    const __m256d tv_r = Lin(s.tex_v.x(), rx, s.tex_v.y(), ry, s.tex_v.z());
    const __m256d zx = _mm256_mul_pd(inv_w, _mm256_set1_pd(prep.inv_fx)),
                  zy = _mm256_mul_pd(inv_w, _mm256_set1_pd(prep.inv_fy));
    const __m256d foot = _mm256_loadu_pd(footprint);
    const __m256d fu =
        _mm256_mul_pd(foot, _mm256_add_pd(Extent(s.tex_u.x(), zx, tu_r, dw_dx), Extent(s.tex_u.y(), zy, tu_r, dw_dy)));
    const __m256d fv =
        _mm256_mul_pd(foot, _mm256_add_pd(Extent(s.tex_v.x(), zx, tv_r, dw_dx), Extent(s.tex_v.y(), zy, tv_r, dw_dy)));
    const __m256d u = _mm256_add_pd(_mm256_mul_pd(tu_r, inv_w), _mm256_set1_pd(s.tex_u0));
    const __m256d v = _mm256_add_pd(_mm256_mul_pd(tv_r, inv_w), _mm256_set1_pd(s.tex_v0));
    // std::max(fu, fv) = (fu < fv) ? fv : fu.
    const __m256d f4 = _mm256_mul_pd(_mm256_set1_pd(4.0), Max(fu, fv));
    const double* lattice = Tables().lattice.data();
    const __m256d limit = _mm256_set1_pd(1073741824.0);  // 2^30: lattice indices fit in 32 bits
    const __m128i mask = _mm_set1_epi32(255);
    __m256d sum = _mm256_setzero_pd();
    for (int o = 0; o < plan->octaves; ++o) {
      const std::size_t k = static_cast<std::size_t>(o);
      const __m256d inv_wl = _mm256_set1_pd(plan->inv_wavelength[k]);
      // clamp(2 - 4 f / wavelength, 0, 1); an octave faded out everywhere ends the sum, as in Shade
      // (a lane faded out earlier adds 0 x its noise, which leaves its sum unchanged).
      const __m256d fade = _mm256_min_pd(
          _mm256_max_pd(_mm256_sub_pd(_mm256_set1_pd(2.0), _mm256_mul_pd(f4, inv_wl)), _mm256_setzero_pd()), one);
      if (_mm256_movemask_pd(_mm256_cmp_pd(fade, _mm256_setzero_pd(), _CMP_GT_OQ)) == 0) break;
      const __m256d nx = _mm256_mul_pd(u, inv_wl), ny = _mm256_mul_pd(v, inv_wl);
      if (_mm256_movemask_pd(_mm256_or_pd(_mm256_cmp_pd(Abs(nx), limit, _CMP_NLT_UQ),
                                          _mm256_cmp_pd(Abs(ny), limit, _CMP_NLT_UQ))) != 0) {
        return false;
      }
      const __m256d fx = _mm256_floor_pd(nx), fy = _mm256_floor_pd(ny);
      const __m128i ix = _mm_add_epi32(_mm256_cvttpd_epi32(fx), _mm_set1_epi32(static_cast<int>(plan->shift_x[k])));
      const __m128i iy = _mm_add_epi32(_mm256_cvttpd_epi32(fy), _mm_set1_epi32(static_cast<int>(plan->shift_y[k])));
      const __m128i i0 = _mm_slli_epi32(_mm_and_si128(ix, mask), 8);
      const __m128i i1 = _mm_slli_epi32(_mm_and_si128(_mm_add_epi32(ix, _mm_set1_epi32(1)), mask), 8);
      const __m128i j0 = _mm_and_si128(iy, mask);
      const __m128i j1 = _mm_and_si128(_mm_add_epi32(iy, _mm_set1_epi32(1)), mask);
      __m256d a, b, c, d;
      const __m128i same_cell =
          _mm_and_si128(_mm_cmpeq_epi32(ix, _mm_shuffle_epi32(ix, 0)), _mm_cmpeq_epi32(iy, _mm_shuffle_epi32(iy, 0)));
      if (_mm_movemask_epi8(same_cell) == 0xFFFF) {
        // The four points in one lattice cell (the common case for the coarser octaves): its corners
        // loaded once each.
        const int c00 = _mm_cvtsi128_si32(_mm_add_epi32(i0, j0)), c10 = _mm_cvtsi128_si32(_mm_add_epi32(i1, j0));
        const int c01 = _mm_cvtsi128_si32(_mm_add_epi32(i0, j1)), c11 = _mm_cvtsi128_si32(_mm_add_epi32(i1, j1));
        a = _mm256_broadcast_sd(lattice + c00);
        b = _mm256_broadcast_sd(lattice + c10);
        c = _mm256_broadcast_sd(lattice + c01);
        d = _mm256_broadcast_sd(lattice + c11);
      } else {
        a = Gather(lattice, _mm_add_epi32(i0, j0));
        b = Gather(lattice, _mm_add_epi32(i1, j0));
        c = Gather(lattice, _mm_add_epi32(i0, j1));
        d = Gather(lattice, _mm_add_epi32(i1, j1));
      }
      const __m256d tx = Quintic4(_mm256_sub_pd(nx, fx)), ty = Quintic4(_mm256_sub_pd(ny, fy));
      const __m256d ab = _mm256_add_pd(a, _mm256_mul_pd(_mm256_sub_pd(b, a), tx));
      const __m256d cd = _mm256_add_pd(c, _mm256_mul_pd(_mm256_sub_pd(d, c), tx));
      const __m256d noise = _mm256_add_pd(ab, _mm256_mul_pd(_mm256_sub_pd(cd, ab), ty));
      sum = _mm256_add_pd(sum, _mm256_mul_pd(_mm256_mul_pd(fade, _mm256_set1_pd(plan->amplitude[k])), noise));
    }
    // std::max(0.0, 1 + sum) = (0 < 1 + sum) ? 1 + sum : 0.
    const __m256d t = _mm256_add_pd(one, sum);
    factor = Max(_mm256_setzero_pd(), t);
  }
  // irradiance x (albedo x factor) per channel, as Shade's irradiance * albedo (factor 1 leaves the
  // albedo as it is).
  const __m256d r = _mm256_mul_pd(irradiance, _mm256_mul_pd(_mm256_set1_pd(s.albedo.x()), factor));
  const __m256d g = _mm256_mul_pd(irradiance, _mm256_mul_pd(_mm256_set1_pd(s.albedo.y()), factor));
  const __m256d b = _mm256_mul_pd(irradiance, _mm256_mul_pd(_mm256_set1_pd(s.albedo.z()), factor));
  if (luma != nullptr) {
    // Luma() and the cast to float of the rasterizer's store.
    const __m256d l =
        _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(0.299), r), _mm256_mul_pd(_mm256_set1_pd(0.587), g)),
                      _mm256_mul_pd(_mm256_set1_pd(0.114), b));
    _mm_storeu_ps(luma, _mm256_cvtpd_ps(l));
    return true;
  }
  alignas(32) double rr[4], gg[4], bb[4];
  _mm256_store_pd(rr, r);
  _mm256_store_pd(gg, g);
  _mm256_store_pd(bb, b);
  for (std::size_t k = 0; k < 4; ++k) rgb[k] = Vec3d(rr[k], gg[k], bb[k]);
  return true;
}

// GCC 12's AVX-512 intrinsics pass _mm512_undefined_pd() as the unused merge source, which its
// uninitialised-use analysis reports once they are inlined.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#define IDI_AVX512 [[gnu::target("avx512f"), gnu::always_inline]] inline
// The AVX2 helpers above on eight lanes.
IDI_AVX512 __m512d Lin8(double a, __m512d u, double b, __m512d v, double c) {
  return _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(_mm512_set1_pd(a), u), _mm512_mul_pd(_mm512_set1_pd(b), v)),
                       _mm512_set1_pd(c));
}
IDI_AVX512 __m512d Abs8(__m512d v) { return _mm512_abs_pd(v); }
IDI_AVX512 __m512d Extent8(double a, __m512d z, __m512d t_r, __m512d dw) {
  return Abs8(_mm512_sub_pd(_mm512_mul_pd(_mm512_set1_pd(a), z), _mm512_mul_pd(t_r, dw)));
}
IDI_AVX512 __m512d Quintic8(__m512d t) {
  const __m512d t3 = _mm512_mul_pd(_mm512_mul_pd(t, t), t);
  const __m512d inner = _mm512_sub_pd(_mm512_mul_pd(t, _mm512_set1_pd(6.0)), _mm512_set1_pd(15.0));
  return _mm512_mul_pd(t3, _mm512_add_pd(_mm512_mul_pd(t, inner), _mm512_set1_pd(10.0)));
}
IDI_AVX512 __m512d Gather8(const double* table, __m256i idx) {
  return _mm512_mask_i32gather_pd(_mm512_setzero_pd(), 0xFF, idx, table, 8);
}
IDI_AVX512 __m512d Max8(__m512d a, __m512d b) {
  return _mm512_mask_blend_pd(_mm512_cmp_pd_mask(a, b, _CMP_LT_OQ), a, b);
}
IDI_AVX512 __m512d Floor8(__m512d v) {
  return _mm512_mask_roundscale_pd(_mm512_setzero_pd(), 0xFF, v, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
}
// The minimum of the eight lanes, in every lane.
IDI_AVX512 __m256i MinOverLanes(__m256i v) {
  v = _mm256_min_epi32(v, _mm256_permute2x128_si256(v, v, 1));
  v = _mm256_min_epi32(v, _mm256_shuffle_epi32(v, _MM_SHUFFLE(1, 0, 3, 2)));
  return _mm256_min_epi32(v, _mm256_shuffle_epi32(v, _MM_SHUFFLE(2, 3, 0, 1)));
}
// The four corners of eight points' cells (lattice cell (ix, iy) of each lane) when the points lie within
// three cells by three (a row of neighbouring pixels, most of the time): the 4 x 4 lattice values
// around them are four row loads, and each corner is a permutation of them instead of a gather. False
// (nothing written) for points spread wider, or where the patch would wrap around the lattice's columns.
IDI_AVX512 bool CornersFromPatch(
    const double* lattice, __m256i ix, __m256i iy, __m512d* a, __m512d* b, __m512d* c, __m512d* d) {
  const __m256i x_min = MinOverLanes(ix), y_min = MinOverLanes(iy);
  const __m256i dx = _mm256_sub_epi32(ix, x_min), dy = _mm256_sub_epi32(iy, y_min);  // >= 0
  const __m256i beyond = _mm256_cmpgt_epi32(_mm256_max_epi32(dx, dy), _mm256_set1_epi32(2));
  const int x0 = _mm256_cvtsi256_si32(x_min), y0 = _mm256_cvtsi256_si32(y_min) & 255;
  if (!_mm256_testz_si256(beyond, beyond) || y0 > 252) return false;
  const auto row = [&](int k) { return lattice + (((x0 + k) & 255) << 8) + y0; };
  // Slot 4 r + q: row x0 + r, column y0 + q (r, q in 0 .. 3); slots 0-7 in lo, 8-15 in hi.
  const __m512d lo = _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_loadu_pd(row(0))), _mm256_loadu_pd(row(1)), 1);
  const __m512d hi = _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_loadu_pd(row(2))), _mm256_loadu_pd(row(3)), 1);
  const __m512i slot = _mm512_cvtepi32_epi64(_mm256_add_epi32(_mm256_slli_epi32(dx, 2), dy));  // (ix, iy)
  *a = _mm512_permutex2var_pd(lo, slot, hi);
  *b = _mm512_permutex2var_pd(lo, _mm512_add_epi64(slot, _mm512_set1_epi64(4)), hi);  // (ix + 1, iy)
  *c = _mm512_permutex2var_pd(lo, _mm512_add_epi64(slot, _mm512_set1_epi64(1)), hi);  // (ix, iy + 1)
  *d = _mm512_permutex2var_pd(lo, _mm512_add_epi64(slot, _mm512_set1_epi64(5)), hi);  // (ix + 1, iy + 1)
  return true;
}

// ShadeFourAvx2 on eight points with AVX-512.
[[gnu::target("avx512f")]] bool ShadeEightAvx512(const Prepared& prep,
                                                 const Surface& s,
                                                 const TexturePlan* plan,
                                                 const double* x,
                                                 const double* y,
                                                 const double* footprint,
                                                 Vec3d* rgb,
                                                 float* luma) {
  const __m512d rx =
      _mm512_mul_pd(_mm512_sub_pd(_mm512_loadu_pd(x), _mm512_set1_pd(prep.cx)), _mm512_set1_pd(prep.inv_fx));
  const __m512d ry =
      _mm512_mul_pd(_mm512_sub_pd(_mm512_loadu_pd(y), _mm512_set1_pd(prep.cy)), _mm512_set1_pd(prep.inv_fy));
  const __m512d one = _mm512_set1_pd(1.0);
  const __m512d inv_w = _mm512_div_pd(
      one, _mm512_mul_pd(Lin8(s.normal.x(), rx, s.normal.y(), ry, s.normal.z()), _mm512_set1_pd(s.inv_d)));
  __m512d irradiance = _mm512_set1_pd(s.flat_irradiance);
  if (prep.has_gradient) {
    const IlluminationGradient& g = prep.gradient;
    const __m512d px = _mm512_mul_pd(rx, inv_w), py = _mm512_mul_pd(ry, inv_w);
    const __m512d dot = _mm512_add_pd(
        _mm512_add_pd(_mm512_mul_pd(_mm512_set1_pd(g.gradient.x()), _mm512_sub_pd(px, _mm512_set1_pd(g.origin.x()))),
                      _mm512_mul_pd(_mm512_set1_pd(g.gradient.y()), _mm512_sub_pd(py, _mm512_set1_pd(g.origin.y())))),
        _mm512_mul_pd(_mm512_set1_pd(g.gradient.z()), _mm512_sub_pd(inv_w, _mm512_set1_pd(g.origin.z()))));
    // std::max(min_factor, v) = (min_factor < v) ? v : min_factor.
    const __m512d v = _mm512_add_pd(one, dot), lo = _mm512_set1_pd(g.min_factor);
    irradiance = _mm512_mul_pd(irradiance, Max8(lo, v));
  }
  __m512d factor = one;  // the noise's albedo factor
  if (plan != nullptr) {
    const __m512d dw_dx =
        _mm512_mul_pd(_mm512_mul_pd(_mm512_set1_pd(s.normal.x() * prep.inv_fx * s.inv_d), inv_w), inv_w);
    const __m512d dw_dy =
        _mm512_mul_pd(_mm512_mul_pd(_mm512_set1_pd(s.normal.y() * prep.inv_fy * s.inv_d), inv_w), inv_w);
    const __m512d tu_r = Lin8(s.tex_u.x(), rx, s.tex_u.y(), ry, s.tex_u.z());
    const __m512d tv_r = Lin8(s.tex_v.x(), rx, s.tex_v.y(), ry, s.tex_v.z());
    const __m512d zx = _mm512_mul_pd(inv_w, _mm512_set1_pd(prep.inv_fx)),
                  zy = _mm512_mul_pd(inv_w, _mm512_set1_pd(prep.inv_fy));
    const __m512d foot = _mm512_loadu_pd(footprint);
    const __m512d fu = _mm512_mul_pd(
        foot, _mm512_add_pd(Extent8(s.tex_u.x(), zx, tu_r, dw_dx), Extent8(s.tex_u.y(), zy, tu_r, dw_dy)));
    const __m512d fv = _mm512_mul_pd(
        foot, _mm512_add_pd(Extent8(s.tex_v.x(), zx, tv_r, dw_dx), Extent8(s.tex_v.y(), zy, tv_r, dw_dy)));
    const __m512d u = _mm512_add_pd(_mm512_mul_pd(tu_r, inv_w), _mm512_set1_pd(s.tex_u0));
    const __m512d v = _mm512_add_pd(_mm512_mul_pd(tv_r, inv_w), _mm512_set1_pd(s.tex_v0));
    // std::max(fu, fv) = (fu < fv) ? fv : fu.
    const __m512d f4 = _mm512_mul_pd(_mm512_set1_pd(4.0), Max8(fu, fv));
    const double* lattice = Tables().lattice.data();
    const __m512d limit = _mm512_set1_pd(1073741824.0);  // 2^30: lattice indices fit in 32 bits
    const __m256i mask = _mm256_set1_epi32(255);
    __m512d sum = _mm512_setzero_pd();
    for (int o = 0; o < plan->octaves; ++o) {
      const std::size_t k = static_cast<std::size_t>(o);
      const __m512d inv_wl = _mm512_set1_pd(plan->inv_wavelength[k]);
      // clamp(2 - 4 f / wavelength, 0, 1); an octave faded out everywhere ends the sum, as in Shade
      // (a lane faded out earlier adds 0 x its noise, which leaves its sum unchanged).
      __m512d fade = _mm512_sub_pd(_mm512_set1_pd(2.0), _mm512_mul_pd(f4, inv_wl));
      fade = _mm512_mask_blend_pd(_mm512_cmp_pd_mask(fade, _mm512_setzero_pd(), _CMP_LT_OQ), fade, _mm512_setzero_pd());
      fade = _mm512_mask_blend_pd(_mm512_cmp_pd_mask(one, fade, _CMP_LT_OQ), fade, one);  // std::clamp(., 0, 1)
      if (_mm512_cmp_pd_mask(fade, _mm512_setzero_pd(), _CMP_GT_OQ) == 0) break;
      const __m512d nx = _mm512_mul_pd(u, inv_wl), ny = _mm512_mul_pd(v, inv_wl);
      if ((_mm512_cmp_pd_mask(Abs8(nx), limit, _CMP_NLT_UQ) | _mm512_cmp_pd_mask(Abs8(ny), limit, _CMP_NLT_UQ)) != 0) {
        return false;
      }
      const __m512d fx = Floor8(nx), fy = Floor8(ny);
      const __m256i ix =
          _mm256_add_epi32(_mm512_cvttpd_epi32(fx), _mm256_set1_epi32(static_cast<int>(plan->shift_x[k])));
      const __m256i iy =
          _mm256_add_epi32(_mm512_cvttpd_epi32(fy), _mm256_set1_epi32(static_cast<int>(plan->shift_y[k])));
      const __m256i i0 = _mm256_slli_epi32(_mm256_and_si256(ix, mask), 8);
      const __m256i i1 = _mm256_slli_epi32(_mm256_and_si256(_mm256_add_epi32(ix, _mm256_set1_epi32(1)), mask), 8);
      const __m256i j0 = _mm256_and_si256(iy, mask);
      const __m256i j1 = _mm256_and_si256(_mm256_add_epi32(iy, _mm256_set1_epi32(1)), mask);
      // The cells' four corners: from a patch of the lattice where the eight points lie close together
      // (nearly always), else by gathers, which were most of this kernel's time.
      __m512d a, b, c, d;
      if (!CornersFromPatch(lattice, ix, iy, &a, &b, &c, &d)) {
        a = Gather8(lattice, _mm256_add_epi32(i0, j0));
        b = Gather8(lattice, _mm256_add_epi32(i1, j0));
        c = Gather8(lattice, _mm256_add_epi32(i0, j1));
        d = Gather8(lattice, _mm256_add_epi32(i1, j1));
      }
      const __m512d tx = Quintic8(_mm512_sub_pd(nx, fx)), ty = Quintic8(_mm512_sub_pd(ny, fy));
      const __m512d ab = _mm512_add_pd(a, _mm512_mul_pd(_mm512_sub_pd(b, a), tx));
      const __m512d cd = _mm512_add_pd(c, _mm512_mul_pd(_mm512_sub_pd(d, c), tx));
      const __m512d noise = _mm512_add_pd(ab, _mm512_mul_pd(_mm512_sub_pd(cd, ab), ty));
      sum = _mm512_add_pd(sum, _mm512_mul_pd(_mm512_mul_pd(fade, _mm512_set1_pd(plan->amplitude[k])), noise));
    }
    // std::max(0.0, 1 + sum) = (0 < 1 + sum) ? 1 + sum : 0.
    const __m512d t = _mm512_add_pd(one, sum);
    factor = Max8(_mm512_setzero_pd(), t);
  }
  // irradiance x (albedo x factor) per channel, as Shade's irradiance * albedo (factor 1 leaves the
  // albedo as it is).
  const __m512d r = _mm512_mul_pd(irradiance, _mm512_mul_pd(_mm512_set1_pd(s.albedo.x()), factor));
  const __m512d g = _mm512_mul_pd(irradiance, _mm512_mul_pd(_mm512_set1_pd(s.albedo.y()), factor));
  const __m512d b = _mm512_mul_pd(irradiance, _mm512_mul_pd(_mm512_set1_pd(s.albedo.z()), factor));
  if (luma != nullptr) {
    // Luma() and the cast to float of the rasterizer's store.
    const __m512d l =
        _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(_mm512_set1_pd(0.299), r), _mm512_mul_pd(_mm512_set1_pd(0.587), g)),
                      _mm512_mul_pd(_mm512_set1_pd(0.114), b));
    _mm256_storeu_ps(luma, _mm512_cvtpd_ps(l));
    return true;
  }
  alignas(64) double rr[8], gg[8], bb[8];
  _mm512_store_pd(rr, r);
  _mm512_store_pd(gg, g);
  _mm512_store_pd(bb, b);
  for (std::size_t k = 0; k < 8; ++k) rgb[k] = Vec3d(rr[k], gg[k], bb[k]);
  return true;
}

#undef IDI_AVX512
#pragma GCC diagnostic pop
#undef IDI_AVX2

}  // namespace
#endif

namespace {

// ShadeBatch into rgb, or into luma (as float) when luma is not null.
void ShadeBatchTo(const Prepared& prep,
                  const Surface& s,
                  const double* x,
                  const double* y,
                  const double* footprint_px,
                  int n,
                  Vec3d* rgb,
                  float* luma) {
  auto one_by_one = [&](int from, int to) {
    for (int k = from; k < to; ++k) {
      const Vec3d v = Shade(prep, s, x[k], y[k], footprint_px[k]);
      if (luma != nullptr) {
        luma[k] = static_cast<float>(Luma(v));
      } else {
        rgb[k] = v;
      }
    }
  };
#if defined(__x86_64__)
  static const bool avx2 = __builtin_cpu_supports("avx2") != 0;
  static const bool avx512 = __builtin_cpu_supports("avx512f") != 0;
  const bool simple =
      !s.constant && !s.cylinder && prep.spotlights.empty() && (s.texture == nullptr || !(s.texture->tile_size > 0));
  if (avx2 && simple) {
    const TexturePlan* plan = nullptr;
    if (s.texture != nullptr) {
      const TexturePlan& p = prep.texture_plans[static_cast<std::size_t>(s.texture_plan)];
      if (p.octaves > 0 && s.texture->noise_amplitude > 0) plan = &p;
    }
    int k = 0;
    for (; avx512 && k + 8 <= n; k += 8) {
      if (!ShadeEightAvx512(prep,
                            s,
                            plan,
                            x + k,
                            y + k,
                            footprint_px + k,
                            rgb == nullptr ? nullptr : rgb + k,
                            luma == nullptr ? nullptr : luma + k)) {
        one_by_one(k, k + 8);
      }
    }
    for (; k + 4 <= n; k += 4) {
      if (!ShadeFourAvx2(prep,
                         s,
                         plan,
                         x + k,
                         y + k,
                         footprint_px + k,
                         rgb == nullptr ? nullptr : rgb + k,
                         luma == nullptr ? nullptr : luma + k)) {
        one_by_one(k, k + 4);
      }
    }
    one_by_one(k, n);
    return;
  }
#endif
  one_by_one(0, n);
}

}  // namespace

void ShadeBatch(const Prepared& prep,
                const Surface& s,
                const double* x,
                const double* y,
                const double* footprint_px,
                int n,
                Vec3d* out) {
  ShadeBatchTo(prep, s, x, y, footprint_px, n, out, nullptr);
}

void ShadeBatchLuma(const Prepared& prep,
                    const Surface& s,
                    const double* x,
                    const double* y,
                    const double* footprint_px,
                    int n,
                    float* out) {
  ShadeBatchTo(prep, s, x, y, footprint_px, n, nullptr, out);
}

double ShadingDetailPx(const Prepared& prep, const Surface& s, double x, double y, double footprint_px,
                       double radiance, double negligible) {
  if (s.texture == nullptr) return std::numeric_limits<double>::infinity();
  const double rx = (x - prep.cx) * prep.inv_fx, ry = (y - prep.cy) * prep.inv_fy;
  const TexturePoint tp = TextureAt(prep, s, rx, ry, DepthAlong(s, rx, ry), footprint_px);
  const TexturePlan& plan = prep.texture_plans[static_cast<std::size_t>(s.texture_plan)];
  // Texture units per pixel (an upper bound: fu and fv sum the absolute derivatives).
  const double f = std::max(tp.fu, tp.fv);
  const double per_px = std::max(f / std::max(footprint_px, 1e-12), 1e-300);
  double finest = std::numeric_limits<double>::infinity();
  if (plan.texture->tile_size > 0) finest = std::min(finest, plan.texture->grout_width / per_px);
  const double noise = std::abs(plan.texture->noise_amplitude);
  if (noise == 0) return finest;
  // The radiance without the noise factor is at most radiance / (1 - noise), and octave o adds at most
  // +-amplitude_o * fade_o of it: the finest octaves whose summed peak-to-peak stays below `negligible`
  // are left out.
  const double base = noise < 0.95 ? std::abs(radiance) / (1 - noise) : std::numeric_limits<double>::infinity();
  std::array<double, 12> fade{};
  int active = 0;
  for (; active < plan.octaves; ++active) {
    const std::size_t k = static_cast<std::size_t>(active);
    fade[k] = std::clamp(2.0 - 4.0 * f * plan.inv_wavelength[k], 0.0, 1.0);
    if (fade[k] <= 0) break;
  }
  double left_out = 0;
  for (int o = active - 1; o >= 0; --o) {
    const std::size_t k = static_cast<std::size_t>(o);
    left_out += 2 * base * std::abs(plan.amplitude[k]) * fade[k];
    if (left_out > negligible) return std::min(finest, 1 / (plan.inv_wavelength[k] * per_px));
  }
  return finest;
}

Vec3d SpotEmission(const Prepared& prep, const Surface& s, double x, double y) {
  const Vec3d ray = prep.Ray(x, y);
  const Vec3d p = ray * (s.d / s.normal.dot(ray));
  Vec3d out = Vec3d::Zero();
  for (const int k : s.spots) {
    const PreparedSpot& ls = prep.laser_spots[static_cast<std::size_t>(k)];
    if (ls.image_layer) continue;
    const double d2 = (p - ls.center).squaredNorm();
    if (d2 > ls.reach * ls.reach) continue;
    out += ls.peak * std::exp(-0.5 * d2 / (ls.sigma * ls.sigma)) * ls.color;
  }
  return out;
}

}  // namespace idi::sim::internal
