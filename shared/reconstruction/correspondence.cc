#include "shared/reconstruction/correspondence.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <optional>

#include "shared/reconstruction/triangulation.h"
#include "shared/util/units.h"

namespace idi {
namespace {

struct Candidate {
  int a = -1, b = -1;
  double epipolar_px = 0;
  int support = 0;
  std::vector<std::pair<int, int>> line_map;  // (line in A, line in B) assignment at this point pair
};

// Support of the line pair (la, lb) for the point pair (i, j): every other IDI point on la that has a
// candidate partner on lb counts 2 (the chain of §8.8.1); one whose epipolar line at least crosses lb
// within its extended segment counts 1 (§8.8.2: the extension stands in for a missing point). The same
// from B to A.
int LinePairSupport(const ViewFeatures& fa, const ViewFeatures& fb, const Mat3d& f, int la, int lb, int i, int j,
                    const std::vector<std::vector<char>>& is_candidate, double margin_px) {
  const ViewLine& line_a = fa.lines[static_cast<std::size_t>(la)];
  const ViewLine& line_b = fb.lines[static_cast<std::size_t>(lb)];
  int support = 0;
  for (const int i2 : line_a.points) {
    if (i2 == i) continue;
    bool strong = false;
    for (const int j2 : line_b.points) {
      if (j2 != j && is_candidate[static_cast<std::size_t>(i2)][static_cast<std::size_t>(j2)]) {
        strong = true;
        break;
      }
    }
    if (strong) {
      support += 2;
      continue;
    }
    const auto x = IntersectLines2(EpipolarLine(f, fa.points[static_cast<std::size_t>(i2)].xy), line_b.line, 1e-6);
    if (x && WithinExtendedSegment(line_b, *x, margin_px)) {
      support += 1;
    }
  }
  for (const int j2 : line_b.points) {
    if (j2 == j) continue;
    bool partnered = false;
    for (const int i2 : line_a.points) {
      if (i2 != i && is_candidate[static_cast<std::size_t>(i2)][static_cast<std::size_t>(j2)]) {
        partnered = true;
        break;
      }
    }
    if (partnered) continue;  // already counted from A's side
    const auto x =
        IntersectLines2(EpipolarLineInFirst(f, fb.points[static_cast<std::size_t>(j2)].xy), line_a.line, 1e-6);
    if (x && WithinExtendedSegment(line_a, *x, margin_px)) {
      support += 1;
    }
  }
  return support;
}

// Best one-to-one assignment of the (few) lines through point i to those through point j.
void AssignLines(const ViewFeatures& fa, const ViewFeatures& fb, const Mat3d& f,
                 const std::vector<std::vector<char>>& is_candidate, double margin_px, Candidate* c) {
  const std::vector<int>& lines_a = fa.points[static_cast<std::size_t>(c->a)].lines;
  const std::vector<int>& lines_b = fb.points[static_cast<std::size_t>(c->b)].lines;
  const std::size_t na = lines_a.size(), nb = lines_b.size();
  std::vector<std::vector<int>> s(na, std::vector<int>(nb, 0));
  for (std::size_t p = 0; p < na; ++p) {
    for (std::size_t q = 0; q < nb; ++q) {
      s[p][q] = LinePairSupport(fa, fb, f, lines_a[p], lines_b[q], c->a, c->b, is_candidate, margin_px);
    }
  }
  // Enumerate injections of the smaller side into the larger (a handful of lines per point).
  const bool a_small = na <= nb;
  const std::size_t small = a_small ? na : nb, large = a_small ? nb : na;
  std::vector<std::size_t> perm(large);
  std::iota(perm.begin(), perm.end(), 0);
  int best = -1;
  std::vector<std::pair<int, int>> best_map;
  if (large > 7) {
    // Pathological junction: fall back to greedy per line.
    std::vector<char> used(large, 0);
    best = 0;
    for (std::size_t p = 0; p < small; ++p) {
      int bv = -1;
      std::size_t bq = 0;
      for (std::size_t q = 0; q < large; ++q) {
        const int v = a_small ? s[p][q] : s[q][p];
        if (!used[q] && v > bv) {
          bv = v;
          bq = q;
        }
      }
      used[bq] = 1;
      best += std::max(bv, 0);
      best_map.emplace_back(a_small ? lines_a[p] : lines_a[bq], a_small ? lines_b[bq] : lines_b[p]);
    }
  } else {
    do {
      int total = 0;
      for (std::size_t p = 0; p < small; ++p) total += a_small ? s[p][perm[p]] : s[perm[p]][p];
      if (total > best) {
        best = total;
        best_map.clear();
        for (std::size_t p = 0; p < small; ++p) {
          best_map.emplace_back(a_small ? lines_a[p] : lines_a[perm[p]], a_small ? lines_b[perm[p]] : lines_b[p]);
        }
      }
    } while (std::next_permutation(perm.begin(), perm.end()));
  }
  c->support = std::max(best, 0);
  c->line_map = std::move(best_map);
}

bool Better(const Candidate& x, const Candidate& y) {
  if (x.support != y.support) return x.support > y.support;
  return x.epipolar_px < y.epipolar_px;
}

// Union-find over (view, index) nodes.
class Dsu {
 public:
  explicit Dsu(std::size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }
  std::size_t Find(std::size_t x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }
  void Union(std::size_t x, std::size_t y) { parent_[Find(x)] = Find(y); }

