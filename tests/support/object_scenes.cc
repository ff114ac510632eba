#include "tests/support/object_scenes.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

#include "shared/features/idi_points.h"
#include "shared/grasp/grasp_planner.h"
#include "shared/sim/render/shapes.h"

namespace idi::test {
namespace {
constexpr double kPi = 3.14159265358979323846;

// The solid's footprint on the table: the convex hull of its vertices' (x, y).
std::vector<Vec2d> Footprint(const sim::Solid& solid) {
  std::vector<Vec2d> p;
  for (const Vec3d& v : solid.vertices) p.emplace_back(v.x(), v.y());
  return ConvexHull2d(std::move(p));
}

// Whether two convex footprints come closer than `gap` (separating axis test on their edge normals).
bool Overlap(const std::vector<Vec2d>& a, const std::vector<Vec2d>& b, double gap) {
  for (const std::vector<Vec2d>* poly : {&a, &b}) {
    for (std::size_t i = 0; i < poly->size(); ++i) {
      const Vec2d e = (*poly)[(i + 1) % poly->size()] - (*poly)[i];
      const Vec2d n = Vec2d(e.y(), -e.x()).normalized();
      double amin = 1e18, amax = -1e18, bmin = 1e18, bmax = -1e18;
      for (const Vec2d& q : a) {
        amin = std::min(amin, n.dot(q));
        amax = std::max(amax, n.dot(q));
      }
      for (const Vec2d& q : b) {
        bmin = std::min(bmin, n.dot(q));
        bmax = std::max(bmax, n.dot(q));
      }
      if (amax + gap <= bmin || bmax + gap <= amin) return false;
    }
  }
  return true;
}

}  // namespace

sim::Scene RandomObjectScene(std::mt19937& rng, bool clutter) {
  std::uniform_real_distribution<double> u(0, 1);
  sim::Scene s;
  s.lighting.ambient = 0.35;
  s.lighting.directional = {{Vec3d(0.4, -0.3, 1.0), 0.55}, {Vec3d(-0.6, 0.5, 0.6), 0.25}};
  sim::Material table = sim::Gray(0.35);
  sim::Material wall = sim::Gray(0.55);
  if (clutter) {
    table.texture.noise_amplitude = 0.25;
    table.texture.noise_scale = 40;
    wall.texture.noise_amplitude = 0.3;
    wall.texture.noise_scale = 120;
  }
  s.solids.push_back(sim::MakeRectangle("table", Vec3d(0, 0, 0), Vec3d::UnitX(), Vec3d::UnitY(), 2000, 2000, table));
  s.solids.push_back(sim::MakeRectangle("wall", Vec3d(0, 900, 600), Vec3d::UnitX(), Vec3d::UnitZ(), 2000, 600, wall));
  const int n = 3 + static_cast<int>(u(rng) * 3);
  // Objects stand apart on the table (at least 10 mm between footprints): solids that interpenetrate
  // make edges and junctions where their faces cut each other, which no mesh edge describes, so the
  // ground truth would not have them. A placement that overlaps is drawn again (up to 100 times).
  std::vector<std::vector<Vec2d>> footprints;
  for (int k = 0; k < n; ++k) {
    const double alb = 0.5 + 0.45 * u(rng);
    const std::vector<sim::Material> faces = {sim::Gray(alb),
                                              sim::Gray(alb * 0.9),
                                              sim::Gray(alb),
                                              sim::Gray(alb * 0.8),
                                              sim::Gray(alb * 0.85),
                                              sim::Gray(alb * 0.95)};
    const int kind = static_cast<int>(u(rng) * 3);
    const Vec3d box_size(120 + 100 * u(rng), 100 + 80 * u(rng), 60 + 80 * u(rng));
    const double prism_skew = 20 * (u(rng) - 0.5);
    for (int attempt = 0; attempt < 100; ++attempt) {
      const Rigid3d pose = Translation(-350 + 700 * u(rng), -250 + 500 * u(rng), 0.0) * RotZ(u(rng) * kPi);
      sim::Solid solid;
      if (kind == 0) {
        solid = sim::MakeBox("box" + std::to_string(k), pose, box_size, sim::Gray(alb), faces);
      } else if (kind == 1) {
        solid = sim::MakeTriangularPrism("prism" + std::to_string(k), pose, 150, 90, 160, prism_skew, sim::Gray(alb));
      } else {
        solid = sim::MakeLBracket("bracket" + std::to_string(k), pose, 160, 110, 120, 25, sim::Gray(alb));
      }
      std::vector<Vec2d> footprint = Footprint(solid);
      if (std::any_of(footprints.begin(), footprints.end(), [&](const std::vector<Vec2d>& f) {
            return Overlap(f, footprint, 10.0);
          })) {
        continue;
      }
      footprints.push_back(std::move(footprint));
      s.solids.push_back(std::move(solid));
      break;
    }
  }
  return s;
}

void CornerScore::Add(const CornerScore& o) {
  total += o.total;
  found += o.found;
  points += o.points;
  spurious += o.spurious;
  miss_line_not_found += o.miss_line_not_found;
  miss_segment_short += o.miss_segment_short;
  miss_other += o.miss_other;
  nearly_collinear += o.nearly_collinear;
  nearly_collinear_missed += o.nearly_collinear_missed;
  resolvable += o.resolvable;
  resolvable_found += o.resolvable_found;
  resolvable_angled += o.resolvable_angled;
  resolvable_angled_found += o.resolvable_angled_found;
  errors_px.insert(errors_px.end(), o.errors_px.begin(), o.errors_px.end());
}

bool CountsForCorners(const sim::TruthLine& line) {
  return line.length_px >= 20 && std::fabs(line.contrast_dn) >= kVisibleContrastDn;
}

std::vector<const sim::TruthLine*> CountedLines(const sim::TruthJunction& j,
                                                const std::map<int, const sim::TruthLine*>& lines) {
  std::vector<const sim::TruthLine*> counted;
  for (int id : j.lines) {
    const auto it = lines.find(id);
    if (it != lines.end() && CountsForCorners(*it->second)) counted.push_back(it->second);
  }
  return counted;
}

bool Resolvable(const sim::TruthLine& line, const std::vector<sim::TruthLine>& all, double blur_sigma_px) {
  const double clearance = 2.0 * blur_sigma_px + 1.0;
  const Vec2d a = line.p1_px, b = line.p2_px;
  const double length = (b - a).norm();
  if (!(length >= kResolvableRunPx)) return false;
  const auto distance_to_chord = [](const Vec2d& q, const Vec2d& p1, const Vec2d& p2) {
    const Vec2d d = p2 - p1;
    const double len2 = d.squaredNorm();
    const double s = len2 > 0 ? std::clamp((q - p1).dot(d) / len2, 0.0, 1.0) : 0.0;
    return (q - (p1 + s * d)).norm();
  };
  // Samples about 1 px apart; a stretch of k clear samples in a row is (k - 1) steps long.
  const int samples = static_cast<int>(std::floor(length)) + 1;
  const double step = length / (samples - 1);
  int clear_in_row = 0, best = 0;
  for (int i = 0; i < samples; ++i) {
    const Vec2d q = a + (b - a) * (static_cast<double>(i) / (samples - 1));
    bool clear = true;
    for (const sim::TruthLine& other : all) {
      if (other.id == line.id || !(std::fabs(other.contrast_dn) >= kVisibleContrastDn)) continue;
      if (distance_to_chord(q, other.p1_px, other.p2_px) <= clearance) {
        clear = false;
        break;
      }
    }
    clear_in_row = clear ? clear_in_row + 1 : 0;
    best = std::max(best, clear_in_row);
  }
  return best > 0 && (best - 1) * step >= kResolvableRunPx;
}

double WidestCos(const std::vector<const sim::TruthLine*>& counted) {
  double widest_cos = 1;
  for (const sim::TruthLine* a : counted) {
    for (const sim::TruthLine* b : counted) widest_cos = std::min(widest_cos, std::fabs(a->normal.dot(b->normal)));
  }
  return widest_cos;
}

const EmplLine* MatchTruthLine(const FeatureResult& result, const Vec2d& normal, const Vec2d& a, const Vec2d& b) {
  const Vec2d mid = 0.5 * (a + b);
  const EmplLine* best = nullptr;
  double best_d = 2.0;
  for (const EmplLine& l : result.lines) {
    if (std::fabs(l.normal.dot(normal)) < std::cos(2 * kPi / 180)) continue;
    const double d = std::fabs(l.SignedDistance(mid));
    if (d < best_d) {
      best_d = d;
      best = &l;
    }
  }
  return best;
}

CornerScore ScoreCorners(const sim::GroundTruth& truth,
                         const FeatureResult& result,
                         const std::function<Vec2d(const Vec2d&)>& to_fit,
                         double blur_sigma_px) {
  CornerScore s;
  std::map<int, const sim::TruthLine*> lines;
  for (const sim::TruthLine& l : truth.lines) lines[l.id] = &l;
  for (const sim::TruthJunction& j : truth.junctions) {
    if (!j.is_vertex || j.type == "tangent") continue;
    // Its lines that count for a corner (visible and contrasted enough).
    const std::vector<const sim::TruthLine*> counted = CountedLines(j, lines);
    if (counted.size() < 2) continue;
    ++s.total;
    const bool nearly_collinear = WidestCos(counted) > std::cos(kNearlyCollinearDeg * kPi / 180);
    s.nearly_collinear += nearly_collinear ? 1 : 0;
    const Vec2d t = to_fit(j.xy_px);
    double bd = 2.0;
    for (const IdiPoint& p : result.points) bd = std::min(bd, (p.xy - t).norm());
    s.nearly_collinear_missed += nearly_collinear && !(bd < 2.0) ? 1 : 0;
    const auto resolvable_lines = std::count_if(counted.begin(), counted.end(), [&](const sim::TruthLine* l) {
      return Resolvable(*l, truth.lines, blur_sigma_px);
    });
    if (resolvable_lines >= 2) {
      ++s.resolvable;
      s.resolvable_found += bd < 2.0 ? 1 : 0;
      if (!nearly_collinear) {
        ++s.resolvable_angled;
        s.resolvable_angled_found += bd < 2.0 ? 1 : 0;
      }
    }
    if (bd < 2.0) {
      ++s.found;
      s.errors_px.push_back(bd);
      continue;
    }
    int matched = 0, reaching = 0;
    for (const sim::TruthLine* line : counted) {
      const sim::TruthLine& tl = *line;
      if (const EmplLine* l = MatchTruthLine(result, tl.normal, to_fit(tl.p1_px), to_fit(tl.p2_px))) {
        ++matched;
        reaching += DistanceBeyondSegment(*l, t) <= (l->extension1 - l->p1).norm() ? 1 : 0;
      }
    }
    ++(matched < 2 ? s.miss_line_not_found : reaching < 2 ? s.miss_segment_short : s.miss_other);
  }
  std::vector<Vec2d> junctions;
  for (const sim::TruthJunction& j : truth.junctions) junctions.push_back(to_fit(j.xy_px));
  for (const IdiPoint& p : result.points) {
    ++s.points;
    double bd = 1e9;
    for (const Vec2d& t : junctions) bd = std::min(bd, (p.xy - t).norm());
    s.spurious += bd > 3.0 ? 1 : 0;
  }
  return s;
}

}  // namespace idi::test
