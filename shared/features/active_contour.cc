#include "shared/features/active_contour.h"

#include <algorithm>
#include <cmath>

#include "shared/features/hough.h"
#include "shared/features/idi_points.h"

namespace idi {
namespace {

double MagnitudeAt(const GradientImages& g, const Eigen::Vector2d& p) {
  const double x = std::clamp(p.x(), 0.0, g.width() - 1.001), y = std::clamp(p.y(), 0.0, g.height() - 1.001);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double ax = x - x0, ay = y - y0;
  auto m = [&](int yy, int xx) { return std::sqrt(static_cast<double>(g.mag2.at<float>(yy, xx))); };
  return (1 - ay) * ((1 - ax) * m(y0, x0) + ax * m(y0, x0 + 1)) + ay * ((1 - ax) * m(y0 + 1, x0) + ax * m(y0 + 1, x0 + 1));
}

Eigen::Vector2d NormalAt(const std::vector<Eigen::Vector2d>& v, std::size_t i) {
  const std::size_t a = i == 0 ? 0 : i - 1, b = std::min(v.size() - 1, i + 1);
  Eigen::Vector2d d = v[b] - v[a];
  if (d.norm() < 1e-9) {
    return Eigen::Vector2d::UnitY();
  }
  d.normalize();
  return Eigen::Vector2d(-d.y(), d.x());
}

// Ordered chain of 8-connected pixels through `seed`, consuming them from `mask`.
std::vector<Eigen::Vector2d> TraceChain(cv::Mat& mask, cv::Point seed) {
  auto walk = [&mask](cv::Point p) {
    std::vector<Eigen::Vector2d> out;
    for (;;) {
      bool moved = false;
      for (int dy = -1; dy <= 1 && !moved; ++dy) {
        for (int dx = -1; dx <= 1 && !moved; ++dx) {
          const cv::Point q(p.x + dx, p.y + dy);
          if ((dx || dy) && q.x >= 0 && q.y >= 0 && q.x < mask.cols && q.y < mask.rows && mask.at<std::uint8_t>(q)) {
            mask.at<std::uint8_t>(q) = 0;
            out.emplace_back(q.x, q.y);
            p = q;
            moved = true;
          }
        }
      }
      if (!moved) {
        return out;
      }
    }
  };
  mask.at<std::uint8_t>(seed) = 0;
  std::vector<Eigen::Vector2d> forward = walk(seed);
  std::vector<Eigen::Vector2d> backward = walk(seed);
  std::reverse(backward.begin(), backward.end());
  backward.emplace_back(seed.x, seed.y);
  backward.insert(backward.end(), forward.begin(), forward.end());
  return backward;
}

double ChainLength(const std::vector<Eigen::Vector2d>& c) {
  double s = 0;
  for (std::size_t i = 1; i < c.size(); ++i) {
    s += (c[i] - c[i - 1]).norm();
  }
  return s;
}

double PointToPolyline(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& p) {
  double best = 1e18;
  for (std::size_t i = 0; i + 1 < poly.size(); ++i) {
    const Eigen::Vector2d d = poly[i + 1] - poly[i];
    const double l2 = d.squaredNorm();
    const double t = l2 > 0 ? std::clamp(d.dot(p - poly[i]) / l2, 0.0, 1.0) : 0.0;
    best = std::min(best, (poly[i] + t * d - p).squaredNorm());
  }
  return std::sqrt(best);
}

}  // namespace

std::vector<Eigen::Vector2d> FitActiveContour(const GradientImages& g, const std::vector<Eigen::Vector2d>& chain,
                                              const CurveOptions& o) {
  std::vector<Eigen::Vector2d> v;
  if (chain.size() < 2) {
    return v;
  }
  // Control points every point_spacing_px along the chain.
  v.push_back(chain.front());
  double acc = 0;
  for (std::size_t i = 1; i < chain.size(); ++i) {
    acc += (chain[i] - chain[i - 1]).norm();
    if (acc >= o.point_spacing_px) {
      v.push_back(chain[i]);
      acc = 0;
    }
  }
  if ((v.back() - chain.back()).norm() > 0.5 * o.point_spacing_px) {
    v.push_back(chain.back());
  } else {
    v.back() = chain.back();
  }
  if (v.size() < 3) {
    return v;
  }
  // Greedy minimisation (Williams-Shah) over positions along each point's normal.
  for (int iter = 0; iter < o.max_iterations; ++iter) {
    double mean_d = 0;
    for (std::size_t i = 1; i < v.size(); ++i) {
      mean_d += (v[i] - v[i - 1]).norm();
    }
    mean_d /= static_cast<double>(v.size() - 1);
    int moved = 0;
    for (std::size_t i = 0; i < v.size(); ++i) {
      const Eigen::Vector2d n = NormalAt(v, i);
      double mag_max = 1e-9;
      std::array<double, 9> mags{};
      for (int k = -4; k <= 4; ++k) {
        mags[static_cast<std::size_t>(k + 4)] = MagnitudeAt(g, v[i] + 0.5 * k * n);
        mag_max = std::max(mag_max, mags[static_cast<std::size_t>(k + 4)]);
      }
      double best_e = 1e18;
      int best_k = 0;
      for (int k = -4; k <= 4; ++k) {
        const Eigen::Vector2d c = v[i] + 0.5 * k * n;
        double e = -o.gamma * mags[static_cast<std::size_t>(k + 4)] / mag_max;
        if (i > 0) {
          const double d = (c - v[i - 1]).norm() - mean_d;
          e += o.alpha * d * d / (mean_d * mean_d);
        }
        if (i > 0 && i + 1 < v.size()) {
          e += o.beta * (v[i - 1] - 2 * c + v[i + 1]).squaredNorm() / (mean_d * mean_d);
        }
        if (e < best_e - 1e-12) {
          best_e = e;
          best_k = k;
        }
      }
      if (best_k != 0) {
        v[i] += 0.5 * best_k * n;
        ++moved;
      }
    }
    if (moved == 0) {
      break;
    }
  }
  // Sub-pixel: each point onto the gradient peak along its normal (parabola through 3 samples).
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<Eigen::Vector2d> nv = v;
    for (std::size_t i = 0; i < v.size(); ++i) {
      const Eigen::Vector2d n = NormalAt(v, i);
      const double a = MagnitudeAt(g, v[i] - n), b = MagnitudeAt(g, v[i]), c = MagnitudeAt(g, v[i] + n);
      const double den = a - 2 * b + c;
      if (den < 0) {
        nv[i] = v[i] + std::clamp(0.5 * (a - c) / den, -1.0, 1.0) * n;
      }
    }
    v = nv;
  }
  return v;
}

