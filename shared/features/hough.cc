#include "shared/features/hough.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <numeric>
#include <opencv2/core/hal/intrin.hpp>

namespace idi {

bool FitLineTls(const std::vector<Vec2d>& points, const std::vector<double>* weights, Vec2d* normal, double* offset) {
  if (points.size() < 2) {
    return false;
  }
  double sw = 0, sx = 0, sy = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double w = weights ? (*weights)[i] : 1.0;
    sw += w;
    sx += w * points[i].x();
    sy += w * points[i].y();
  }
  if (sw <= 0) {
    return false;
  }
  const double mx = sx / sw, my = sy / sw;
  double cxx = 0, cxy = 0, cyy = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double w = weights ? (*weights)[i] : 1.0;
    const double dx = points[i].x() - mx, dy = points[i].y() - my;
    cxx += w * dx * dx;
    cxy += w * dx * dy;
    cyy += w * dy * dy;
  }
  if (cxx + cyy <= 0) {
    return false;
  }
  // Direction of largest spread: angle 0.5*atan2(2cxy, cxx-cyy); the normal is perpendicular.
  const double phi = 0.5 * std::atan2(2 * cxy, cxx - cyy);
  *normal = Vec2d(-std::sin(phi), std::cos(phi));
  *offset = normal->dot(Vec2d(mx, my));
  return true;
}

void HoughLineFinder::Vote(int index, int delta) {
  const std::size_t i = static_cast<std::size_t>(index);
  const float x = ex_[i], y = ey_[i];
  const int b = bin_[i];
  const float inv_step = static_cast<float>(1.0 / options_.offset_step_px);
  const float r0 = static_cast<float>(r_max_ / options_.offset_step_px) + 0.5f;
  for (int k = -window_bins_; k <= window_bins_; ++k) {
    int t = b + k;
    if (t < 0) {
      t += n_theta_;
    } else if (t >= n_theta_) {
      t -= n_theta_;
    }
    const float r = x * cos_[static_cast<std::size_t>(t)] + y * sin_[static_cast<std::size_t>(t)];
    const float fb = r * inv_step + r0;
    if (!(fb >= 0.0f && fb < static_cast<float>(n_r_))) {
      continue;  // only under extreme distortion: outside the accumulator
    }
    const int rb = static_cast<int>(fb);
    std::uint16_t& cell = acc_[static_cast<std::size_t>(t) * static_cast<std::size_t>(n_r_) + static_cast<std::size_t>(rb)];
    cell = static_cast<std::uint16_t>(cell + delta);
  }
}

bool HoughLineFinder::AnyEdgeBlock(int x0, int y0, int x1, int y1) const {
  const int bx0 = std::max(0, x0 >> kBlockShift), by0 = std::max(0, y0 >> kBlockShift);
  const int bx1 = std::min(block_cols_ - 1, x1 >> kBlockShift), by1 = std::min(block_rows_ - 1, y1 >> kBlockShift);
  for (int by = by0; by <= by1; ++by) {
    const std::uint8_t* row = &blocks_[static_cast<std::size_t>(by) * static_cast<std::size_t>(block_cols_)];
    for (int bx = bx0; bx <= bx1; ++bx) {
      if (row[bx] != 0) return true;
    }
  }
  return false;
}

