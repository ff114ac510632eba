#include "shared/features/idi_points.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace idi {

double LineDistanceVariance(const EmplLine& line, const Eigen::Vector2d& x) {
  // f = n(phi)·x - d; df/dphi = n'(phi)·x, df/dd = -1.
  const Eigen::Vector2d nd(-line.normal.y(), line.normal.x());
  const Eigen::Vector2d j(nd.dot(x), -1.0);
  return j.dot(line.covariance * j);
}

bool IntersectLinesWeighted(const std::vector<const EmplLine*>& lines, const Eigen::Vector2d& start,
                            Eigen::Vector2d* xy, Eigen::Matrix2d* covariance) {
  if (lines.size() < 2) {
    return false;
  }
  Eigen::Vector2d x = start;
  Eigen::Matrix2d a;
  for (int iter = 0; iter < 2; ++iter) {
    a.setZero();
    Eigen::Vector2d b = Eigen::Vector2d::Zero();
    for (const EmplLine* l : lines) {
      const double var = std::max(1e-12, LineDistanceVariance(*l, x));
      a += l->normal * l->normal.transpose() / var;
      b += l->normal * l->offset / var;
    }
    const double det = a.determinant();
    if (!(std::fabs(det) > 1e-12 * a.squaredNorm())) {
      return false;
    }
    x = a.inverse() * b;
  }
  if (!x.allFinite()) {
    return false;
  }
  *xy = x;
  *covariance = a.inverse();
  return covariance->allFinite();
}

std::optional<LineIntersection> IntersectWithCovariance(const EmplLine& a, const EmplLine& b) {
  const double det = a.normal.x() * b.normal.y() - a.normal.y() * b.normal.x();
  if (std::fabs(det) < 1e-9) {
    return std::nullopt;
  }
  const Eigen::Vector2d x0((a.offset * b.normal.y() - b.offset * a.normal.y()) / det,
                           (a.normal.x() * b.offset - b.normal.x() * a.offset) / det);
  LineIntersection out;
  if (!IntersectLinesWeighted({&a, &b}, x0, &out.xy, &out.covariance)) {
    return std::nullopt;
  }
  return out;
}

bool PlacedPreciselyEnough(const IdiPoint& point, const IdiOptions& options) {
  const double max_sigma = options.max_point_sigma_px;
  return max_sigma <= 0 || point.covariance.trace() <= max_sigma * max_sigma;
}

double DistanceBeyondSegment(const EmplLine& line, const Eigen::Vector2d& x) {
  const Eigen::Vector2d d = line.p2 - line.p1;
  const double len = d.norm();
  if (len <= 0) {
    return (x - line.p1).norm();
  }
  const double t = d.dot(x - line.p1) / len;
  return std::max({0.0, -t, t - len});
}

namespace {

// Bilinear sample of a CV_32F image; false outside [0, cols - 1] x [0, rows - 1].
bool Sample(const cv::Mat& img, const Eigen::Vector2d& p, double* v) {
  if (!(p.x() >= 0 && p.y() >= 0 && p.x() <= img.cols - 1.001 && p.y() <= img.rows - 1.001)) return false;
  const int x0 = static_cast<int>(p.x()), y0 = static_cast<int>(p.y());
  const double fx = p.x() - x0, fy = p.y() - y0;
  const float* r0 = img.ptr<float>(y0);
  const float* r1 = img.ptr<float>(y0 + 1);
  *v = (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) + fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]);
  return true;
}

}  // namespace

