// Ground truth of a render: which straight 3D edges are seen where, their junctions, the laser spots
// and the cylinders' rims. Visibility is decided on the prepared scene, the same data the raster uses:
// a point of an edge is seen when it is in the image, no face lies in front of it, and the two sides
// of the edge differ by at least RenderOptions::truth_min_contrast_dn in the noise-free image.
#include <algorithm>
#include <cmath>
#include <map>

#include "shared/sim/render/raster_internal.h"
#include "shared/util/units.h"

namespace idi::sim::internal {
namespace {

enum class EdgeKind { kNone, kLine, kSilhouette, kRim };

struct MeshEdge {
  int a = -1, b = -1;  // vertex indices (after merging collinear chains: the chain's ends)
  EdgeKind kind = EdgeKind::kNone;
};

enum class EndReason { kVertex, kOccluded, kContrast, kBorder };

struct Interval {
  double s0 = 0, s1 = 0;  // image-space parameter along the projected segment, 0 at a, 1 at b
  EndReason r0 = EndReason::kVertex, r1 = EndReason::kVertex;
  int line_id = -1;
};

struct EdgeState {
  bool visible = false;
  EndReason why = EndReason::kBorder;  // why not visible
  double contrast_dn = 0;
};

// Front-most surface radiance at an ideal point (background where nothing is hit).
Vec3d RadianceAt(const Prepared& prep, const Vec2d& q) {
  const int front = FrontPieceAt(prep, q);
  if (front < 0) return prep.background;
  const Piece& p = prep.pieces[static_cast<std::size_t>(front)];
  return Shade(prep, prep.surfaces[static_cast<std::size_t>(p.surface)], q.x(), q.y(), 1.0);
}

// Is anything strictly in front of inverse depth w at ideal point q?
bool Occluded(const Prepared& prep, const Vec2d& q, double w, double rel_tol) {
  const int t = prep.TileOfIdeal(q);
  if (t < 0) return false;
  for (int k = prep.tile_start[static_cast<std::size_t>(t)]; k < prep.tile_start[static_cast<std::size_t>(t) + 1]; ++k) {
    const Piece& p = prep.pieces[static_cast<std::size_t>(prep.tile_items[static_cast<std::size_t>(k)])];
    if (p.Inside(q) > 1e-7 && p.InvDepth(q) > w * (1 + rel_tol)) return true;
  }
  return false;
}

class TruthBuilder {
 public:
  TruthBuilder(const Prepared& prep, const RenderOptions& options, GroundTruth* truth)
      : prep_(prep), options_(options), truth_(truth) {}

  void Run() {
    truth_->width = prep_.camera.width;
    truth_->height = prep_.camera.height;
    truth_->camera = prep_.camera;
    truth_->cam_from_world = prep_.cam_from_world;
    truth_->lines.clear();
    truth_->junctions.clear();
    truth_->spots.clear();
    truth_->curves.clear();
    for (std::size_t m = 0; m < prep_.meshes.size(); ++m) DoMesh(static_cast<int>(m));
    OcclusionJunctions();
    Spots();
  }

 private:
  // Camera-frame point of edge (a, b) at image parameter s (perspective-correct).
  static double TOfS(double s, double za, double zb) { return s * za / ((1 - s) * zb + s * za); }

  struct Segment {
    Vec3d a_cam, b_cam, a_world, b_world;
    Vec2d qa, qb;  // ideal
    double s_min = 0, s_max = 1;
  };

