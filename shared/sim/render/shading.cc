// Lambertian shading with procedural textures filtered over the pixel footprint.
#include <algorithm>
#include <cmath>
#include <array>
#include <cstdint>
#include <limits>
#include <utility>

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
// The four corner values are looked up every time (two byte-table loads each, in L1): cheaper than
// remembering the last cell, whose hit-or-miss branch the octaves' varying cell sizes make
// unpredictable, and the octaves' work stays independent so that they overlap.
inline double ValueNoise(double x, double y, int64_t shift_x, int64_t shift_y, const NoiseTables& t) {
  const double fx = FastFloor(x), fy = FastFloor(y);
  const auto ix = static_cast<int64_t>(fx) + shift_x, iy = static_cast<int64_t>(fy) + shift_y;
  const double tx = Quintic(x - fx), ty = Quintic(y - fy);
  const uint8_t p0 = t.perm[static_cast<std::size_t>(ix & 255)];
  const uint8_t p1 = t.perm[static_cast<std::size_t>((ix + 1) & 255)];
  const double a = t.value[t.perm[static_cast<std::size_t>((p0 + iy) & 255)]];
  const double b = t.value[t.perm[static_cast<std::size_t>((p1 + iy) & 255)]];
  const double c = t.value[t.perm[static_cast<std::size_t>((p0 + iy + 1) & 255)]];
  const double d = t.value[t.perm[static_cast<std::size_t>((p1 + iy + 1) & 255)]];
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
// likewise for y), dotted with the texture axes. inv_w = z on the face's plane (w = 1/z). Per
// shaded point: reciprocals are multiplied, not divided by.
struct TexturePoint {
  double u, v, fu, fv;
};
[[gnu::always_inline]] inline TexturePoint TextureAt(const Prepared& prep, const Surface& s, const Vec3d& ray,
                                                   double inv_w, double footprint_px) {
  const double dw_dx = s.normal.x() * prep.inv_fx * s.inv_d * inv_w * inv_w;
  const double dw_dy = s.normal.y() * prep.inv_fy * s.inv_d * inv_w * inv_w;
  const double tu_r = s.tex_u.dot(ray), tv_r = s.tex_v.dot(ray);
  const double zx = inv_w * prep.inv_fx, zy = inv_w * prep.inv_fy;
  TexturePoint tp;
  tp.fu = footprint_px * (std::abs(s.tex_u.x() * zx - tu_r * dw_dx) + std::abs(s.tex_u.y() * zy - tu_r * dw_dy));
  tp.fv = footprint_px * (std::abs(s.tex_v.x() * zx - tv_r * dw_dx) + std::abs(s.tex_v.y() * zy - tv_r * dw_dy));
  tp.u = tu_r * inv_w + s.tex_u0;
  tp.v = tv_r * inv_w + s.tex_v0;
  return tp;
}

}  // namespace

Vec3d Shade(const Prepared& prep, const Surface& s, double x, double y, double footprint_px) {
  if (s.constant) return s.radiance;
  const Vec3d ray((x - prep.cx) * prep.inv_fx, (y - prep.cy) * prep.inv_fy, 1.0);
  const double inv_w = 1 / (s.normal.dot(ray) * s.inv_d);  // z on the face's plane
  const Vec3d p = ray * inv_w;
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
  if (prep.has_gradient) {
    irradiance *= std::max(prep.gradient.min_factor, 1 + prep.gradient.gradient.dot(p - prep.gradient.origin));
  }
  Vec3d albedo = s.albedo;
  if (s.texture != nullptr) {
    const TexturePoint tp = TextureAt(prep, s, ray, inv_w, footprint_px);
    albedo = TexturedAlbedo(prep.texture_plans[static_cast<std::size_t>(s.texture_plan)], albedo, tp.u, tp.v, tp.fu, tp.fv);
  }
  return irradiance * albedo;
}

double ShadingDetailPx(const Prepared& prep, const Surface& s, double x, double y, double footprint_px,
                       double radiance, double negligible) {
  if (s.texture == nullptr) return std::numeric_limits<double>::infinity();
  const Vec3d ray((x - prep.cx) * prep.inv_fx, (y - prep.cy) * prep.inv_fy, 1.0);
  const TexturePoint tp = TextureAt(prep, s, ray, 1 / (s.normal.dot(ray) * s.inv_d), footprint_px);
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