void HoughLineFinder::Walk(const GradientImages& g, const EdgeMap& edges, const PixelGeometry& geometry,
                           const Vec2d& normal, double offset, double t_min, double t_max, std::vector<Hit>* hits) {
  hits->clear();
  const int w = g.width(), h = g.height();
  const Vec2d dir = LineDirection(normal);
  const Vec2d foot = normal * offset;
  const bool horizontal = std::fabs(dir.x()) >= std::fabs(dir.y());
  const bool ident = geometry.identity();
  if (!ident) {
    // A new mark for this walk's pixels. The count would overflow after 2^31 walks (a week of video at
    // 30 frames a second and a hundred walks a frame): the marks start again from a clean image first.
    if (visit_.rows != h || visit_.cols != w || walk_id_ == std::numeric_limits<int>::max()) {
      visit_.create(h, w, CV_32S);
      visit_.setTo(0);
      walk_id_ = 0;
    }
    ++walk_id_;
  }
  const double step = ident ? 1.0 : 0.8;
  const int reach = static_cast<int>(std::ceil(options_.band_px));
  // The line is walked in chunks of kChunk steps; a chunk whose band (with a margin for rounding and
  // for the bend of a distorted line over a few pixels) lies in empty blocks is stepped over. The
  // steps themselves are the same as without the skip, so are the hits.
  constexpr int kChunk = 8;
  const int margin = reach + 2;
  // Without distortion the walk's major coordinate (x of a horizontal walk) moves one way only, by at
  // least 0.7 px a step, so a pixel can only be tested again at the very next step: that step's band
  // is masked off where it overlaps the last one, instead of marking every tested pixel in the visit
  // image (a cache miss per candidate on a cluttered frame). A distorted line may bend back across
  // columns: there the visit image stays.
  int last_major = std::numeric_limits<int>::min(), last_minor = 0;
  double t = t_min;
  while (t <= t_max) {
    const Vec2d qa = geometry.ToPixel(foot + t * dir);
    const Vec2d qb = geometry.ToPixel(foot + std::min(t_max, t + (kChunk - 1) * step) * dir);
    const int x0 = static_cast<int>(std::floor(std::min(qa.x(), qb.x()))) - margin;
    const int y0 = static_cast<int>(std::floor(std::min(qa.y(), qb.y()))) - margin;
    const int x1 = static_cast<int>(std::ceil(std::max(qa.x(), qb.x()))) + margin;
    const int y1 = static_cast<int>(std::ceil(std::max(qa.y(), qb.y()))) + margin;
    if (!AnyEdgeBlock(x0, y0, x1, y1)) {
      for (int c = 0; c < kChunk && t <= t_max; ++c) t += step;
      continue;
    }
    for (int c = 0; c < kChunk && t <= t_max; ++c, t += step) {
      const Vec2d q = geometry.ToPixel(foot + t * dir);
      const int qx = RoundToInt(q.x()), qy = RoundToInt(q.y());
      // The band's pixels across the line that are unclaimed edges (mask 1; 2 = claimed by a stronger
      // peak), as bits from k = -reach up: on a cluttered frame most band pixels are not edges, and
      // testing them one by one with a branch each was most of the walk's time.
      unsigned candidates = 0;
      const int bx0 = horizontal ? qx : qx - reach, by0 = horizontal ? qy - reach : qy;
      const int bx1 = horizontal ? qx : qx + reach, by1 = horizontal ? qy + reach : qy;
      if (bx0 >= 0 && by0 >= 0 && bx1 < w && by1 < h) {
        const std::uint8_t* m = edges.mask.ptr<std::uint8_t>(by0) + bx0;
        const std::ptrdiff_t stride = horizontal ? static_cast<std::ptrdiff_t>(edges.mask.step[0]) : 1;
        for (int i = 0; i <= 2 * reach; ++i) candidates |= static_cast<unsigned>(m[i * stride] == 1) << i;
      } else {
        for (int i = 0; i <= 2 * reach; ++i) {
          const int px = horizontal ? qx : bx0 + i, py = horizontal ? by0 + i : qy;
          if (px >= 0 && py >= 0 && px < w && py < h && edges.mask.at<std::uint8_t>(py, px) == 1) candidates |= 1u << i;
        }
      }
      if (ident) {
        const int major = horizontal ? qx : qy, minor = horizontal ? qy : qx;
        if (major == last_major) {
          // Bit i is the pixel at minor - reach + i; the last step tested last_minor +- reach.
          const int shift = minor - last_minor;
          const int lo = std::max(0, -shift), hi = std::min(2 * reach, 2 * reach - shift);
          if (lo <= hi) candidates &= ~(((2u << hi) - 1u) & ~((1u << lo) - 1u));
        }
        last_major = major;
        last_minor = minor;
      }
      while (candidates != 0) {
        const int i = std::countr_zero(candidates);
        candidates &= candidates - 1;
        const int px = horizontal ? qx : bx0 + i, py = horizontal ? by0 + i : qy;
        if (!ident) {
          int& visit = visit_.at<int>(py, px);
          if (visit == walk_id_) {
            continue;
          }
          visit = walk_id_;
        }
        const Vec2d u = geometry.ToFit(px, py);
        if (std::fabs(normal.dot(u) - offset) > options_.band_px) {
          continue;
        }
        const double gxv = g.gx.at<float>(py, px), gyv = g.gy.at<float>(py, px);
        const double gn = std::fabs(gxv * normal.x() + gyv * normal.y());
        if (gn < cos_tol_ * std::sqrt(gxv * gxv + gyv * gyv)) {
          continue;
        }
        hits->push_back({dir.dot(u - foot), index_.at<int>(py, px)});
      }
    }
  }
  std::sort(hits->begin(), hits->end(), [](const Hit& a, const Hit& b) { return a.t < b.t; });
}