  // Clips a camera-frame segment to the near plane and projects it; false if nothing is left.
  bool MakeSegment(const Vec3d& aw, const Vec3d& bw, Segment* seg) const {
    Vec3d a = prep_.cam_from_world * aw, b = prep_.cam_from_world * bw;
    const double near = prep_.near_clip * 1.0001;
    if (a.z() < near && b.z() < near) return false;
    Vec3d a_w = aw, b_w = bw;
    if (a.z() < near) {
      const double t = (near - a.z()) / (b.z() - a.z());
      a = a + t * (b - a);
      a_w = aw + t * (bw - aw);
    } else if (b.z() < near) {
      const double t = (near - b.z()) / (a.z() - b.z());
      b = b + t * (a - b);
      b_w = bw + t * (aw - bw);
    }
    seg->a_cam = a;
    seg->b_cam = b;
    seg->a_world = a_w;
    seg->b_world = b_w;
    seg->qa = prep_.IdealFromCam(a);
    seg->qb = prep_.IdealFromCam(b);
    return (seg->qb - seg->qa).norm() > 1e-9;
  }

  Vec3d CamAt(const Segment& seg, double s) const {
    const double t = TOfS(s, seg.a_cam.z(), seg.b_cam.z());
    return seg.a_cam + t * (seg.b_cam - seg.a_cam);
  }
  Vec3d WorldAt(const Segment& seg, double s) const {
    const double t = TOfS(s, seg.a_cam.z(), seg.b_cam.z());
    return seg.a_world + t * (seg.b_world - seg.a_world);
  }

  EdgeState StateAt(const Segment& seg, double s) const {
    EdgeState st;
    const Vec2d q = seg.qa + s * (seg.qb - seg.qa);
    const Vec2d px = PixelFromIdeal(prep_.camera, q);
    if (!prep_.camera.InImage(px)) {
      st.why = EndReason::kBorder;
      return st;
    }
    const Vec3d p = CamAt(seg, s);
    if (Occluded(prep_, q, 1.0 / p.z(), 1e-7)) {
      st.why = EndReason::kOccluded;
      return st;
    }
    const Vec2d dir = (seg.qb - seg.qa).normalized();
    const Vec2d n(-dir.y(), dir.x());
    const double eps = 0.05;
    st.contrast_dn =
        options_.exposure_dn * (Luma(RadianceAt(prep_, q + eps * n)) - Luma(RadianceAt(prep_, q - eps * n)));
    if (std::abs(st.contrast_dn) < std::max(options_.truth_min_contrast_dn, 1e-9)) {
      st.why = EndReason::kContrast;
      return st;
    }
    st.visible = true;
    return st;
  }

  // Visible intervals of a segment (image parameter), with why each end ends.
  std::vector<Interval> VisibleIntervals(const Segment& seg) const {
    std::vector<Interval> out;
    const double len = (seg.qb - seg.qa).norm();
    const int n = std::clamp(static_cast<int>(std::ceil(len / 0.5)), 2, 40000);
    EdgeState prev = StateAt(seg, 0);
    double prev_s = 0;
    Interval cur;
    bool open = prev.visible;
    if (open) cur.s0 = 0, cur.r0 = EndReason::kVertex;
    for (int k = 1; k <= n; ++k) {
      const double s = static_cast<double>(k) / n;
      const EdgeState st = StateAt(seg, s);
      if (st.visible != prev.visible) {
        // Bisection for the transition.
        double lo = prev_s, hi = s;
        EdgeState lo_state = prev, hi_state = st;
        for (int it = 0; it < 40 && (hi - lo) * len > 1e-7; ++it) {
          const double mid = 0.5 * (lo + hi);
          const EdgeState ms = StateAt(seg, mid);
          if (ms.visible == prev.visible) {
            lo = mid;
            lo_state = ms;
          } else {
            hi = mid;
            hi_state = ms;
          }
        }
        const double at = 0.5 * (lo + hi);
        if (open) {
          cur.s1 = at;
          cur.r1 = hi_state.why;
          out.push_back(cur);
          open = false;
        } else {
          cur = Interval();
          cur.s0 = at;
          cur.r0 = lo_state.why;
          open = true;
        }
      }
      prev = st;
      prev_s = s;
    }
    if (open) {
      cur.s1 = 1;
      cur.r1 = EndReason::kVertex;
      out.push_back(cur);
    }
    // Near a vertex where edges meet at a small angle in the image, both contrast probes (0.05 px
    // either side) fall on the same face, so the edge seems to lose contrast just before its vertex.
    // An edge whose visible run loses contrast within a pixel of its vertex ends at the vertex
    // (0.05 px / 1 px is an angle of about 3 degrees).
    const double snap = len > 0 ? 1.0 / len : 0.0;
    for (Interval& iv : out) {
      if (iv.s0 > 0 && iv.s0 < snap && iv.r0 == EndReason::kContrast) iv.s0 = 0, iv.r0 = EndReason::kVertex;
      if (iv.s1 < 1 && iv.s1 > 1 - snap && iv.r1 == EndReason::kContrast) iv.s1 = 1, iv.r1 = EndReason::kVertex;
    }
    // Drop slivers shorter than half a pixel.
    std::vector<Interval> kept;
    for (const Interval& iv : out) {
      if ((iv.s1 - iv.s0) * len >= 0.5) kept.push_back(iv);
    }
    return kept;
  }