std::vector<Curve> FindCurves(const GradientImages& g, const EdgeMap& edges, const PixelGeometry& geometry,
                              const std::vector<EmplLine>& lines, const CurveOptions& o, cv::Mat* work) {
  std::vector<Curve> curves;
  // Only edge pixels no Hough peak claimed (1) can start a chain; if there are none, no curves.
  bool any_free = false;
  for (const cv::Point& p : edges.pixels) {
    if (edges.mask.at<std::uint8_t>(p) == 1) {
      any_free = true;
      break;
    }
  }
  if (!any_free) {
    return curves;
  }
  edges.mask.copyTo(*work);  // 1: free edge pixel, 2: claimed by a Hough peak
  cv::Mat& mask = *work;
  // Edge pixels the lines explain are not curves.
  for (const EmplLine& l : lines) {
    const Eigen::Vector2d d = l.p2 - l.p1;
    const double len = d.norm();
    const Eigen::Vector2d u = len > 0 ? Eigen::Vector2d(d / len) : Eigen::Vector2d::UnitX();
    const bool horizontal = std::fabs(u.x()) >= std::fabs(u.y());
    for (double t = -2; t <= len + 2; t += 0.7) {
      const Eigen::Vector2d q = geometry.ToPixel(l.p1 + t * u);
      const int qx = RoundToInt(q.x()), qy = RoundToInt(q.y());
      for (int k = -2; k <= 2; ++k) {
        const int x = horizontal ? qx : qx + k, y = horizontal ? qy + k : qy;
        if (x >= 0 && y >= 0 && x < mask.cols && y < mask.rows) {
          mask.at<std::uint8_t>(y, x) = 0;
        }
      }
    }
  }
  for (const cv::Point& seed : edges.pixels) {
    if (!mask.at<std::uint8_t>(seed)) {
      continue;
    }
    const std::vector<Eigen::Vector2d> chain = TraceChain(mask, seed);
    if (ChainLength(chain) < o.min_length_px) {
      continue;
    }
    std::vector<Vec2d> pts(chain.begin(), chain.end());
    Vec2d n;
    double off;
    if (FitLineTls(pts, nullptr, &n, &off)) {
      double s = 0;
      for (const Vec2d& p : pts) {
        s += (n.dot(p) - off) * (n.dot(p) - off);
      }
      if (std::sqrt(s / static_cast<double>(pts.size())) < o.straight_rms_px) {
        continue;  // straight: not a curve
      }
    }
    std::vector<Eigen::Vector2d> snake = FitActiveContour(g, chain, o);
    if (snake.size() < 3) {
      continue;
    }
    Curve c;
    c.id = static_cast<int>(curves.size());
    double s = 0;
    for (const Eigen::Vector2d& p : chain) {
      const double d = PointToPolyline(snake, p);
      s += d * d;
    }
    c.fit_rms_px = std::sqrt(s / static_cast<double>(chain.size()));
    for (const Eigen::Vector2d& p : snake) {
      c.points.push_back(geometry.ToFit(p));
    }
    curves.push_back(std::move(c));
  }
  return curves;
}

