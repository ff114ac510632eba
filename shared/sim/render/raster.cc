// Exact area integration of the prepared scene over every pixel's footprint.
//
// For each pixel the candidate pieces (from its tile) are classified against the pixel quad by their
// signed edge distances at its centre: outside, covering, or cut. A pixel covered by one piece that is
// in front of every other candidate everywhere in the quad takes that piece's shading (the common
// case, fast). Otherwise the visible part of each candidate is computed exactly: the quad clipped to the
// piece, minus every piece in front of it (only where in front: the depth order of two planes flips
// along a straight line in ideal coordinates). The pixel value is the area-weighted shading of the
// visible parts plus background for the rest.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <thread>
#include <vector>

#include "shared/sim/render/raster_internal.h"

namespace idi::sim::internal {
namespace {

constexpr int kMaxClipVerts = 40;
// Beyond this many visible fragments of one face in one pixel (never seen in practice) the pixel is
// integrated by 32 x 32 point samples instead.
constexpr std::size_t kMaxFragments = 256;

struct ClipPoly {
  int n = 0;
  std::array<Vec2d, kMaxClipVerts> v;

  ClipPoly() = default;
  ClipPoly(const ClipPoly& o) : n(o.n) { std::copy(o.v.begin(), o.v.begin() + n, v.begin()); }
  ClipPoly& operator=(const ClipPoly& o) {
    n = o.n;
    std::copy(o.v.begin(), o.v.begin() + n, v.begin());
    return *this;
  }
};

// Keeps the part where a x + b y + c >= 0. Returns false when nothing is left.
bool ClipHalfPlane(const ClipPoly& in, double a, double b, double c, ClipPoly* out) {
  out->n = 0;
  if (in.n == 0) return false;
  std::array<double, kMaxClipVerts> s;
  int inside = 0;
  for (int i = 0; i < in.n; ++i) {
    s[static_cast<std::size_t>(i)] = a * in.v[static_cast<std::size_t>(i)].x() + b * in.v[static_cast<std::size_t>(i)].y() + c;
    if (s[static_cast<std::size_t>(i)] >= 0) ++inside;
  }
  if (inside == in.n) {
    *out = in;
    return true;
  }
  if (inside == 0) return false;
  for (int i = 0; i < in.n; ++i) {
    const int j = (i + 1) % in.n;
    const double si = s[static_cast<std::size_t>(i)], sj = s[static_cast<std::size_t>(j)];
    const Vec2d& vi = in.v[static_cast<std::size_t>(i)];
    const Vec2d& vj = in.v[static_cast<std::size_t>(j)];
    if (si >= 0) {
      IDI_CHECK(out->n < kMaxClipVerts, "clip polygon overflow");
      out->v[static_cast<std::size_t>(out->n++)] = vi;
    }
    if ((si >= 0) != (sj >= 0)) {
      IDI_CHECK(out->n < kMaxClipVerts, "clip polygon overflow");
      const double t = si / (si - sj);
      out->v[static_cast<std::size_t>(out->n++)] = vi + t * (vj - vi);
    }
  }
  return out->n >= 3;
}

// Splits `in` by the line a x + b y + c = 0 into the part >= 0 (`pos`) and the part < 0 (`neg`), in one
// pass. Either may come out with fewer than 3 vertices (empty).
void SplitHalfPlane(const ClipPoly& in, const Vec3d& h, ClipPoly* pos, ClipPoly* neg) {
  pos->n = 0;
  neg->n = 0;
  std::array<double, kMaxClipVerts> s;
  int inside = 0;
  for (int i = 0; i < in.n; ++i) {
    const Vec2d& v = in.v[static_cast<std::size_t>(i)];
    s[static_cast<std::size_t>(i)] = h.x() * v.x() + h.y() * v.y() + h.z();
    if (s[static_cast<std::size_t>(i)] >= 0) ++inside;
  }
  if (inside == in.n) {
    *pos = in;
    return;
  }
  if (inside == 0) {
    *neg = in;
    return;
  }
  for (int i = 0; i < in.n; ++i) {
    const int j = i + 1 == in.n ? 0 : i + 1;
    const double si = s[static_cast<std::size_t>(i)], sj = s[static_cast<std::size_t>(j)];
    const Vec2d& vi = in.v[static_cast<std::size_t>(i)];
    IDI_CHECK(pos->n + 1 < kMaxClipVerts && neg->n + 1 < kMaxClipVerts, "clip polygon overflow");
    if (si >= 0) {
      pos->v[static_cast<std::size_t>(pos->n++)] = vi;
    } else {
      neg->v[static_cast<std::size_t>(neg->n++)] = vi;
    }
    if ((si >= 0) != (sj >= 0)) {
      const Vec2d x = vi + (si / (si - sj)) * (in.v[static_cast<std::size_t>(j)] - vi);
      pos->v[static_cast<std::size_t>(pos->n++)] = x;
      neg->v[static_cast<std::size_t>(neg->n++)] = x;
    }
  }
}

double AreaAndCentroid(const ClipPoly& p, Vec2d* centroid) {
  double a2 = 0, cx = 0, cy = 0;
  const Vec2d o = p.v[0];
  for (int i = 1; i + 1 < p.n; ++i) {
    const Vec2d u = p.v[static_cast<std::size_t>(i)] - o, w = p.v[static_cast<std::size_t>(i + 1)] - o;
    const double cr = u.x() * w.y() - u.y() * w.x();
    a2 += cr;
    cx += cr * (u.x() + w.x());
    cy += cr * (u.y() + w.y());
  }
  if (std::abs(a2) < 1e-300) {
    *centroid = o;
    return 0;
  }
  *centroid = o + Vec2d(cx, cy) / (3 * a2);
  return std::abs(a2) / 2;
}

// Gauss-Legendre nodes and weights on [0, 1] for m points (Newton on the Legendre polynomial).
struct GaussLegendre {
  std::vector<double> x, w;
  explicit GaussLegendre(int m) {
    for (int i = 1; i <= m; ++i) {
      double z = std::cos(M_PI * (i - 0.25) / (m + 0.5));
      double dp = 1;
      for (int it = 0; it < 100; ++it) {
        double p0 = 1, p1 = z;
        for (int k = 2; k <= m; ++k) {
          const double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k;
          p0 = p1;
          p1 = p2;
        }
        const double pm = m == 1 ? z : p1;
        const double pm1 = m == 1 ? 1 : p0;
        dp = m * (z * pm - pm1) / (z * z - 1);
        const double step = pm / dp;
        z -= step;
        if (std::abs(step) < 1e-16) break;
      }
      x.push_back(0.5 * (1 - z));
      w.push_back(1.0 / ((1 - z * z) * dp * dp));  // 2 / ((1 - z^2) P'^2), halved for [0, 1]
    }
  }
};

const GaussLegendre& GaussLegendreRule(int m) {
  static const std::vector<GaussLegendre> rules = [] {
    std::vector<GaussLegendre> r;
    for (int k = 0; k <= 32; ++k) r.emplace_back(std::max(k, 1));
    return r;
  }();
  return rules[static_cast<std::size_t>(std::clamp(m, 1, 32))];
}

}  // namespace

double GaussLegendreNode(int m, int i) { return GaussLegendreRule(m).x[static_cast<std::size_t>(i)]; }
double GaussLegendreWeight(int m, int i) { return GaussLegendreRule(m).w[static_cast<std::size_t>(i)]; }

namespace {

// A candidate piece active in the current pixel (or tile), with the edges that cut it.
struct Active {
  int piece = -1;
  int group = -1;
  bool interior = false;    // every cutting edge is a seam (or none cuts)
  bool has_centre = false;  // the centre lies inside the piece
  int n_cut = 0;
  std::array<int, kMaxPieceVerts> cut;
};

class PixelIntegrator {
 public:
  // spots_only: integrate the laser spot layer instead of the surfaces' shading.
  PixelIntegrator(const Prepared& prep, bool spots_only) : prep_(prep), spots_only_(spots_only) {
    background_ = spots_only ? Vec3d::Zero() : prep.background;
    rest_.reserve(64);
    next_.reserve(64);
  }