  // Classifies every edge of a mesh, merges collinear chains of line edges.
  std::vector<MeshEdge> MeshEdges(const Mesh& m) const {
    std::map<std::pair<int, int>, std::vector<int>> faces_of;
    for (std::size_t f = 0; f < m.faces.size(); ++f) {
      const auto& fv = m.faces[f];
      for (std::size_t i = 0; i < fv.size(); ++i) {
        const int a = fv[i], b = fv[(i + 1) % fv.size()];
        faces_of[{std::min(a, b), std::max(a, b)}].push_back(static_cast<int>(f));
      }
    }
    std::vector<MeshEdge> edges;
    for (const auto& [key, fs] : faces_of) {
      MeshEdge e;
      e.a = key.first;
      e.b = key.second;
      auto seen = [&](int f) { return m.face_surface[static_cast<std::size_t>(f)] >= 0; };
      auto side = [&](int f) { return f < m.cylinder_side_faces; };
      if (fs.size() == 1) {
        if (seen(fs[0])) e.kind = EdgeKind::kLine;
      } else if (fs.size() == 2) {
        const int f1 = fs[0], f2 = fs[1];
        if (!seen(f1) && !seen(f2)) continue;
        if (side(f1) && side(f2)) {
          if (seen(f1) != seen(f2)) e.kind = EdgeKind::kSilhouette;
        } else if (side(f1) != side(f2) && m.cylinder_side_faces > 0) {
          e.kind = EdgeKind::kRim;
        } else if (seen(f1) != seen(f2)) {
          e.kind = EdgeKind::kLine;
        } else {
          const Vec3d& n1 = m.face_normal_cam[static_cast<std::size_t>(f1)];
          const Vec3d& n2 = m.face_normal_cam[static_cast<std::size_t>(f2)];
          const Material* m1 = m.face_material[static_cast<std::size_t>(f1)];
          const Material* m2 = m.face_material[static_cast<std::size_t>(f2)];
          const bool same_material = m1 == m2 || (m1->albedo == m2->albedo && !m1->texture.Enabled() &&
                                                   !m2->texture.Enabled());
          if (n1.cross(n2).norm() > 1e-9 || n1.dot(n2) < 0 || !same_material) e.kind = EdgeKind::kLine;
        }
      } else {
        for (const int f : fs) {
          if (seen(f)) e.kind = EdgeKind::kLine;
        }
      }
      if (e.kind != EdgeKind::kNone) edges.push_back(e);
    }
    // Merge chains of collinear line edges through vertices where exactly two line edges meet.
    bool merged = true;
    while (merged) {
      merged = false;
      std::map<int, std::vector<std::size_t>> at;
      for (std::size_t i = 0; i < edges.size(); ++i) {
        if (edges[i].kind != EdgeKind::kLine) continue;
        at[edges[i].a].push_back(i);
        at[edges[i].b].push_back(i);
      }
      for (const auto& [v, list] : at) {
        if (list.size() != 2) continue;
        MeshEdge& e1 = edges[list[0]];
        MeshEdge& e2 = edges[list[1]];
        const int o1 = e1.a == v ? e1.b : e1.a, o2 = e2.a == v ? e2.b : e2.a;
        if (o1 == o2) continue;
        const Vec3d& pv = m.vertices_world[static_cast<std::size_t>(v)];
        const Vec3d d1 = m.vertices_world[static_cast<std::size_t>(o1)] - pv;
        const Vec3d d2 = m.vertices_world[static_cast<std::size_t>(o2)] - pv;
        if (d1.cross(d2).norm() > 1e-9 * d1.norm() * d2.norm() || d1.dot(d2) >= 0) continue;
        e1.a = o1;
        e1.b = o2;
        e2.kind = EdgeKind::kNone;
        merged = true;
        break;
      }
      if (merged) {
        edges.erase(std::remove_if(edges.begin(), edges.end(), [](const MeshEdge& e) { return e.kind == EdgeKind::kNone; }),
                    edges.end());
      }
    }
    return edges;
  }

