#include "rmp/perception/tape_geometry.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "shared/util/units.h"

namespace idi::rmp {
namespace {

double Cross2(const Vec2d& a, const Vec2d& b) { return a.x() * b.y() - a.y() * b.x(); }

struct PairCandidate {
  int i, j;
  double score;
  double t0, t1;  // overlap interval along edge i's direction (from edge i's a)
};

}  // namespace

void TapeGeometryOptions::SetTapeWidth(double width_m) {
  tape_width_m = width_m;
  width_tolerance_m = std::min(width_tolerance_m, 0.5 * width_m);
}

Status TapeGeometryOptions::Check() const {
  auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  if (!positive(tape_width_m)) return InvalidArgument("perception: tape_width_m must be positive");
  if (!positive(width_tolerance_m) || width_tolerance_m >= tape_width_m) {
    return InvalidArgument("perception: width_tolerance_m must be positive and below tape_width_m");
  }
  if (!(max_edge_angle_deg > 0 && max_edge_angle_deg < 45)) return InvalidArgument("perception: max_edge_angle_deg must be in (0, 45)");
  if (!(min_overlap_m >= 0)) return InvalidArgument("perception: min_overlap_m must be >= 0");
  if (!positive(join_distance_m)) return InvalidArgument("perception: join_distance_m must be positive");
  if (!(max_turn_deg > 0 && max_turn_deg < 180)) return InvalidArgument("perception: max_turn_deg must be in (0, 180)");
  // Positive: at 0, exactly collinear strips went to the corner construction, whose intersection of two
  // parallel lines is 0/0 (a NaN vertex, and the piece dropped).
  if (!(collinear_deg > 0 && collinear_deg < max_turn_deg)) {
    return InvalidArgument("perception: collinear_deg must be in (0, max_turn_deg)");
  }
  if (!(min_piece_length_m >= 0)) return InvalidArgument("perception: min_piece_length_m must be >= 0");
  return Status::Ok();
}

std::vector<CentreSegment> PairTapeEdges(const std::vector<GroundEdge>& edges, const TapeGeometryOptions& o) {
  std::vector<PairCandidate> candidates;
  const double cos_max = std::cos(DegToRad(o.max_edge_angle_deg));
  for (std::size_t i = 0; i < edges.size(); ++i) {
    const Vec2d di = edges[i].b - edges[i].a;
    const double li = di.norm();
    if (li < 1e-6) continue;
    const Vec2d ui = di / li;
    const Vec2d ni(-ui.y(), ui.x());  // left of a->b
    for (std::size_t j = i + 1; j < edges.size(); ++j) {
      const Vec2d dj = edges[j].b - edges[j].a;
      const double lj = dj.norm();
      if (lj < 1e-6) continue;
      const Vec2d uj = dj / lj;
      if (std::abs(ui.dot(uj)) < cos_max) continue;
      // Separation: where edge j's ends lie across edge i's line, and vice versa.
      const double sa = (edges[j].a - edges[i].a).dot(ni), sb = (edges[j].b - edges[i].a).dot(ni);
      const double sep = 0.5 * (sa + sb);
      if (std::abs(std::abs(sep) - o.tape_width_m) > o.width_tolerance_m) continue;
      if (std::signbit(sa) != std::signbit(sb)) continue;
      // Tape polarity: each edge must have the other on its tape side.
      const int side_of_j = sep > 0 ? +1 : -1;  // j lies left (+1) or right of i
      if (edges[i].tape_side != 0 && edges[i].tape_side != side_of_j) continue;
      const Vec2d nj(-uj.y(), uj.x());
      const double sep_back = 0.5 * ((edges[i].a - edges[j].a).dot(nj) + (edges[i].b - edges[j].a).dot(nj));
      const int side_of_i = sep_back > 0 ? +1 : -1;
      if (edges[j].tape_side != 0 && edges[j].tape_side != side_of_i) continue;
      // Overlap along edge i.
      const double ta = (edges[j].a - edges[i].a).dot(ui), tb = (edges[j].b - edges[i].a).dot(ui);
      const double t0 = std::max(0.0, std::min(ta, tb)), t1 = std::min(li, std::max(ta, tb));
      if (t1 - t0 < o.min_overlap_m) continue;
      const double angle = std::acos(std::min(1.0, std::abs(ui.dot(uj))));
      const double score = std::abs(std::abs(sep) - o.tape_width_m) / o.width_tolerance_m + angle / DegToRad(o.max_edge_angle_deg) -
                           0.5 * std::min(1.0, (t1 - t0) / std::min(li, lj));
      candidates.push_back({static_cast<int>(i), static_cast<int>(j), score, t0, t1});
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const PairCandidate& x, const PairCandidate& y) { return x.score < y.score; });
  // An edge may pair several times along its length (its partner broken into pieces), never twice
  // over the same stretch.
  std::vector<std::vector<std::pair<Vec2d, Vec2d>>> used(edges.size());
  auto overlaps_used = [&](int e, const Vec2d& p, const Vec2d& q) {
    const Vec2d d = edges[static_cast<std::size_t>(e)].b - edges[static_cast<std::size_t>(e)].a;
    const Vec2d u = d.normalized();
    const Vec2d a = edges[static_cast<std::size_t>(e)].a;
    const double s0 = std::min((p - a).dot(u), (q - a).dot(u)), s1 = std::max((p - a).dot(u), (q - a).dot(u));
    for (const auto& [up, uq] : used[static_cast<std::size_t>(e)]) {
      const double r0 = std::min((up - a).dot(u), (uq - a).dot(u)), r1 = std::max((up - a).dot(u), (uq - a).dot(u));
      if (std::min(s1, r1) - std::max(s0, r0) > 0.5 * o.min_overlap_m) return true;
    }
    return false;
  };
  std::vector<CentreSegment> out;
  for (const PairCandidate& c : candidates) {
    const GroundEdge& ei = edges[static_cast<std::size_t>(c.i)];
    const GroundEdge& ej = edges[static_cast<std::size_t>(c.j)];
    // Orient j like i.
    Vec2d ja = ej.a, jb = ej.b;
    std::array<bool, 2> j_inside = ej.end_inside;
    if ((jb - ja).dot(ei.b - ei.a) < 0) {
      std::swap(ja, jb);
      std::swap(j_inside[0], j_inside[1]);
    }
    const Vec2d ui = (ei.b - ei.a).normalized(), uj = (jb - ja).normalized();
    const Vec2d u = (ui + uj).normalized();
    // The midline passes through the mean of the four ends' mid-points.
    const Vec2d centre = 0.25 * (ei.a + ei.b + ja + jb);
    auto along = [&](const Vec2d& p) { return (p - centre).dot(u); };
    // Each end of the strip: where both edges end if both are seen ending; otherwise the further one
    // (the strip runs out of the image there).
    const double ia = along(ei.a), ib = along(ei.b), jsa = along(ja), jsb = along(jb);
    const bool seen0 = ei.end_inside[0] && j_inside[0];
    const bool seen1 = ei.end_inside[1] && j_inside[1];
    const double s0 = seen0 ? 0.5 * (ia + jsa) : std::min(ia, jsa);
    const double s1 = seen1 ? 0.5 * (ib + jsb) : std::max(ib, jsb);
    if (s1 - s0 < o.min_overlap_m) continue;
    const Vec2d p0 = centre + s0 * u, p1 = centre + s1 * u;
    if (overlaps_used(c.i, ei.a + (c.t0) * ui, ei.a + c.t1 * ui) || overlaps_used(c.j, ei.a + c.t0 * ui, ei.a + c.t1 * ui)) {
      continue;
    }
    used[static_cast<std::size_t>(c.i)].emplace_back(ei.a + c.t0 * ui, ei.a + c.t1 * ui);
    used[static_cast<std::size_t>(c.j)].emplace_back(ei.a + c.t0 * ui, ei.a + c.t1 * ui);
    CentreSegment seg;
    seg.a = p0;
    seg.b = p1;
    seg.end_seen = {seen0, seen1};
    seg.edge1 = c.i;
    seg.edge2 = c.j;
    out.push_back(seg);
  }
  return out;
}

std::vector<CentreLinePiece> ChainCentreSegments(const std::vector<CentreSegment>& segs, const TapeGeometryOptions& o) {
  struct Link {
    int seg_a, end_a, seg_b, end_b;
    double score;
    Vec2d vertex;
    bool has_vertex;
  };
  auto end_point = [&](int s, int e) { return e == 0 ? segs[static_cast<std::size_t>(s)].a : segs[static_cast<std::size_t>(s)].b; };
  // Direction pointing out of segment s at end e.
  auto out_dir = [&](int s, int e) {
    const Vec2d d = (segs[static_cast<std::size_t>(s)].b - segs[static_cast<std::size_t>(s)].a).normalized();
    return e == 0 ? Vec2d(-d) : d;
  };
  const double reach = o.join_distance_m + o.tape_width_m;
  std::vector<Link> links;
  const int n = static_cast<int>(segs.size());
  for (int s = 0; s < n; ++s) {
    for (int t = s + 1; t < n; ++t) {
      for (int es = 0; es < 2; ++es) {
        for (int et = 0; et < 2; ++et) {
          const Vec2d ps = end_point(s, es), pt = end_point(t, et);
          const Vec2d ds = out_dir(s, es), dt = out_dir(t, et);
          // Travelling out of s at this end and into t at its end: turn between ds and -dt.
          const Vec2d din = -dt;
          const double turn = std::atan2(Cross2(ds, din), ds.dot(din));
          if (std::abs(turn) > DegToRad(o.max_turn_deg)) continue;
          Link l{s, es, t, et, 0.0, Vec2d::Zero(), false};
          if (std::abs(turn) < DegToRad(o.collinear_deg)) {
            // In line: the ends must face each other and be close.
            const Vec2d gap = pt - ps;
            if (gap.norm() > reach || gap.dot(ds) < -o.tape_width_m) continue;
            if (std::abs(Cross2(ds, gap)) > 0.5 * o.tape_width_m) continue;
            l.score = gap.norm();
          } else {
            // Corner: the lines' intersection lies near both ends, ahead of (or just behind) each.
            const double denom = Cross2(ds, din);
            const double a = Cross2(pt - ps, din) / denom;  // ps + a ds = X
            const Vec2d x = ps + a * ds;
            const double b = (x - pt).dot(-din);  // X = pt + b (-din): beyond t's end along its outward dir
            if (a < -reach || a > reach || b < -reach || b > reach) continue;
            if ((x - ps).norm() > reach || (x - pt).norm() > reach) continue;
            l.vertex = x;
            l.has_vertex = true;
            l.score = (x - ps).norm() + (x - pt).norm();
          }
          links.push_back(l);
        }
      }
    }
  }
  std::sort(links.begin(), links.end(), [](const Link& x, const Link& y) { return x.score < y.score; });
  // Each end links at most once; no cycles (union-find over segments).
  std::vector<std::array<int, 2>> partner(segs.size(), {-1, -1});
  std::vector<std::array<int, 2>> partner_end(segs.size(), {-1, -1});
  std::vector<std::array<int, 2>> link_of(segs.size(), {-1, -1});
  std::vector<int> root(segs.size());
  for (std::size_t i = 0; i < root.size(); ++i) root[i] = static_cast<int>(i);
  auto find = [&](int x) {
    while (root[static_cast<std::size_t>(x)] != x) x = root[static_cast<std::size_t>(x)] = root[static_cast<std::size_t>(root[static_cast<std::size_t>(x)])];
    return x;
  };
  for (std::size_t k = 0; k < links.size(); ++k) {
    const Link& l = links[k];
    auto& pa = partner[static_cast<std::size_t>(l.seg_a)][static_cast<std::size_t>(l.end_a)];
    auto& pb = partner[static_cast<std::size_t>(l.seg_b)][static_cast<std::size_t>(l.end_b)];
    if (pa >= 0 || pb >= 0) continue;
    if (find(l.seg_a) == find(l.seg_b)) continue;
    root[static_cast<std::size_t>(find(l.seg_a))] = find(l.seg_b);
    pa = l.seg_b;
    pb = l.seg_a;
    partner_end[static_cast<std::size_t>(l.seg_a)][static_cast<std::size_t>(l.end_a)] = l.end_b;
    partner_end[static_cast<std::size_t>(l.seg_b)][static_cast<std::size_t>(l.end_b)] = l.end_a;
    link_of[static_cast<std::size_t>(l.seg_a)][static_cast<std::size_t>(l.end_a)] = static_cast<int>(k);
    link_of[static_cast<std::size_t>(l.seg_b)][static_cast<std::size_t>(l.end_b)] = static_cast<int>(k);
  }
  // Walk each chain from a free end.
  std::vector<char> visited(segs.size(), 0);
  std::vector<CentreLinePiece> pieces;
  for (int s0 = 0; s0 < n; ++s0) {
    if (visited[static_cast<std::size_t>(s0)]) continue;
    int start_end = -1;
    for (int e = 0; e < 2; ++e) {
      if (partner[static_cast<std::size_t>(s0)][static_cast<std::size_t>(e)] < 0) start_end = e;
    }
    if (start_end < 0) continue;  // inside a chain; reached from its free end
    CentreLinePiece piece;
    int s = s0, e = start_end;
    piece.points_m.push_back(end_point(s, e));
    piece.end_seen[0] = segs[static_cast<std::size_t>(s)].end_seen[static_cast<std::size_t>(e)];
    while (true) {
      visited[static_cast<std::size_t>(s)] = 1;
      const int other = 1 - e;
      const int next = partner[static_cast<std::size_t>(s)][static_cast<std::size_t>(other)];
      if (next < 0) {
        piece.points_m.push_back(end_point(s, other));
        piece.end_seen[1] = segs[static_cast<std::size_t>(s)].end_seen[static_cast<std::size_t>(other)];
        break;
      }
      const Link& l = links[static_cast<std::size_t>(link_of[static_cast<std::size_t>(s)][static_cast<std::size_t>(other)])];
      if (l.has_vertex) {
        piece.points_m.push_back(l.vertex);
      } else {
        piece.points_m.push_back(0.5 * (end_point(s, other) + end_point(next, partner_end[static_cast<std::size_t>(s)][static_cast<std::size_t>(other)])));
      }
      e = partner_end[static_cast<std::size_t>(s)][static_cast<std::size_t>(other)];
      s = next;
    }
    double len = 0.0;
    for (std::size_t k = 1; k < piece.points_m.size(); ++k) len += (piece.points_m[k] - piece.points_m[k - 1]).norm();
    if (len >= o.min_piece_length_m) pieces.push_back(std::move(piece));
  }
  return pieces;
}

}  // namespace idi::rmp