  // Classifies the candidates against a region given by its centre and the largest distance from
  // the centre to any point of it. Returns the index (in active_) of the front-most piece that
  // contains the centre and whose group covers the whole region, provided that group is in front of
  // every other active piece at all `corners`; -1 when the region needs exact integration.
  int Classify(const Vec2d& c, double radius, const int* cand, int n_cand, const Vec2d* corners, int n_corners) {
    active_.clear();
    for (int k = 0; k < n_cand; ++k) {
      const Piece& p = prep_.pieces[static_cast<std::size_t>(cand[k])];
      Active a;
      a.piece = cand[k];
      a.group = p.group;
      bool outside = false;
      double min_s = 1e300;
      bool boundary_cut = false;
      for (int i = 0; i < p.n; ++i) {
        const Vec3d& h = p.e[static_cast<std::size_t>(i)];
        const double s = h.x() * c.x() + h.y() * c.y() + h.z();
        if (s <= -radius) {
          outside = true;
          break;
        }
        min_s = std::min(min_s, s);
        if (s < radius) {
          a.cut[static_cast<std::size_t>(a.n_cut++)] = i;
          if ((p.seam_mask & (1u << i)) == 0) boundary_cut = true;
        }
      }
      if (outside) continue;
      a.interior = !boundary_cut;
      a.has_centre = min_s >= 0;
      active_.push_back(a);
    }
    int front = -1;
    for (std::size_t k = 0; k < active_.size(); ++k) {
      const Active& a = active_[k];
      if (!a.interior || !a.has_centre) continue;
      if (front < 0 || FrontOrder(prep_.pieces[static_cast<std::size_t>(a.piece)],
                                  prep_.pieces[static_cast<std::size_t>(active_[static_cast<std::size_t>(front)].piece)],
                                  &c, 1) > 0) {
        front = static_cast<int>(k);
      }
    }
    if (front < 0) return -1;
    const int g = active_[static_cast<std::size_t>(front)].group;
    for (std::size_t k = 0; k < active_.size(); ++k) {
      const Active& a = active_[k];
      if (a.group == g) {
        if (!a.interior) return -1;  // the group's outline crosses the region
        continue;
      }
      const Piece& pa = prep_.pieces[static_cast<std::size_t>(a.piece)];
      for (const Active& m : active_) {
        if (m.group != g) continue;
        if (FrontOrder(prep_.pieces[static_cast<std::size_t>(m.piece)], pa, corners, n_corners) <= 0) return -1;
      }
    }
    return front;
  }

  // The piece of active_[front]'s group that contains point p (the covering group's member).
  int MemberAt(int front, const Vec2d& p) {
    const Active& f = active_[static_cast<std::size_t>(front)];
    if (last_member_ >= 0 && prep_.pieces[static_cast<std::size_t>(last_member_)].group == f.group &&
        prep_.pieces[static_cast<std::size_t>(last_member_)].Inside(p) >= 0) {
      return last_member_;
    }
    if (prep_.pieces[static_cast<std::size_t>(f.piece)].Inside(p) >= 0) return last_member_ = f.piece;
    int best = f.piece;
    double best_s = -1e300;
    for (const Active& a : active_) {
      if (a.group != f.group) continue;
      const double s = prep_.pieces[static_cast<std::size_t>(a.piece)].Inside(p);
      if (s >= 0) return last_member_ = a.piece;
      if (s > best_s) {
        best_s = s;
        best = a.piece;
      }
    }
    return best;
  }