void AddCurveLinePoints(const IdiOptions& options, std::vector<Curve>* curves, std::vector<EmplLine>* lines,
                        std::vector<IdiPoint>* points) {
  const double min_sin = std::sin(options.min_angle_deg * 3.14159265358979323846 / 180.0);
  for (Curve& c : *curves) {
    if (c.points.size() < 3) {
      continue;
    }
    const double var_c = std::max(0.01, c.fit_rms_px * c.fit_rms_px / 3.0);
    for (EmplLine& l : *lines) {
      const double ext = (l.extension1 - l.p1).norm();
      // Candidate positions along the polyline: crossings, and ends lying on the line.
      struct Hit {
        Eigen::Vector2d xy;
        Eigen::Vector2d tangent;
      };
      std::vector<Hit> hits;
      for (std::size_t k = 0; k + 1 < c.points.size(); ++k) {
        const double s0 = l.SignedDistance(c.points[k]), s1 = l.SignedDistance(c.points[k + 1]);
        if ((s0 < 0) != (s1 < 0)) {
          const double t = s0 / (s0 - s1);
          hits.push_back({c.points[k] + t * (c.points[k + 1] - c.points[k]), c.points[k + 1] - c.points[k]});
        }
      }
      for (int end = 0; end < 2; ++end) {
        const std::size_t i0 = end == 0 ? 0 : c.points.size() - 1;
        const std::size_t i1 = end == 0 ? std::min<std::size_t>(2, c.points.size() - 1) : c.points.size() - 3;
        const Eigen::Vector2d q = c.points[i0];
        if (std::fabs(l.SignedDistance(q)) <= 3.0) {
          const Eigen::Vector2d tdir = q - c.points[i1];
          const double den = l.normal.dot(tdir);
          if (std::fabs(den) > 1e-9) {
            const double s = -l.SignedDistance(q) / den;
            hits.push_back({q + s * tdir, tdir});
          }
        }
      }
      for (const Hit& h : hits) {
        const double tn = h.tangent.norm();
        if (tn < 1e-9 || std::fabs(l.normal.dot(h.tangent / tn)) < min_sin) {
          continue;
        }
        if (DistanceBeyondSegment(l, h.xy) > ext) {
          continue;
        }
        // The curve's local tangent as a line with the curve's positional uncertainty.
        EmplLine tangent_line;
        tangent_line.normal = Eigen::Vector2d(-h.tangent.y(), h.tangent.x()) / tn;
        tangent_line.offset = tangent_line.normal.dot(h.xy);
        const Eigen::Vector2d nd(-tangent_line.normal.y(), tangent_line.normal.x());
        // Angle variance from ~2 control-point spacings of support; offset chosen so the distance
        // variance at the point is var_c.
        const double var_angle = var_c / std::max(1.0, tn * tn);
        const double dx = nd.dot(h.xy);
        tangent_line.covariance << var_angle, var_angle * dx, var_angle * dx, var_c + var_angle * dx * dx;
        IdiPoint p;
        if (!IntersectLinesWeighted({&l, &tangent_line}, h.xy, &p.xy, &p.covariance)) {
          continue;
        }
        // Merge with an existing point of this line when close.
        bool merged = false;
        for (IdiPoint& existing : *points) {
          if ((existing.xy - p.xy).norm() <= options.merge_radius_px &&
              std::find(existing.line_ids.begin(), existing.line_ids.end(), l.id) != existing.line_ids.end()) {
            if (std::find(existing.curve_ids.begin(), existing.curve_ids.end(), c.id) == existing.curve_ids.end()) {
              existing.curve_ids.push_back(c.id);
              c.point_ids.push_back(existing.id);
            }
            merged = true;
            break;
          }
        }
        // A new point the curve and the line cannot place (IdiOptions::max_point_sigma_px) is not reported.
        if (merged || !PlacedPreciselyEnough(p, options)) {
          continue;
        }
        p.id = static_cast<int>(points->size());
        p.kind = IdiPointKind::kCurveLine;
        p.line_ids = {l.id};
        p.curve_ids = {c.id};
        l.point_ids.push_back(p.id);
        c.point_ids.push_back(p.id);
        points->push_back(std::move(p));
      }
    }
  }
}

}  // namespace idi