bool EdgeContinues(const GradientImages& gradients,
                   const PixelGeometry& geometry,
                   const EmplLine& line,
                   const Eigen::Vector2d& end,
                   const Eigen::Vector2d& x,
                   double skip_px,
                   double min_strength) {
  const Eigen::Vector2d to_x = x - end;
  const double gap = to_x.norm() - skip_px;
  if (!(gap > 0) || !(line.length_px > 0)) return false;
  const Eigen::Vector2d u = to_x.normalized();
  const double sign_n = line.normal.dot(Eigen::Vector2d(-u.y(), u.x())) >= 0 ? 1.0 : -1.0;
  const double cos_max = std::cos(30.0 * 3.14159265358979323846 / 180.0);
  // The gradient along the line's normal at fit position q: the normal taken in the image (lens
  // distortion turns it), 0 when the gradient points more than 30 deg away from it.
  auto across = [&](const Eigen::Vector2d& q, double* g) {
    const Eigen::Vector2d pix = geometry.ToPixel(q);
    const Eigen::Vector2d t = geometry.ToPixel(q + 0.5 * u) - geometry.ToPixel(q - 0.5 * u);
    const Eigen::Vector2d n = sign_n * Eigen::Vector2d(-t.y(), t.x()).normalized();
    double gx, gy;
    if (!Sample(gradients.gx, pix, &gx) || !Sample(gradients.gy, pix, &gy)) return false;
    const double along = gx * n.x() + gy * n.y();
    *g = std::abs(along) >= cos_max * std::hypot(gx, gy) ? along : 0.0;
    return true;
  };
  // The edge's strength next to the end, on the segment.
  const double reach = std::min(10.0, line.length_px);
  double ref = 0;
  int n_ref = 0;
  for (double t = 0.5; t <= reach; t += 0.5) {
    double g;
    if (!across(end - t * u, &g)) continue;
    ref += line.alternating ? std::abs(g) : g;
    ++n_ref;
  }
  if (n_ref == 0) return false;
  ref /= n_ref;
  if (!(std::abs(ref) > 2 * gradients.gradient_noise)) return false;
  const double sign = ref > 0 ? 1.0 : -1.0;
  const int pieces = static_cast<int>(std::ceil(gap / 3.0));
  const double piece = gap / pieces;
  for (int k = 0; k < pieces; ++k) {
    double sum = 0;
    int count = 0;
    for (double t = k * piece; t <= (k + 1) * piece + 1e-9; t += 0.5) {
      double g;
      if (!across(end + t * u, &g)) return false;
      sum += line.alternating ? std::abs(g) : sign * g;
      ++count;
    }
    if (!(sum / count >= min_strength * std::abs(ref))) return false;
  }
  return true;
}