  void DoMesh(int mesh_index) {
    const Mesh& m = prep_.meshes[static_cast<std::size_t>(mesh_index)];
    const std::vector<MeshEdge> edges = MeshEdges(m);
    // Vertex -> (line id, which end) of visible lines ending there.
    std::map<int, std::vector<std::pair<int, Vec2d>>> ends_at;
    std::map<int, bool> rim_vertex_visible;
    for (const MeshEdge& e : edges) {
      if (e.kind == EdgeKind::kRim) {
        RimEdge(m, e, &rim_vertex_visible);
        continue;
      }
      Segment seg;
      if (!MakeSegment(m.vertices_world[static_cast<std::size_t>(e.a)], m.vertices_world[static_cast<std::size_t>(e.b)],
                       &seg)) {
        continue;
      }
      const bool a_clipped = (seg.a_world - m.vertices_world[static_cast<std::size_t>(e.a)]).norm() > 0;
      const bool b_clipped = (seg.b_world - m.vertices_world[static_cast<std::size_t>(e.b)]).norm() > 0;
      const Vec2d d = (seg.qb - seg.qa).normalized();
      const Vec2d normal(-d.y(), d.x());
      for (Interval iv : VisibleIntervals(seg)) {
        TruthLine line;
        line.id = static_cast<int>(truth_->lines.size());
        line.object = m.name;
        line.kind = e.kind == EdgeKind::kSilhouette ? "silhouette" : "edge";
        if (e.kind == EdgeKind::kLine) {
          line.v1 = e.a;
          line.v2 = e.b;
        }
        line.p1_world = WorldAt(seg, iv.s0);
        line.p2_world = WorldAt(seg, iv.s1);
        line.p1_px = PixelFromIdeal(prep_.camera, seg.qa + iv.s0 * (seg.qb - seg.qa));
        line.p2_px = PixelFromIdeal(prep_.camera, seg.qa + iv.s1 * (seg.qb - seg.qa));
        line.normal = normal;
        line.offset = normal.dot(seg.qa);
        line.contrast_dn = StateAt(seg, 0.5 * (iv.s0 + iv.s1)).contrast_dn;
        line.length_px = (line.p2_px - line.p1_px).norm();
        truth_->lines.push_back(line);
        ideal_ends_.push_back({seg.qa + iv.s0 * (seg.qb - seg.qa), seg.qa + iv.s1 * (seg.qb - seg.qa)});
        iv.line_id = line.id;
        intervals_.push_back(iv);
        if (iv.s0 == 0 && iv.r0 == EndReason::kVertex && !a_clipped) ends_at[e.a].push_back({line.id, seg.qb - seg.qa});
        if (iv.s1 == 1 && iv.r1 == EndReason::kVertex && !b_clipped) ends_at[e.b].push_back({line.id, seg.qa - seg.qb});
      }
    }
    for (const auto& [v, lst] : ends_at) {
      const bool rim = rim_vertex_visible.count(v) > 0 && rim_vertex_visible[v];
      if (lst.size() < 2 && !(lst.size() == 1 && rim)) continue;
      TruthJunction j;
      j.id = static_cast<int>(truth_->junctions.size());
      j.is_vertex = true;
      j.object = m.name;
      j.vertex = v;
      j.point_world = m.vertices_world[static_cast<std::size_t>(v)];
      const Vec3d pc = prep_.cam_from_world * j.point_world;
      j.xy_px = ProjectToPixel(prep_.camera.params.data(), pc);
      std::vector<double> angles;
      for (const auto& [id, dir] : lst) {
        j.lines.push_back(id);
        angles.push_back(std::atan2(dir.y(), dir.x()));
      }
      if (lst.size() == 1) {
        j.type = "tangent";
      } else if (lst.size() == 2) {
        j.type = "L";
      } else if (lst.size() == 3) {
        std::sort(angles.begin(), angles.end());
        double max_gap = angles.front() + 2 * kPi - angles.back();
        for (std::size_t i = 1; i < angles.size(); ++i) max_gap = std::max(max_gap, angles[i] - angles[i - 1]);
        j.type = max_gap > kPi ? "arrow" : "Y";
      } else {
        j.type = "multi";
      }
      truth_->junctions.push_back(j);
    }
  }