  const Piece& FrontPiece(int front) const {
    return prep_.pieces[static_cast<std::size_t>(active_[static_cast<std::size_t>(front)].piece)];
  }

  // Do all active members of front's group belong to `surface` (a face cut into convex pieces)?
  bool GroupShares(int front, int surface) const {
    for (const Active& a : active_) {
      if (a.group == active_[static_cast<std::size_t>(front)].group &&
          prep_.pieces[static_cast<std::size_t>(a.piece)].surface != surface) {
        return false;
      }
    }
    return true;
  }

  bool GroupOfOne(int front) const {
    for (std::size_t k = 0; k < active_.size(); ++k) {
      if (static_cast<int>(k) != front && active_[k].group == active_[static_cast<std::size_t>(front)].group) return false;
    }
    return true;
  }

  // Radiance over the pixel quad q (ideal coordinates).
  Vec3d Pixel(const Vec2d* q, const int* cand, int n_cand, double radius, int samples) {
    const Vec2d c = (q[0] + q[1] + q[2] + q[3]) / 4;
    const int front = Classify(c, radius, cand, n_cand, q, 4);
    if (active_.empty()) return background_;
    if (front >= 0 && (samples <= 1 || GroupOfOne(front))) {
      const Piece& f = prep_.pieces[static_cast<std::size_t>(active_[static_cast<std::size_t>(front)].piece)];
      return ShadeArea(prep_.surfaces[static_cast<std::size_t>(f.surface)], q, samples);
    }
    if (samples <= 1) return Exact(q);
    // Near a laser spot: exact visibility on each of n x n sub-quads.
    Vec3d sum = Vec3d::Zero();
    double area_sum = 0;
    for (int j = 0; j < samples; ++j) {
      for (int i = 0; i < samples; ++i) {
        Vec2d sq[4];
        const double u[2] = {static_cast<double>(i) / samples, static_cast<double>(i + 1) / samples};
        const double v[2] = {static_cast<double>(j) / samples, static_cast<double>(j + 1) / samples};
        sq[0] = Bilinear(q, u[0], v[0]);
        sq[1] = Bilinear(q, u[1], v[0]);
        sq[2] = Bilinear(q, u[1], v[1]);
        sq[3] = Bilinear(q, u[0], v[1]);
        const double a = QuadArea(sq);
        sum += a * Exact(sq);
        area_sum += a;
      }
    }
    return area_sum > 0 ? Vec3d(sum / area_sum) : background_;
  }

  // Pixel(q, cand, n_cand, radius, 1) into *value (true), except for a pixel covered by one group in
  // front of the rest: false, with the surface and the point and footprint that Pixel would shade it at,
  // so that the caller can shade such pixels in batches (ShadeBatch gives Shade's values to the bit).
  bool PixelOrCovered(const Vec2d* q,
                      const int* cand,
                      int n_cand,
                      double radius,
                      Vec3d* value,
                      int* surface,
                      Vec2d* c,
                      double* footprint) {
    IDI_CHECK(!spots_only_, "PixelOrCovered shades surfaces, not the spot layer");
    *c = (q[0] + q[1] + q[2] + q[3]) / 4;
    const int front = Classify(*c, radius, cand, n_cand, q, 4);
    if (active_.empty()) {
      *value = background_;
      return true;
    }
    if (front >= 0) {
      *surface = prep_.pieces[static_cast<std::size_t>(active_[static_cast<std::size_t>(front)].piece)].surface;
      *footprint = std::sqrt(QuadArea(q));  // ShadeArea's, with one sample
      return false;
    }
    *value = Exact(q);
    return true;
  }

  // Centre shading of a pixel inside a tile that Classify found covered by one group.
  Vec3d TilePixel(int front, bool group_of_one, const Vec2d& c, double footprint) {
    const int member = group_of_one ? active_[static_cast<std::size_t>(front)].piece : MemberAt(front, c);
    const Piece& p = prep_.pieces[static_cast<std::size_t>(member)];
    return Radiance(prep_.surfaces[static_cast<std::size_t>(p.surface)], c.x(), c.y(), footprint);
  }

 private:
  static Vec2d Bilinear(const Vec2d* q, double u, double v) {
    return (1 - v) * ((1 - u) * q[0] + u * q[1]) + v * ((1 - u) * q[3] + u * q[2]);
  }
  static double QuadArea(const Vec2d* q) {
    const Vec2d d1 = q[2] - q[0], d2 = q[3] - q[1];
    return std::abs(d1.x() * d2.y() - d1.y() * d2.x()) / 2;
  }