namespace {

struct HoughRun {
  std::size_t begin, end;  // [begin, end) into hits
  double t0, t1;
};

template <typename HitT>
std::vector<HoughRun> SplitIntoRuns(const std::vector<HitT>& hits, const HoughOptions& o) {
  std::vector<HoughRun> runs;
  std::size_t start = 0;
  for (std::size_t i = 1; i <= hits.size(); ++i) {
    if (i == hits.size() || hits[i].t - hits[i - 1].t > o.max_gap_px + 1.0) {
      if (i > start) {
        const double t0 = hits[start].t, t1 = hits[i - 1].t;
        const double length = t1 - t0 + 1.0;
        if (length >= o.min_length_px && static_cast<double>(i - start) >= o.min_fill * length) {
          runs.push_back({start, i, t0, t1});
        }
      }
      start = i;
    }
  }
  return runs;
}

// Range of t for which foot + t*dir lies within the rectangle [lo, hi] (expanded).
bool ClipLineToBox(const Vec2d& foot, const Vec2d& dir, const Vec2d& lo, const Vec2d& hi, double* t0, double* t1) {
  double a = -1e18, b = 1e18;
  for (int i = 0; i < 2; ++i) {
    if (std::fabs(dir[i]) < 1e-12) {
      if (foot[i] < lo[i] || foot[i] > hi[i]) {
        return false;
      }
      continue;
    }
    double s0 = (lo[i] - foot[i]) / dir[i], s1 = (hi[i] - foot[i]) / dir[i];
    if (s0 > s1) {
      std::swap(s0, s1);
    }
    a = std::max(a, s0);
    b = std::min(b, s1);
  }
  *t0 = a;
  *t1 = b;
  return b > a;
}

}  // namespace