  // A rim chord: visible runs of sample points go to the curves; records rim-vertex visibility.
  void RimEdge(const Mesh& m, const MeshEdge& e, std::map<int, bool>* rim_vertex_visible) {
    Segment seg;
    if (!MakeSegment(m.vertices_world[static_cast<std::size_t>(e.a)], m.vertices_world[static_cast<std::size_t>(e.b)],
                     &seg)) {
      return;
    }
    const double len = (seg.qb - seg.qa).norm();
    const int n = std::clamp(static_cast<int>(std::ceil(len / 2.0)), 1, 1000);
    for (int k = 0; k <= n; ++k) {
      const double s = static_cast<double>(k) / n;
      const bool vis = StateAt(seg, s).visible;
      if (k == 0) (*rim_vertex_visible)[e.a] = (*rim_vertex_visible)[e.a] || vis;
      if (k == n) (*rim_vertex_visible)[e.b] = (*rim_vertex_visible)[e.b] || vis;
      if (vis && k < n) rim_points_[m.name].push_back({e.a, PixelFromIdeal(prep_.camera, seg.qa + s * (seg.qb - seg.qa))});
    }
  }

  void OcclusionJunctions() {
    // Rims: one curve per object, points in edge order, split where they are not adjacent.
    for (auto& [name, pts] : rim_points_) {
      TruthCurve c;
      c.object = name;
      c.kind = "rim";
      for (std::size_t i = 0; i < pts.size(); ++i) {
        if (!c.points_px.empty() && (pts[i].second - c.points_px.back()).norm() > 4.0) {
          if (c.points_px.size() >= 2) truth_->curves.push_back(c);
          c.points_px.clear();
        }
        c.points_px.push_back(pts[i].second);
      }
      if (c.points_px.size() >= 2) truth_->curves.push_back(c);
    }
    // Ends of visible lines inside their edge: where an occluding (or coplanar covering) line takes
    // over, a T junction (the occluder continues on both sides) or an occlusion L.
    const std::size_t n = truth_->lines.size();
    for (std::size_t i = 0; i < n; ++i) {
      const Interval& iv = intervals_[i];
      for (int end = 0; end < 2; ++end) {
        const EndReason why = end == 0 ? iv.r0 : iv.r1;
        if (why != EndReason::kOccluded && why != EndReason::kContrast) continue;
        const Vec2d q = end == 0 ? ideal_ends_[i].first : ideal_ends_[i].second;
        int best = -1;
        double best_dist = 0.05;
        double best_t = 0, best_len = 0;
        for (std::size_t j = 0; j < n; ++j) {
          if (j == i) continue;
          const TruthLine& lj = truth_->lines[j];
          const double dist = std::abs(lj.normal.dot(q) - lj.offset);
          if (dist > best_dist) continue;
          const Vec2d a = ideal_ends_[j].first, b = ideal_ends_[j].second;
          const double len = (b - a).norm();
          if (!(len > 0)) continue;
          const double t = (q - a).dot(b - a) / len;
          if (t < -0.5 || t > len + 0.5) continue;
          best = static_cast<int>(j);
          best_dist = dist;
          best_t = t;
          best_len = len;
        }
        if (best < 0) continue;
        const TruthLine& li = truth_->lines[i];
        const TruthLine& lj = truth_->lines[static_cast<std::size_t>(best)];
        Eigen::Matrix2d a;
        a << li.normal.x(), li.normal.y(), lj.normal.x(), lj.normal.y();
        if (std::abs(a.determinant()) < 1e-9) continue;
        const Vec2d x = a.inverse() * Vec2d(li.offset, lj.offset);
        TruthJunction jn;
        jn.is_vertex = false;
        jn.type = (best_t > 0.5 && best_len - best_t > 0.5) ? "T" : "occlusion_L";
        jn.object = li.object;
        jn.point_world = end == 0 ? li.p1_world : li.p2_world;
        jn.xy_px = PixelFromIdeal(prep_.camera, x);
        jn.lines = {li.id, lj.id};
        bool duplicate = false;
        for (const TruthJunction& other : truth_->junctions) {
          if (!other.is_vertex && (other.xy_px - jn.xy_px).norm() < 0.01 && other.lines.size() == 2 &&
              std::min(other.lines[0], other.lines[1]) == std::min(li.id, lj.id) &&
              std::max(other.lines[0], other.lines[1]) == std::max(li.id, lj.id)) {
            duplicate = true;
          }
        }
        if (duplicate) continue;
        jn.id = static_cast<int>(truth_->junctions.size());
        truth_->junctions.push_back(jn);
      }
    }
  }