 private:
  std::vector<std::size_t> parent_;
};

struct Edge {
  Observation u, v;
  int weight = 0;
};

// Chains pairwise matches into tracks with at most one observation per view. Conflicting components
// are split by dropping their weakest edges until no view appears twice.
std::vector<std::vector<Observation>> ChainTracks(const std::vector<std::size_t>& offsets, std::size_t total,
                                                  std::vector<Edge> edges, int* conflicts) {
  auto node = [&](const Observation& o) { return offsets[static_cast<std::size_t>(o.view)] + static_cast<std::size_t>(o.index); };
  std::sort(edges.begin(), edges.end(), [](const Edge& x, const Edge& y) { return x.weight > y.weight; });
  // Kruskal-like: add edges strongest first, skipping any that would put two nodes of one view in a
  // component (those are the conflicts).
  Dsu dsu(total);
  std::vector<std::vector<int>> views_in(total);  // per root: the views present (small sets)
  std::vector<Observation> obs_of(total);
  for (std::size_t v = 0; v + 1 < offsets.size(); ++v) {
    for (std::size_t k = offsets[v]; k < offsets[v + 1]; ++k) {
      views_in[k] = {static_cast<int>(v)};
      obs_of[k] = {static_cast<int>(v), static_cast<int>(k - offsets[v])};
    }
  }
  for (const Edge& e : edges) {
    const std::size_t ru = dsu.Find(node(e.u)), rv = dsu.Find(node(e.v));
    if (ru == rv) continue;
    bool clash = false;
    for (const int a : views_in[ru]) {
      if (std::find(views_in[rv].begin(), views_in[rv].end(), a) != views_in[rv].end()) {
        clash = true;
        break;
      }
    }
    if (clash) {
      ++*conflicts;
      continue;
    }
    dsu.Union(ru, rv);
    const std::size_t root = dsu.Find(ru);
    const std::size_t other = root == ru ? rv : ru;
    views_in[root].insert(views_in[root].end(), views_in[other].begin(), views_in[other].end());
  }
  std::map<std::size_t, std::vector<Observation>> groups;
  for (std::size_t k = 0; k < total; ++k) groups[dsu.Find(k)].push_back(obs_of[k]);
  std::vector<std::vector<Observation>> tracks;
  for (auto& [root, obs] : groups) {
    if (obs.size() < 2) continue;
    std::sort(obs.begin(), obs.end(), [](const Observation& x, const Observation& y) { return x.view < y.view; });
    tracks.push_back(std::move(obs));
  }
  return tracks;
}

CameraModel Undistorted(const CameraModel& c) {
  CameraModel out = c;
  for (int k = kK1; k <= kK3; ++k) out.params[static_cast<std::size_t>(k)] = 0;
  return out;
}

}  // namespace

PairMatches MatchViewPair(const ViewFeatures& fa, const ViewFeatures& fb, const Mat3d& f,
                          const CorrespondenceOptions& options) {
  const std::size_t na = fa.points.size(), nb = fb.points.size();
  std::vector<std::vector<char>> is_candidate(na, std::vector<char>(nb, 0));
  std::vector<Candidate> candidates;
  std::vector<int> count_a(na, 0), count_b(nb, 0);
  for (std::size_t i = 0; i < na; ++i) {
    const Line2d epi_b = EpipolarLine(f, fa.points[i].xy);
    for (std::size_t j = 0; j < nb; ++j) {
      const double d_b = std::abs(epi_b.SignedDistance(fb.points[j].xy));
      const double sigma = std::hypot(fa.points[i].sigma_px, fb.points[j].sigma_px);
      const double tol = options.epipolar_tolerance_px + 3.0 * sigma;
      if (d_b > tol) continue;
      const double d_a = std::abs(EpipolarLineInFirst(f, fb.points[j].xy).SignedDistance(fa.points[i].xy));
      if (d_a > tol) continue;
      is_candidate[i][j] = 1;
      ++count_a[i];
      ++count_b[j];
      Candidate c;
      c.a = static_cast<int>(i);
      c.b = static_cast<int>(j);
      c.epipolar_px = std::max(d_a, d_b);
      candidates.push_back(c);
    }
  }
  for (Candidate& c : candidates) {
    AssignLines(fa, fb, f, is_candidate, options.segment_margin_px, &c);
  }
  // Mutually best-first, one to one.
  PairMatches out;
  std::vector<char> used_a(na, 0), used_b(nb, 0);
  std::map<std::pair<int, int>, int> line_votes;
  bool progress = true;
  while (progress) {
    progress = false;
    std::vector<int> best_of_a(na, -1), best_of_b(nb, -1);
    for (std::size_t k = 0; k < candidates.size(); ++k) {
      const Candidate& c = candidates[k];
      if (used_a[static_cast<std::size_t>(c.a)] || used_b[static_cast<std::size_t>(c.b)]) continue;
      int& ba = best_of_a[static_cast<std::size_t>(c.a)];
      if (ba < 0 || Better(c, candidates[static_cast<std::size_t>(ba)])) ba = static_cast<int>(k);
      int& bb = best_of_b[static_cast<std::size_t>(c.b)];
      if (bb < 0 || Better(c, candidates[static_cast<std::size_t>(bb)])) bb = static_cast<int>(k);
    }
    for (std::size_t i = 0; i < na; ++i) {
      const int k = best_of_a[i];
      if (k < 0) continue;
      const Candidate& c = candidates[static_cast<std::size_t>(k)];
      if (best_of_b[static_cast<std::size_t>(c.b)] != k) continue;
      const bool unique = count_a[i] == 1 && count_b[static_cast<std::size_t>(c.b)] == 1 &&
                          fa.points[i].lines.size() == fb.points[static_cast<std::size_t>(c.b)].lines.size();
      if (c.support < options.min_support && !(options.accept_unique_unsupported && unique)) continue;
      // A tie with another candidate of equal support and similar epipolar distance is ambiguous:
      // leave both for the multi-view stage rather than guess.
      bool ambiguous = false;
      for (const Candidate& o : candidates) {
        if (&o == &c || used_b[static_cast<std::size_t>(o.b)] || used_a[static_cast<std::size_t>(o.a)]) continue;
        if ((o.a == c.a || o.b == c.b) && o.support == c.support && c.support > 0 &&
            std::abs(o.epipolar_px - c.epipolar_px) < 0.05) {
          ambiguous = true;
          break;
        }
      }
      if (ambiguous) continue;
      used_a[i] = 1;
      used_b[static_cast<std::size_t>(c.b)] = 1;
      out.points.emplace_back(c.a, c.b);
      out.point_support.push_back(c.support);
      for (const auto& lm : c.line_map) line_votes[lm] += 1;
      progress = true;
    }
  }
  // Lines: most-voted pairs first, one to one.
  std::vector<std::pair<std::pair<int, int>, int>> votes(line_votes.begin(), line_votes.end());
  std::sort(votes.begin(), votes.end(), [](const auto& x, const auto& y) { return x.second > y.second; });
  std::vector<char> line_used_a(fa.lines.size(), 0), line_used_b(fb.lines.size(), 0);
  for (const auto& [pair, v] : votes) {
    if (line_used_a[static_cast<std::size_t>(pair.first)] || line_used_b[static_cast<std::size_t>(pair.second)]) continue;
    line_used_a[static_cast<std::size_t>(pair.first)] = 1;
    line_used_b[static_cast<std::size_t>(pair.second)] = 1;
    out.lines.push_back(pair);
  }
  return out;
}

Result<Correspondences> MatchViews(const std::vector<CorrespondenceView>& views, const CorrespondenceOptions& options) {
  if (!options.Check()) {
    return InvalidArgument("correspondence: invalid options");
  }
  if (views.size() < 2) {
    return InvalidArgument("correspondence: need at least two views, got " + std::to_string(views.size()));
  }
  std::vector<ProjectionMatrix34> p;
  std::vector<CameraModel> pinhole;
  for (std::size_t v = 0; v < views.size(); ++v) {
    if (views[v].features == nullptr || views[v].camera == nullptr) {
      return InvalidArgument("correspondence: view " + std::to_string(v) + " has no features or no camera");
    }
    if (!views[v].cam_from_world.rotation.allFinite() || !views[v].cam_from_world.translation.allFinite()) {
      return InvalidArgument("correspondence: view " + std::to_string(v) + " has a non-finite pose");
    }
    pinhole.push_back(Undistorted(*views[v].camera));
    p.push_back(MakeProjection(pinhole.back().K(), views[v].cam_from_world));
  }
  Correspondences out;
  std::vector<std::size_t> point_offsets{0}, line_offsets{0};
  for (const CorrespondenceView& v : views) {
    point_offsets.push_back(point_offsets.back() + v.features->points.size());
    line_offsets.push_back(line_offsets.back() + v.features->lines.size());
  }
  std::vector<Edge> point_edges, line_edges;
  for (std::size_t v = 0; v < views.size(); ++v) {
    for (std::size_t w = v + 1; w < views.size(); ++w) {
      const Vec3d cv = views[v].cam_from_world.Inverse().translation;
      const Vec3d cw = views[w].cam_from_world.Inverse().translation;
      const auto f = FundamentalFromProjections(p[v], p[w]);
      if (!f || (cv - cw).norm() < 1e-6) {
        ++out.pairs_skipped;
        continue;
      }
      ++out.pairs_matched;
      const PairMatches m = MatchViewPair(*views[v].features, *views[w].features, *f, options);
      for (std::size_t k = 0; k < m.points.size(); ++k) {
        // Agreement of the other views (the trifocal check of N views): the pair's point, triangulated,
        // must land on an IDI point of the views that see it. A match that is consistent in its pair only
        // (a pattern of corners shifted along the epipolar lines, whose topology agrees) finds none, so
        // chaining takes the agreeing edges first and the ghost's edges then conflict.
        const Vec2d xa = views[v].features->points[static_cast<std::size_t>(m.points[k].first)].xy;
        const Vec2d xb = views[w].features->points[static_cast<std::size_t>(m.points[k].second)].xy;
        int agree = 0;
        if (const auto tp = TriangulatePoint({{&pinhole[v], views[v].cam_from_world, xa},
                                              {&pinhole[w], views[w].cam_from_world, xb}},
                                             options.min_ray_angle_deg * kPi / 180.0)) {
          for (std::size_t u = 0; u < views.size(); ++u) {
            if (u == v || u == w) continue;
            const auto px = Project(pinhole[u], views[u].cam_from_world * tp->xyz);
            if (!px) continue;
            for (const ViewPoint& q : views[u].features->points) {
              if ((q.xy - *px).norm() <= options.max_reprojection_px) {
                ++agree;
                break;
              }
            }
          }
        }
        if (static_cast<int>(views.size()) >= 3 && agree < options.min_agreeing_views) continue;
        point_edges.push_back({{static_cast<int>(v), m.points[k].first}, {static_cast<int>(w), m.points[k].second},
                               1 + m.point_support[k] + 8 * agree});
      }
      for (const auto& [la, lb] : m.lines) {
        line_edges.push_back({{static_cast<int>(v), la}, {static_cast<int>(w), lb}, 1});
      }
    }
  }
  const auto raw_tracks = ChainTracks(point_offsets, point_offsets.back(), point_edges, &out.conflicts_split);
  const double min_angle = options.min_ray_angle_deg * kPi / 180.0;
  // Weighted: each IDI point by its sigma, widened by the floor; else every point alike.
  auto rays = [&](const std::vector<Observation>& obs, bool weighted) {
    std::vector<PointObservation> po;
    for (const Observation& o : obs) {
      const ViewPoint& q = views[static_cast<std::size_t>(o.view)].features->points[static_cast<std::size_t>(o.index)];
      po.push_back({&pinhole[static_cast<std::size_t>(o.view)],
                    views[static_cast<std::size_t>(o.view)].cam_from_world,
                    q.xy,
                    weighted ? std::hypot(q.sigma_px, options.track_sigma_floor_px) : 0.0});
    }
    return po;
  };
  auto triangulate = [&](const std::vector<Observation>& obs, bool weighted = false) {
    return TriangulatePoint(rays(obs, weighted), min_angle);
  };
  auto consistent = [&](const TriangulatedPoint& tri, std::size_t n) {
    return ChiSquareConsistent(tri, n, options.track_outlier_z);
  };
  std::vector<std::vector<char>> taken(views.size());
  for (std::size_t v = 0; v < views.size(); ++v) taken[v].assign(views[v].features->points.size(), 0);
  for (std::vector<Observation> obs : raw_tracks) {
    std::optional<TriangulatedPoint> tp;
    // Drop the worst observation until every reprojection is within tolerance.
    while (obs.size() >= 2) {
      tp = triangulate(obs);
      if (!tp) break;
      std::size_t worst = 0;
      double worst_err = -1;
      for (std::size_t k = 0; k < obs.size(); ++k) {
        const Observation& o = obs[k];
        const auto px = Project(pinhole[static_cast<std::size_t>(o.view)],
                                views[static_cast<std::size_t>(o.view)].cam_from_world * tp->xyz);
        const double err =
            px ? (*px - views[static_cast<std::size_t>(o.view)].features->points[static_cast<std::size_t>(o.index)].xy).norm()
               : 1e9;
        if (err > worst_err) {
          worst_err = err;
          worst = k;
        }
      }
      if (worst_err <= options.max_track_residual_px) break;
      obs.erase(obs.begin() + static_cast<long>(worst));
      ++out.observations_rejected;
      tp.reset();
    }
    if (tp && options.track_outlier_z > 0 && obs.size() >= 3) {
      // With one observation left out the rest must agree; leave out the one that makes them agree best
      // (the one with the largest residual is often a right one, when a precise wrong one pulls the point).
      std::optional<TriangulatedPoint> w = triangulate(obs, true);
      while (w && obs.size() >= 3 && !consistent(*w, obs.size())) {
        const std::optional<LeftOut> left = LeaveOneOut(rays(obs, true), min_angle);
        if (!left) break;
        obs.erase(obs.begin() + static_cast<long>(left->index));
        ++out.observations_rejected;
        w = left->rest;
      }
      if (w) tp = w;
    }
    if (!tp || obs.size() < 2) continue;
    // A two-view track is weak evidence (any two points near each other's epipolar lines triangulate
    // consistently). Reject it when the point should be visible in two or more other views and
    // nothing was detected there: it is a chance pairing of false intersections (§8.8.2).
    if (obs.size() == 2 && views.size() > 3) {
      int missing = 0;
      for (std::size_t v = 0; v < views.size(); ++v) {
        if (static_cast<int>(v) == obs[0].view || static_cast<int>(v) == obs[1].view) continue;
        const auto px = Project(pinhole[v], views[v].cam_from_world * tp->xyz);
        if (!px || !pinhole[v].InImage(*px, 10.0)) continue;
        const bool any = std::any_of(views[v].features->points.begin(), views[v].features->points.end(),
                                     [&](const ViewPoint& q) { return (q.xy - *px).norm() <= 3.0; });
        if (!any) ++missing;
      }
      if (missing >= 2) {
        out.observations_rejected += 2;
        continue;
      }
    }
    PointTrack t;
    t.observations = obs;
    t.xyz = tp->xyz;
    t.reprojection_rms_px = tp->reprojection_rms_px;
    for (const Observation& o : obs) taken[static_cast<std::size_t>(o.view)][static_cast<std::size_t>(o.index)] = 1;
    out.points.push_back(std::move(t));
  }
  // Recall: a triangulated track picks up an unmatched point in a view where it projects within
  // tolerance, if exactly one such point is there.
  for (PointTrack& t : out.points) {
    for (std::size_t v = 0; v < views.size(); ++v) {
      const bool has = std::any_of(t.observations.begin(), t.observations.end(),
                                   [&](const Observation& o) { return o.view == static_cast<int>(v); });
      if (has) continue;
      const auto px = Project(pinhole[v], views[v].cam_from_world * t.xyz);
      if (!px) continue;
      int found = -1, n_found = 0;
      for (std::size_t k = 0; k < views[v].features->points.size(); ++k) {
        if (taken[v][k]) continue;
        if ((views[v].features->points[k].xy - *px).norm() <= options.max_reprojection_px) {
          found = static_cast<int>(k);
          ++n_found;
        }
      }
      if (n_found != 1) continue;
      std::vector<Observation> with = t.observations;
      with.push_back({static_cast<int>(v), found});
      if (options.track_outlier_z > 0) {
        // Within tolerance in pixels is not enough: the point must agree with the track's own precision.
        const auto w = triangulate(with, true);
        if (!w || !consistent(*w, with.size())) continue;
      }
      t.observations = std::move(with);
      taken[v][static_cast<std::size_t>(found)] = 1;
    }
    std::sort(t.observations.begin(), t.observations.end(),
              [](const Observation& x, const Observation& y) { return x.view < y.view; });
  }
  int line_conflicts = 0;
  for (auto& obs : ChainTracks(line_offsets, line_offsets.back(), line_edges, &line_conflicts)) {
    out.lines.push_back({std::move(obs)});
  }
  return out;
}

}  // namespace idi