std::vector<HoughSegment> HoughLineFinder::Find(const GradientImages& g, EdgeMap* edges, const PixelGeometry& geometry,
                                                const HoughOptions& options) {
  options_ = options;
  const int w = g.width(), h = g.height();
  constexpr double kPi = 3.14159265358979323846;
  n_theta_ = std::max(4, static_cast<int>(std::lround(180.0 / options.angle_step_deg)));
  const double theta_step = kPi / n_theta_;
  window_bins_ = static_cast<int>(std::ceil(options.vote_window_deg / options.angle_step_deg));
  centre_ = Vec2d(0.5 * (w - 1), 0.5 * (h - 1));
  // Fit coordinates may stretch beyond the image under distortion: leave a generous margin.
  r_max_ = 0.5 * std::hypot(w, h) * (geometry.identity() ? 1.0 : 1.5) + 4.0;
  n_r_ = static_cast<int>(std::ceil(2.0 * r_max_ / options.offset_step_px)) + 2;
  cos_.resize(static_cast<std::size_t>(n_theta_));
  sin_.resize(static_cast<std::size_t>(n_theta_));
  for (int t = 0; t < n_theta_; ++t) {
    cos_[static_cast<std::size_t>(t)] = static_cast<float>(std::cos((t + 0.5) * theta_step));
    sin_[static_cast<std::size_t>(t)] = static_cast<float>(std::sin((t + 0.5) * theta_step));
  }
  acc_.assign(static_cast<std::size_t>(n_theta_) * static_cast<std::size_t>(n_r_), 0);
  cos_tol_ = std::cos(options.max_angle_error_deg * kPi / 180.0);
  if (index_.rows != h || index_.cols != w) {
    index_.create(h, w, CV_32S);
    index_.setTo(-1);
  }

  // Votes of each edge pixel, restricted to +-window around its gradient direction.
  const std::size_t n = edges->pixels.size();
  block_cols_ = (w + (1 << kBlockShift) - 1) >> kBlockShift;
  block_rows_ = (h + (1 << kBlockShift) - 1) >> kBlockShift;
  blocks_.assign(static_cast<std::size_t>(block_cols_) * static_cast<std::size_t>(block_rows_), 0);
  ex_.resize(n);
  ey_.resize(n);
  bin_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const cv::Point p = edges->pixels[i];
    const Vec2d u = geometry.ToFit(p.x, p.y) - centre_;
    ex_[i] = static_cast<float>(u.x());
    ey_[i] = static_cast<float>(u.y());
    double angle = FastAtan2(g.gy.at<float>(p), g.gx.at<float>(p));
    if (angle < 0) {
      angle += kPi;
    }
    bin_[i] = std::min(n_theta_ - 1, static_cast<int>(angle / theta_step));
    index_.at<int>(p) = static_cast<int>(i);
    blocks_[static_cast<std::size_t>(p.y >> kBlockShift) * static_cast<std::size_t>(block_cols_) +
            static_cast<std::size_t>(p.x >> kBlockShift)] = 1;
    Vote(static_cast<int>(i), +1);
  }

  // Peak candidates: local maxima whose score (three offset bins) reaches the minimum.
  const int min_score = std::max(3, static_cast<int>(0.8 * options.min_length_px * options.min_fill));
  auto score_at = [&](int t, int r) {
    const std::uint16_t* row = &acc_[static_cast<std::size_t>(t) * static_cast<std::size_t>(n_r_)];
    return static_cast<int>(row[r - 1]) + row[r] + row[r + 1];
  };
  struct Peak {
    int score, t, r;
  };
  std::vector<Peak> peaks;
  for (int t = 0; t < n_theta_; ++t) {
    const int tp = t == 0 ? n_theta_ - 1 : t - 1;
    const int tn = t == n_theta_ - 1 ? 0 : t + 1;
    const std::uint16_t* row = &acc_[static_cast<std::size_t>(t) * static_cast<std::size_t>(n_r_)];
    const auto consider = [&](int r) {
      const int v = row[r];
      if (v == 0 || 3 * v < min_score || v < row[r - 1] || v <= row[r + 1]) {
        return;
      }
      // Wrapping in theta flips the sign of r; compare with the mirrored bins there.
      const int rp = t == 0 ? n_r_ - 1 - r : r;
      const int rn = t == n_theta_ - 1 ? n_r_ - 1 - r : r;
      const std::uint16_t* prow = &acc_[static_cast<std::size_t>(tp) * static_cast<std::size_t>(n_r_)];
      const std::uint16_t* nrow = &acc_[static_cast<std::size_t>(tn) * static_cast<std::size_t>(n_r_)];
      if (v < prow[rp] || v <= nrow[rn]) {
        return;
      }
      const int s = score_at(t, r);
      if (s >= min_score) {
        peaks.push_back({s, t, r});
      }
    };
    int r = 2;
#if CV_SIMD128
    // Eight bins at a time: only a bin that passes the threshold and is a maximum along r goes on
    // to the full test (on a textured floor most bins hold a few votes).
    const cv::v_uint16x8 vmin = cv::v_setall_u16(static_cast<std::uint16_t>((min_score + 2) / 3));
    for (; r + 8 <= n_r_ - 2; r += 8) {
      const cv::v_uint16x8 v = cv::v_load(row + r);
      const cv::v_uint16x8 maybe = (v >= vmin) & (v >= cv::v_load(row + r - 1)) & (v > cv::v_load(row + r + 1));
      if (!cv::v_check_any(maybe)) {
        continue;
      }
      const int bits = cv::v_signmask(maybe);
      for (int i = 0; i < 8; ++i) {
        if (bits & (1 << i)) consider(r + i);
      }
    }
#endif
    for (; r < n_r_ - 2; ++r) {
      consider(r);
    }
  }
  std::sort(peaks.begin(), peaks.end(), [](const Peak& a, const Peak& b) { return a.score > b.score; });

  std::vector<HoughSegment> segments;
  std::vector<Hit> hits, hits2;
  std::vector<Vec2d> pts;
  const Vec2d lo = geometry.identity() ? Vec2d(-0.5, -0.5) : Vec2d(-0.25 * w, -0.25 * h);
  const Vec2d hi = geometry.identity() ? Vec2d(w - 0.5, h - 0.5) : Vec2d(1.25 * w, 1.25 * h);
  for (const Peak& peak : peaks) {
    if (static_cast<int>(segments.size()) >= options.max_lines) {
      break;
    }
    if (score_at(peak.t, peak.r) < min_score) {
      continue;  // its pixels were claimed by stronger peaks
    }
    const double theta = (peak.t + 0.5) * theta_step;
    Vec2d normal(std::cos(theta), std::sin(theta));
    double offset = (peak.r - r_max_ / options.offset_step_px) * options.offset_step_px + normal.dot(centre_);
    double t_min, t_max;
    if (!ClipLineToBox(normal * offset, LineDirection(normal), lo, hi, &t_min, &t_max)) {
      continue;
    }
    Walk(g, *edges, geometry, normal, offset, t_min, t_max, &hits);
    for (const HoughRun& run : SplitIntoRuns(hits, options)) {
      // Refit the run's pixels and walk again along the refined line: the peak's bin is only
      // accurate to half a bin, which drifts off a long line.
      pts.clear();
      for (std::size_t i = run.begin; i < run.end; ++i) {
        const cv::Point p = edges->pixels[static_cast<std::size_t>(hits[i].index)];
        pts.push_back(geometry.ToFit(p.x, p.y));
      }
      Vec2d n2;
      double d2;
      if (!FitLineTls(pts, nullptr, &n2, &d2)) {
        continue;
      }
      if (n2.dot(normal) < 0) {
        n2 = -n2;
        d2 = -d2;
      }
      const Vec2d foot_old = normal * offset, dir_old = LineDirection(normal);
      const Vec2d a = foot_old + (run.t0 - options.max_gap_px - 2) * dir_old;
      const Vec2d b = foot_old + (run.t1 + options.max_gap_px + 2) * dir_old;
      const Vec2d foot2 = n2 * d2, dir2 = LineDirection(n2);
      double c0, c1;
      if (!ClipLineToBox(foot2, dir2, lo, hi, &c0, &c1)) {
        continue;
      }
      const double s0 = std::max(c0, dir2.dot(a - foot2)), s1 = std::min(c1, dir2.dot(b - foot2));
      Walk(g, *edges, geometry, n2, d2, s0, s1, &hits2);
      const std::vector<HoughRun> runs2 = SplitIntoRuns(hits2, options);
      if (runs2.empty()) {
        continue;
      }
      const HoughRun* best = &runs2.front();
      for (const HoughRun& r2 : runs2) {
        if (r2.end - r2.begin > best->end - best->begin) {
          best = &r2;
        }
      }
      HoughSegment seg;
      seg.normal = n2;
      seg.offset = d2;
      seg.t0 = best->t0;
      seg.t1 = best->t1;
      seg.support = static_cast<int>(best->end - best->begin);
      segments.push_back(seg);
      for (std::size_t i = best->begin; i < best->end; ++i) {
        const int idx = hits2[i].index;
        const cv::Point p = edges->pixels[static_cast<std::size_t>(idx)];
        if (edges->mask.at<std::uint8_t>(p) == 1) {
          edges->mask.at<std::uint8_t>(p) = 2;
          Vote(idx, -1);
        }
      }
    }
  }
  // Leave the index image clean for the next frame.
  for (const cv::Point& p : edges->pixels) {
    index_.at<int>(p) = -1;
  }
  return segments;
}

}  // namespace idi