  // Shading of one surface over the whole quad: centre value, or n x n quadrature near a spot.
  Vec3d ShadeArea(const Surface& s, const Vec2d* q, int samples) {
    if (samples <= 1) {
      const Vec2d c = (q[0] + q[1] + q[2] + q[3]) / 4;
      return Radiance(s, c.x(), c.y(), std::sqrt(QuadArea(q)));
    }
    // Gauss-Legendre product rule over the bilinear quad, weighted by the map's Jacobian: accurate
    // to ~1e-9 for a spot a third of a pixel wide, so its centroid is not biased by the sampling.
    const GaussLegendre& gl = GaussLegendreRule(samples);
    Vec3d sum = Vec3d::Zero();
    double wsum = 0;
    const double foot = std::sqrt(QuadArea(q)) / samples;
    for (std::size_t j = 0; j < gl.x.size(); ++j) {
      for (std::size_t i = 0; i < gl.x.size(); ++i) {
        const double u = gl.x[i], v = gl.x[j];
        const Vec2d du = (1 - v) * (q[1] - q[0]) + v * (q[2] - q[3]);
        const Vec2d dv = (1 - u) * (q[3] - q[0]) + u * (q[2] - q[1]);
        const double w = gl.w[i] * gl.w[j] * std::abs(du.x() * dv.y() - du.y() * dv.x());
        const Vec2d p = Bilinear(q, u, v);
        sum += w * Radiance(s, p.x(), p.y(), foot);
        wsum += w;
      }
    }
    return sum / wsum;
  }

  // Point-sampled integration (32 x 32) of a quad: the fallback for pathological overlaps.
  Vec3d SampledFallback(const Vec2d* q) {
    constexpr int kN = 32;
    Vec3d sum = Vec3d::Zero();
    for (int j = 0; j < kN; ++j) {
      for (int i = 0; i < kN; ++i) {
        const Vec2d p = Bilinear(q, (i + 0.5) / kN, (j + 0.5) / kN);
        int front = -1;
        for (const Active& a : active_) {
          const Piece& pc = prep_.pieces[static_cast<std::size_t>(a.piece)];
          if (pc.Inside(p) < 0) continue;
          if (front < 0 || FrontOrder(pc, prep_.pieces[static_cast<std::size_t>(front)], &p, 1) > 0) front = a.piece;
        }
        if (front < 0) {
          sum += background_;
        } else {
          const Piece& pc = prep_.pieces[static_cast<std::size_t>(front)];
          sum += Radiance(prep_.surfaces[static_cast<std::size_t>(pc.surface)], p.x(), p.y(), 1.0 / kN);
        }
      }
    }
    return sum / (kN * kN);
  }

  // Exact visible-area integration over a quad.
  Vec3d Exact(const Vec2d* q) {
    ClipPoly quad;
    quad.n = 4;
    for (int i = 0; i < 4; ++i) quad.v[static_cast<std::size_t>(i)] = q[i];
    Vec2d quad_centroid;
    const double area = AreaAndCentroid(quad, &quad_centroid);
    if (!(area > 0)) return background_;
    const double foot = std::sqrt(area);
    // Depth order of every pair over the quad, once.
    const std::size_t na = active_.size();
    order_.assign(na * na, 0);
    for (std::size_t i = 0; i < na; ++i) {
      for (std::size_t j = i + 1; j < na; ++j) {
        const int o = FrontOrder(prep_.pieces[static_cast<std::size_t>(active_[i].piece)],
                                 prep_.pieces[static_cast<std::size_t>(active_[j].piece)], q, 4);
        order_[i * na + j] = o;
        order_[j * na + i] = -o;
      }
    }
    // A piece that covers the whole quad behind every other one takes what the others leave: its
    // area and centroid follow from theirs, no clipping needed (the common silhouette-over-background
    // pixel).
    int back = -1;
    for (std::size_t i = 0; i < na && back < 0; ++i) {
      if (active_[i].n_cut != 0) continue;
      bool behind_all = true;
      for (std::size_t j = 0; j < na && behind_all; ++j) behind_all = j == i || order_[j * na + i] > 0;
      if (behind_all) back = static_cast<int>(i);
    }
    Vec3d sum = Vec3d::Zero();
    double covered = 0;
    Vec2d moment = Vec2d::Zero();
    ClipPoly tmp;
    for (std::size_t ia = 0; ia < na; ++ia) {
      if (static_cast<int>(ia) == back) continue;
      const Active& aa = active_[ia];
      const Piece& a = prep_.pieces[static_cast<std::size_t>(aa.piece)];
      // Quad clipped to piece a (only the edges that cut the quad matter).
      rest_.clear();
      rest_.push_back(quad);
      bool empty = false;
      for (int k = 0; k < aa.n_cut && !empty; ++k) {
        const Vec3d& h = a.e[static_cast<std::size_t>(aa.cut[static_cast<std::size_t>(k)])];
        empty = !ClipHalfPlane(rest_[0], h.x(), h.y(), h.z(), &tmp);
        if (!empty) std::swap(rest_[0], tmp);
      }
      if (empty) continue;
      for (std::size_t ib = 0; ib < na && !rest_.empty(); ++ib) {
        if (ib == ia) continue;
        const int order = order_[ib * na + ia];
        if (order < 0) continue;
        // Subtract b (where it is in front of a) from every remaining polygon.
        const Active& bb = active_[ib];
        const Piece& b = prep_.pieces[static_cast<std::size_t>(bb.piece)];
        half_.clear();
        for (int k = 0; k < bb.n_cut; ++k) half_.push_back(b.e[static_cast<std::size_t>(bb.cut[static_cast<std::size_t>(k)])]);
        if (order == 0) half_.push_back(b.w - a.w);
        Subtract(1e-13 * area);
        if (rest_.size() > kMaxFragments) return SampledFallback(q);
      }
      for (const ClipPoly& p : rest_) {
        Vec2d centroid;
        const double pa = AreaAndCentroid(p, &centroid);
        if (pa <= 0) continue;
        sum += pa * Radiance(prep_.surfaces[static_cast<std::size_t>(a.surface)], centroid.x(), centroid.y(), foot);
        covered += pa;
        moment += pa * centroid;
      }
    }
    const double rest_area = area - covered;
    if (rest_area > 1e-12 * area) {
      if (back >= 0) {
        const Vec2d c = (area * quad_centroid - moment) / rest_area;
        const Piece& b = prep_.pieces[static_cast<std::size_t>(active_[static_cast<std::size_t>(back)].piece)];
        sum += rest_area * Radiance(prep_.surfaces[static_cast<std::size_t>(b.surface)], c.x(), c.y(), foot);
      } else {
        sum += rest_area * background_;
      }
    }
    return sum / area;
  }