std::vector<IdiPoint> FindIdiPoints(
    std::vector<EmplLine>* lines_io, const IdiOptions& options, int width, int height, const GapTest& gap) {
  std::vector<EmplLine>& lines = *lines_io;
  const double min_sin = std::sin(options.min_angle_deg * 3.14159265358979323846 / 180.0);
  struct Candidate {
    Eigen::Vector2d xy;
    int a, b;
  };
  std::vector<Candidate> cand;
  const std::size_t n = lines.size();
  std::vector<double> ext(n);
  for (std::size_t i = 0; i < n; ++i) {
    ext[i] = (lines[i].extension1 - lines[i].p1).norm();
    lines[i].point_ids.clear();
  }
  // Whether line i reaches x: within its extension, or across a gap that carries its edge.
  auto reaches = [&](std::size_t i, const Eigen::Vector2d& x) {
    const double beyond = DistanceBeyondSegment(lines[i], x);
    if (beyond <= ext[i]) return true;
    if (!gap || beyond > options.max_gap_px) return false;
    const EmplLine& l = lines[i];
    return gap(l, (x - l.p1).squaredNorm() < (x - l.p2).squaredNorm() ? l.p1 : l.p2, x);
  };
  const double m = options.image_margin_px;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      const EmplLine& a = lines[i];
      const EmplLine& b = lines[j];
      const double det = a.normal.x() * b.normal.y() - a.normal.y() * b.normal.x();
      if (std::fabs(det) < min_sin) {
        continue;
      }
      const Eigen::Vector2d x((a.offset * b.normal.y() - b.offset * a.normal.y()) / det,
                              (a.normal.x() * b.offset - b.normal.x() * a.offset) / det);
      if (x.x() < -0.5 - m || x.y() < -0.5 - m || x.x() > width - 0.5 + m || x.y() > height - 0.5 + m) {
        continue;
      }
      if (!reaches(i, x) || !reaches(j, x)) {
        continue;
      }
      cand.push_back({x, static_cast<int>(i), static_cast<int>(j)});
    }
  }
  // Intersections closer than the merge radius are one point (§8.8.2 "non unique point").
  std::vector<int> parent(cand.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int x) {
    while (parent[static_cast<std::size_t>(x)] != x) {
      parent[static_cast<std::size_t>(x)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(x)])];
      x = parent[static_cast<std::size_t>(x)];
    }
    return x;
  };
  const double r2 = options.merge_radius_px * options.merge_radius_px;
  for (std::size_t i = 0; i < cand.size(); ++i) {
    for (std::size_t j = i + 1; j < cand.size(); ++j) {
      if ((cand[i].xy - cand[j].xy).squaredNorm() <= r2) {
        parent[static_cast<std::size_t>(find(static_cast<int>(i)))] = find(static_cast<int>(j));
      }
    }
  }
  std::vector<std::vector<int>> groups(cand.size());
  for (std::size_t i = 0; i < cand.size(); ++i) {
    groups[static_cast<std::size_t>(find(static_cast<int>(i)))].push_back(static_cast<int>(i));
  }
  std::vector<IdiPoint> points;
  for (const std::vector<int>& group : groups) {
    if (group.empty()) {
      continue;
    }
    std::vector<int> ids;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (int c : group) {
      ids.push_back(cand[static_cast<std::size_t>(c)].a);
      ids.push_back(cand[static_cast<std::size_t>(c)].b);
      mean += cand[static_cast<std::size_t>(c)].xy;
    }
    mean /= static_cast<double>(group.size());
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    std::vector<const EmplLine*> ls;
    for (int id : ids) {
      ls.push_back(&lines[static_cast<std::size_t>(id)]);
    }
    IdiPoint p;
    if (!IntersectLinesWeighted(ls, mean, &p.xy, &p.covariance) || !PlacedPreciselyEnough(p, options)) {
      continue;
    }
    p.line_ids = ids;  // indices into `lines` for now (ids below)
    points.push_back(std::move(p));
  }
  // A line reaches beyond each end of its confirmed segment only as far as the first point there: its
  // extension bridges the blur at the corner where the edge ends, not past that corner to the next one
  // (a long line's extension would otherwise pass near a corner a dozen pixels beyond its own).
  if (options.first_point_beyond_end) {
    std::vector<std::vector<std::size_t>> on_line(n);
    for (std::size_t k = 0; k < points.size(); ++k) {
      for (const int id : points[k].line_ids) on_line[static_cast<std::size_t>(id)].push_back(k);
    }
    std::vector<std::vector<int>> drop(points.size());
    for (std::size_t i = 0; i < n; ++i) {
      const EmplLine& l = lines[i];
      const Eigen::Vector2d d = l.p2 - l.p1;
      const double len = d.norm();
      if (len <= 0) continue;
      // How far each of the line's points lies beyond its end on `side` (negative: not beyond it).
      auto beyond = [&](std::size_t k, int side) {
        const double t = d.dot(points[k].xy - l.p1) / len;
        return side < 0 ? -t : t - len;
      };
      for (const int side : {-1, 1}) {
        std::size_t nearest = points.size();
        double nearest_beyond = std::numeric_limits<double>::infinity();
        for (const std::size_t k : on_line[i]) {
          const double b = beyond(k, side);
          if (b > 0 && b < nearest_beyond) {
            nearest_beyond = b;
            nearest = k;
          }
        }
        for (const std::size_t k : on_line[i]) {
          if (k != nearest && beyond(k, side) > 0) drop[k].push_back(static_cast<int>(i));
        }
      }
    }
    std::vector<IdiPoint> kept;
    for (std::size_t k = 0; k < points.size(); ++k) {
      IdiPoint& p = points[k];
      if (!drop[k].empty()) {
        std::vector<int> ids;
        std::vector<const EmplLine*> ls;
        for (const int id : p.line_ids) {
          if (std::find(drop[k].begin(), drop[k].end(), id) != drop[k].end()) continue;
          ids.push_back(id);
          ls.push_back(&lines[static_cast<std::size_t>(id)]);
        }
        if (ls.size() < 2 || !IntersectLinesWeighted(ls, p.xy, &p.xy, &p.covariance) ||
            !PlacedPreciselyEnough(p, options))
          continue;
        p.line_ids = ids;
      }
      kept.push_back(std::move(p));
    }
    points = std::move(kept);
  }
  for (std::size_t k = 0; k < points.size(); ++k) {
    IdiPoint& p = points[k];
    p.id = static_cast<int>(k);
    for (int& id : p.line_ids) {
      lines[static_cast<std::size_t>(id)].point_ids.push_back(p.id);
      id = lines[static_cast<std::size_t>(id)].id;
    }
  }
  // Points on each line ordered from p1 to p2.
  for (EmplLine& l : lines) {
    const Eigen::Vector2d d = l.p2 - l.p1;
    std::sort(l.point_ids.begin(), l.point_ids.end(), [&](int a, int b) {
      return d.dot(points[static_cast<std::size_t>(a)].xy - l.p1) < d.dot(points[static_cast<std::size_t>(b)].xy - l.p1);
    });
  }
  return points;
}

}  // namespace idi