  void Spots() {
    const Rigid3d world_from_cam = prep_.cam_from_world.Inverse();
    for (std::size_t k = 0; k < prep_.laser_spots.size(); ++k) {
      const PreparedSpot& ls = prep_.laser_spots[k];
      const double sigma = ls.sigma;
      TruthSpot ts;
      ts.center_world = world_from_cam * ls.center;
      if (ls.center.z() > prep_.near_clip) {
        ts.xy_px = ProjectToPixel(prep_.camera.params.data(), ls.center);
        ts.sigma_px = sigma * std::max(prep_.fx, prep_.fy) / ls.center.z();
        const int front = FrontPieceAt(prep_, prep_.IdealFromCam(ls.center));
        if (front >= 0 && prep_.camera.InImage(ts.xy_px)) {
          const Vec2d q = prep_.IdealFromCam(ls.center);
          const double z_front = 1.0 / prep_.pieces[static_cast<std::size_t>(front)].InvDepth(q);
          ts.visible = std::abs(z_front - ls.center.z()) <= 3 * sigma;
          ts.centroid_px = ls.centroid_px;
        }
      }
      truth_->spots.push_back(ts);
    }
  }

  const Prepared& prep_;
  const RenderOptions& options_;
  GroundTruth* truth_;
  std::vector<Interval> intervals_;
  std::vector<std::pair<Vec2d, Vec2d>> ideal_ends_;
  std::map<std::string, std::vector<std::pair<int, Vec2d>>> rim_points_;
};

}  // namespace

void ComputeGroundTruth(const Prepared& prep, const RenderOptions& options, GroundTruth* truth) {
  TruthBuilder(prep, options, truth).Run();
}

}  // namespace idi::sim::internal