  // rest_ := rest_ minus the convex region given by half_ (an intersection of half-planes). Polygons
  // that do not meet the region stay whole, and only half-planes that cut a polygon split it, so the
  // number of fragments grows only with real overlaps. Fragments below min_area are dropped.
  void Subtract(double min_area) {
    next_.clear();
    ClipPoly buf[2], outside;
    Vec2d unused;
    for (const ClipPoly& p0 : rest_) {
      const std::size_t mark = next_.size();
      const ClipPoly* cur = &p0;
      int which = 0;
      bool meets = true;
      for (const Vec3d& h : half_) {
        ClipPoly* pos = &buf[which];
        SplitHalfPlane(*cur, h, pos, &outside);
        if (outside.n >= 3 && AreaAndCentroid(outside, &unused) > min_area) next_.push_back(outside);
        if (pos->n < 3) {
          meets = false;
          break;
        }
        cur = pos;
        which ^= 1;
      }
      // The part inside every half-plane is covered by b and dropped; when b does not really meet
      // p0, keep p0 whole instead of its fragments.
      if (!meets || AreaAndCentroid(*cur, &unused) <= min_area) {
        next_.resize(mark);
        next_.push_back(p0);
      }
    }
    rest_.swap(next_);
  }

  Vec3d Radiance(const Surface& s, double x, double y, double footprint_px) const {
    return spots_only_ ? SpotEmission(prep_, s, x, y) : Shade(prep_, s, x, y, footprint_px);
  }

  const Prepared& prep_;
  bool spots_only_;
  Vec3d background_;
  int last_member_ = -1;
  std::vector<Active> active_;
  std::vector<ClipPoly> rest_, next_;
  std::vector<int> order_;
  std::vector<Vec3d> half_;
};

}  // namespace

namespace {

// Shading of a tile covered by one smooth surface (Surface::smooth), interpolated bilinearly in pixel
// index space between exactly shaded nodes, when that is within prep.shading_tolerance:
//  - nodes on a 5 x 5 lattice (spacing 2 pixels in a full tile), shaded exactly;
//  - its error estimated as half the largest difference, at the 16 nodes off the coarser 3 x 3
//    lattice, between the exact value and the 3 x 3 lattice's interpolation (bilinear error shrinks
//    with the square of the spacing, so half is still a safe margin);
//  - only where the shading's finest detail that matters (texture octave wavelength) spans at least
//    two node spacings, so that no feature can hide between the nodes.
// Returns false (the caller shades every pixel) otherwise. `out` holds w x h values, row-major.
class TileInterpolator {
 public:
  static constexpr double kErrorFactor = 0.5;

  TileInterpolator(const Prepared& prep, bool color) : prep_(prep), color_(color) {}

  bool Shade(const Surface& s, int i0, int j0, int w, int h, Vec3d* out) {
    const PixelGrid& g = *prep_.grid;
    if (!s.smooth || !(prep_.shading_tolerance > 0) || w < 5 || h < 5) return false;
    const double tol = prep_.shading_tolerance;
    xs_ = {0, w / 4, w / 2, w / 2 + (w - 1 - w / 2) / 2, w - 1};
    ys_ = {0, h / 4, h / 2, h / 2 + (h - 1 - h / 2) / 2, h - 1};
    int spacing = 0;
    for (std::size_t k = 0; k + 1 < 5; ++k) spacing = std::max({spacing, xs_[k + 1] - xs_[k], ys_[k + 1] - ys_[k]});
    // Every node's centre and footprint, the four corners first: they decide whether the texture's
    // detail allows interpolation at all, before the other 21 are shaded.
    std::array<int, 25> order;
    std::array<double, 25> nx, ny, nf;
    std::array<Vec3d, 25> value;
    int n = 0;
    for (const int b : {0, 4}) {
      for (const int a : {0, 4}) order[static_cast<std::size_t>(n++)] = b * 5 + a;
    }
    for (int k = 0; k < 25; ++k) {
      if (k != 0 && k != 4 && k != 20 && k != 24) order[static_cast<std::size_t>(n++)] = k;
    }
    for (std::size_t k = 0; k < 25; ++k) {
      const int a = order[k] % 5, b = order[k] / 5;
      const int i = i0 + xs_[static_cast<std::size_t>(a)], j = j0 + ys_[static_cast<std::size_t>(b)];
      const Vec2d c = g.Center(i, j);
      nx[k] = c.x();
      ny[k] = c.y();
      nf[k] = g.Footprint(i, j);
    }
    ShadeBatch(prep_, s, nx.data(), ny.data(), nf.data(), 4, value.data());
    // Texture detail finer than the nodes resolve must be negligible (a quarter of the tolerance).
    for (std::size_t k = 0; k < 4; ++k) {
      const Vec3d& v = value[k];
      const double detail = ShadingDetailPx(
          prep_, s, nx[k], ny[k], nf[k], color_ ? v.cwiseAbs().maxCoeff() : std::abs(Luma(v)), 0.25 * tol);
      if (!(detail >= 2 * spacing)) return false;
    }
    ShadeBatch(prep_, s, nx.data() + 4, ny.data() + 4, nf.data() + 4, 21, value.data() + 4);
    for (std::size_t k = 0; k < 25; ++k) node_[static_cast<std::size_t>(order[k])] = value[k];
    double err = 0;
    for (int b = 0; b < 5; ++b) {
      for (int a = 0; a < 5; ++a) {
        if (a % 2 == 0 && b % 2 == 0) continue;
        // The 3 x 3 lattice's interpolation here.
        const int a0 = std::min(a / 2 * 2, 2), b0 = std::min(b / 2 * 2, 2);
        const double tx = Fraction(xs_, a0, a), ty = Fraction(ys_, b0, b);
        const Vec3d interp = (1 - ty) * ((1 - tx) * At(a0, b0) + tx * At(a0 + 2, b0)) +
                             ty * ((1 - tx) * At(a0, b0 + 2) + tx * At(a0 + 2, b0 + 2));
        err = std::max(err, Diff(interp, At(a, b)));
      }
    }
    if (kErrorFactor * err > tol) return false;
    // Bilinear interpolation of the 5 x 5 lattice over the tile.
    for (int y = 0, b = 0; y < h; ++y) {
      while (b < 3 && y > ys_[static_cast<std::size_t>(b + 1)]) ++b;
      const double ty = static_cast<double>(y - ys_[static_cast<std::size_t>(b)]) /
                        (ys_[static_cast<std::size_t>(b + 1)] - ys_[static_cast<std::size_t>(b)]);
      for (int x = 0, a = 0; x < w; ++x) {
        while (a < 3 && x > xs_[static_cast<std::size_t>(a + 1)]) ++a;
        const double tx = static_cast<double>(x - xs_[static_cast<std::size_t>(a)]) /
                          (xs_[static_cast<std::size_t>(a + 1)] - xs_[static_cast<std::size_t>(a)]);
        out[y * w + x] = (1 - ty) * ((1 - tx) * At(a, b) + tx * At(a + 1, b)) + ty * ((1 - tx) * At(a, b + 1) + tx * At(a + 1, b + 1));
      }
    }
    return true;
  }

 private:
  Vec3d& At(int a, int b) { return node_[static_cast<std::size_t>(b * 5 + a)]; }

  // Position of lattice place k between places k0 and k0 + 2, in [0, 1].
  static double Fraction(const std::array<int, 5>& xs, int k0, int k) {
    return static_cast<double>(xs[static_cast<std::size_t>(k)] - xs[static_cast<std::size_t>(k0)]) /
           (xs[static_cast<std::size_t>(k0 + 2)] - xs[static_cast<std::size_t>(k0)]);
  }

  double Diff(const Vec3d& a, const Vec3d& b) const {
    return color_ ? (a - b).cwiseAbs().maxCoeff() : std::abs(Luma(a - b));
  }

  const Prepared& prep_;
  bool color_;
  std::array<int, 5> xs_{}, ys_{};
  std::array<Vec3d, 25> node_;
};

// The tile's candidates and its ideal bounding box as a region for PixelIntegrator::Classify.
struct TileRegion {
  const int* cand;
  int n_cand;
  Vec2d corners[4];
  Vec2d centre;
  double half_diag;
  TileRegion(const Prepared& prep, std::size_t t) {
    cand = prep.tile_items.data() + prep.tile_start[t];
    n_cand = prep.tile_start[t + 1] - prep.tile_start[t];
    const auto& box = prep.tile_box[t];
    corners[0] = {box[0], box[1]};
    corners[1] = {box[2], box[1]};
    corners[2] = {box[2], box[3]};
    corners[3] = {box[0], box[3]};
    centre = Vec2d((box[0] + box[2]) / 2, (box[1] + box[3]) / 2);
    half_diag = 0.5 * std::hypot(box[2] - box[0], box[3] - box[1]) * (1 + 1e-9);
  }
};

// Tile rows first, first + stride, ...: for each tile, 1 + the group that covers it in front of
// everything else (no edge inside it), or 0.
void ClassifyTileRows(const Prepared& prep, int first, int stride, std::vector<int>* covered) {
  PixelIntegrator integrator(prep, false);
  for (int ty = first; ty < prep.tiles_y; ty += stride) {
    for (int tx = 0; tx < prep.tiles_x; ++tx) {
      const std::size_t t = static_cast<std::size_t>(ty * prep.tiles_x + tx);
      const TileRegion r(prep, t);
      const int front = r.n_cand > 0 ? integrator.Classify(r.centre, r.half_diag, r.cand, r.n_cand, r.corners, 4) : -1;
      (*covered)[t] = front >= 0 ? 1 + integrator.FrontPiece(front).group : 0;
    }
  }
}

// Interpolated shading only in a tile whose 8 neighbours are covered by the same group: within a tile
// of any edge the image is the per-pixel one (PSF included), so edges are exactly where per-pixel
// shading puts them.
bool NeighboursCovered(const Prepared& prep, const std::vector<int>& covered, int tx, int ty) {
  const int own = covered[static_cast<std::size_t>(ty * prep.tiles_x + tx)];
  if (own == 0) return false;
  for (int y = std::max(0, ty - 1); y <= std::min(prep.tiles_y - 1, ty + 1); ++y) {
    for (int x = std::max(0, tx - 1); x <= std::min(prep.tiles_x - 1, tx + 1); ++x) {
      if (covered[static_cast<std::size_t>(y * prep.tiles_x + x)] != own) return false;
    }
  }
  return true;
}

void RasterizeTileRows(const Prepared& prep, bool color, int first, int stride, const std::vector<int>& covered,
                       cv::Mat& out) {
  const PixelGrid& g = *prep.grid;
  PixelIntegrator integrator(prep, false);
  TileInterpolator interpolator(prep, color);
  std::array<Vec3d, kTileSize * kTileSize> tile_values;
  // The pixels of an edge tile that one surface covers, waiting to be shaded in batches.
  struct CoveredPixel {
    int i = 0, j = 0, surface = -1;
    double x = 0, y = 0, footprint = 0;
  };
  std::array<CoveredPixel, kTileSize * kTileSize> covered_px;
  std::array<double, kTileSize * kTileSize> batch_x, batch_y, batch_f;
  std::array<int, kTileSize * kTileSize> batch_at;
  std::array<float, kTileSize * kTileSize> batch_luma;
  auto store = [&](int i, int j, const Vec3d& rgb) {
    if (color) {
      out.at<cv::Vec3f>(j, i) =
          cv::Vec3f(static_cast<float>(rgb.x()), static_cast<float>(rgb.y()), static_cast<float>(rgb.z()));
    } else {
      out.at<float>(j, i) = static_cast<float>(Luma(rgb));
    }
  };
  for (int ty = first; ty < prep.tiles_y; ty += stride) {
    for (int tx = 0; tx < prep.tiles_x; ++tx) {
      const std::size_t t = static_cast<std::size_t>(ty * prep.tiles_x + tx);
      const int* cand = prep.tile_items.data() + prep.tile_start[t];
      const int n_cand = prep.tile_start[t + 1] - prep.tile_start[t];
      const double radius = prep.tile_radius[t];
      const int i0 = tx * kTileSize, j0 = ty * kTileSize;
      const int i1 = std::min(i0 + kTileSize, g.cols), j1 = std::min(j0 + kTileSize, g.rows);
      if (n_cand == 0) {
        for (int j = j0; j < j1; ++j) {
          for (int i = i0; i < i1; ++i) store(i, j, prep.background);
        }
        continue;
      }
      // Whole tile covered by one group in front of everything else: centre shading, no per-pixel tests.
      const TileRegion region(prep, t);
      const int front = integrator.Classify(region.centre, region.half_diag, cand, n_cand, region.corners, 4);
      if (front >= 0) {
        const bool one = integrator.GroupOfOne(front);
        const Surface& fs = prep.surfaces[static_cast<std::size_t>(integrator.FrontPiece(front).surface)];
        const bool shares = integrator.GroupShares(front, integrator.FrontPiece(front).surface);
        const bool uniform = fs.constant && shares;
        if (!uniform && shares && NeighboursCovered(prep, covered, tx, ty) && interpolator.Shade(fs, i0, j0, i1 - i0, j1 - j0, tile_values.data())) {
          for (int j = j0; j < j1; ++j) {
            for (int i = i0; i < i1; ++i) store(i, j, tile_values[static_cast<std::size_t>((j - j0) * (i1 - i0) + (i - i0))]);
          }
          continue;
        }
        if (shares && !uniform) {
          // Every pixel on the one surface fs: shaded a row at a time.
          std::array<double, kTileSize> xs, ys, fp;
          for (int j = j0; j < j1; ++j) {
            for (int i = i0; i < i1; ++i) {
              const Vec2d c = g.Center(i, j);
              xs[static_cast<std::size_t>(i - i0)] = c.x();
              ys[static_cast<std::size_t>(i - i0)] = c.y();
              fp[static_cast<std::size_t>(i - i0)] = g.Footprint(i, j);
            }
            if (color) {
              ShadeBatch(prep, fs, xs.data(), ys.data(), fp.data(), i1 - i0, tile_values.data());
              for (int i = i0; i < i1; ++i) store(i, j, tile_values[static_cast<std::size_t>(i - i0)]);
            } else {
              ShadeBatchLuma(prep, fs, xs.data(), ys.data(), fp.data(), i1 - i0, out.ptr<float>(j) + i0);
            }
          }
          continue;
        }
        for (int j = j0; j < j1; ++j) {
          for (int i = i0; i < i1; ++i) {
            if (uniform) {
              store(i, j, fs.radiance);
            } else {
              store(i, j, integrator.TilePixel(front, one, g.Center(i, j), g.Footprint(i, j)));
            }
          }
        }
        continue;
      }
      // An edge crosses the tile: each pixel integrated exactly where it must be; the pixels that one
      // surface covers (most of them) are shaded afterwards, a surface's pixels in one batch.
      int n_covered = 0;
      for (int j = j0; j < j1; ++j) {
        for (int i = i0; i < i1; ++i) {
          const Vec2d q[4] = {g.Corner(i, j), g.Corner(i + 1, j), g.Corner(i + 1, j + 1), g.Corner(i, j + 1)};
          Vec3d value;
          Vec2d c;
          CoveredPixel& cp = covered_px[static_cast<std::size_t>(n_covered)];
          if (integrator.PixelOrCovered(q, cand, n_cand, radius, &value, &cp.surface, &c, &cp.footprint)) {
            store(i, j, value);
          } else {
            cp.x = c.x();
            cp.y = c.y();
            cp.i = i;
            cp.j = j;
            ++n_covered;
          }
        }
      }
      for (int k = 0; k < n_covered; ++k) {
        const int surface = covered_px[static_cast<std::size_t>(k)].surface;
        if (surface < 0) continue;  // already shaded with an earlier surface's batch
        int n = 0;
        for (int m = k; m < n_covered; ++m) {
          CoveredPixel& cp = covered_px[static_cast<std::size_t>(m)];
          if (cp.surface != surface) continue;
          batch_x[static_cast<std::size_t>(n)] = cp.x;
          batch_y[static_cast<std::size_t>(n)] = cp.y;
          batch_f[static_cast<std::size_t>(n)] = cp.footprint;
          batch_at[static_cast<std::size_t>(n)] = m;
          ++n;
          cp.surface = -1;
        }
        const Surface& fs = prep.surfaces[static_cast<std::size_t>(surface)];
        if (color) {
          ShadeBatch(prep, fs, batch_x.data(), batch_y.data(), batch_f.data(), n, tile_values.data());
        } else {
          ShadeBatchLuma(prep, fs, batch_x.data(), batch_y.data(), batch_f.data(), n, batch_luma.data());
        }
        for (int b = 0; b < n; ++b) {
          const CoveredPixel& cp = covered_px[static_cast<std::size_t>(batch_at[static_cast<std::size_t>(b)])];
          if (color) {
            store(cp.i, cp.j, tile_values[static_cast<std::size_t>(b)]);
          } else {
            out.at<float>(cp.j, cp.i) = batch_luma[static_cast<std::size_t>(b)];  // store's float(Luma(.))
          }
        }
      }
    }
  }
}

}  // namespace

void RasterizeRadiance(const Prepared& prep, bool color, int threads, cv::Mat* out_image) {
  const PixelGrid& g = *prep.grid;
  out_image->create(g.rows, g.cols, color ? CV_32FC3 : CV_32FC1);
  const int n = std::clamp(threads, 1, std::max(1, prep.tiles_y));
  std::vector<int> covered(static_cast<std::size_t>(prep.tiles_x * prep.tiles_y), 0);
  const bool interpolate = prep.shading_tolerance > 0;
  if (n == 1) {
    if (interpolate) ClassifyTileRows(prep, 0, 1, &covered);
    RasterizeTileRows(prep, color, 0, 1, covered, *out_image);
    return;
  }
  // Interleaved tile rows balance the work (the costly rows - textured floor, many edges - cluster).
  auto run = [&prep, n](auto&& rows) {
    std::vector<std::thread> helpers;
    helpers.reserve(static_cast<std::size_t>(n - 1));
    for (int k = 1; k < n; ++k) helpers.emplace_back([&rows, k] { rows(k); });
    rows(0);
    for (std::thread& h : helpers) h.join();
  };
  if (interpolate) run([&](int k) { ClassifyTileRows(prep, k, n, &covered); });
  run([&](int k) { RasterizeTileRows(prep, color, k, n, covered, *out_image); });
}

bool RasterizeSpots(const Prepared& prep, bool color, cv::Mat* out_image) {
  if (prep.spot_boxes.empty()) return false;
  const PixelGrid& g = *prep.grid;
  out_image->create(g.rows, g.cols, color ? CV_32FC3 : CV_32FC1);
  out_image->setTo(cv::Scalar::all(0));
  auto add = [&](int i, int j, const Vec3d& rgb) {
    if (color) {
      out_image->at<cv::Vec3f>(j, i) +=
          cv::Vec3f(static_cast<float>(rgb.x()), static_cast<float>(rgb.y()), static_cast<float>(rgb.z()));
    } else {
      out_image->at<float>(j, i) += static_cast<float>(Luma(rgb));
    }
  };
  cv::Mat done(g.rows, g.cols, CV_8UC1, cv::Scalar(0));
  PixelIntegrator integrator(prep, true);
  for (const SpotBox& b : prep.spot_boxes) {
    const PreparedSpot& ps = prep.laser_spots[static_cast<std::size_t>(b.spot)];
    const GaussLegendre& gl = GaussLegendreRule(b.samples);
    for (int j = std::max(b.y0, 0); j <= std::min(b.y1, g.rows - 1); ++j) {
      for (int i = std::max(b.x0, 0); i <= std::min(b.x1, g.cols - 1); ++i) {
        if (ps.image_layer) {
          // The spot's image convolved with the PSF, integrated over the pixel square.
          double sum = 0;
          for (std::size_t v = 0; v < gl.x.size(); ++v) {
            for (std::size_t u = 0; u < gl.x.size(); ++u) {
              const Vec2d d = Vec2d(g.x0 + i - 0.5 + gl.x[u], g.y0 + j - 0.5 + gl.x[v]) - ps.centroid_px;
              sum += gl.w[u] * gl.w[v] * std::exp(-0.5 * d.dot(ps.inv_cov_layer * d));
            }
          }
          add(i, j, ps.amplitude * sum * ps.color);
          continue;
        }
        // No PSF: the emission on the surfaces, with exact visibility (once per pixel for all spots).
        if (done.at<uint8_t>(j, i) != 0) continue;
        done.at<uint8_t>(j, i) = 1;
        int samples = 1;
        for (const SpotBox& o : prep.spot_boxes) {
          if (i >= o.x0 && i <= o.x1 && j >= o.y0 && j <= o.y1) samples = std::max(samples, o.samples);
        }
        const int tx = i / kTileSize, ty = j / kTileSize;
        const std::size_t t = static_cast<std::size_t>(ty * prep.tiles_x + tx);
        const Vec2d q[4] = {g.Corner(i, j), g.Corner(i + 1, j), g.Corner(i + 1, j + 1), g.Corner(i, j + 1)};
        add(i, j,
            integrator.Pixel(q, prep.tile_items.data() + prep.tile_start[t], prep.tile_start[t + 1] - prep.tile_start[t],
                             prep.tile_radius[t], samples));
      }
    }
  }
  return true;
}

}  // namespace idi::sim::internal
