// Preparing a scene for one camera: tessellation, back-face culling, convex pieces in ideal pixel
// coordinates, lighting in the camera frame, and binning of pieces into tiles.
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <list>
#include <map>
#include <mutex>

#include "shared/sim/render/raster_internal.h"
#include "shared/util/units.h"

namespace idi::sim::internal {

double Piece::Inside(const Vec2d& p) const {
  double m = 1e300;
  for (int i = 0; i < n; ++i) {
    const Vec3d& h = e[static_cast<std::size_t>(i)];
    m = std::min(m, h.x() * p.x() + h.y() * p.y() + h.z());
  }
  return m;
}

// ---------------------------------------------------------------------------------------------------
// Lens distortion: the forward model is the camera's (Distort, pinhole.h); the inverse is Newton's
// method with the analytic Jacobian of that polynomial.

namespace {

void DistortWithJacobian(const double* p, double x, double y, Vec2d* out, Eigen::Matrix2d* jac) {
  const double r2 = x * x + y * y;
  const double radial = 1 + r2 * (p[kK1] + r2 * (p[kK2] + r2 * p[kK3]));
  const double dradial_dr2 = p[kK1] + r2 * (2 * p[kK2] + 3 * r2 * p[kK3]);
  *out = Vec2d(x * radial + 2 * p[kP1] * x * y + p[kP2] * (r2 + 2 * x * x),
               y * radial + p[kP1] * (r2 + 2 * y * y) + 2 * p[kP2] * x * y);
  (*jac)(0, 0) = radial + 2 * x * x * dradial_dr2 + 2 * p[kP1] * y + 6 * p[kP2] * x;
  (*jac)(0, 1) = 2 * x * y * dradial_dr2 + 2 * p[kP1] * x + 2 * p[kP2] * y;
  (*jac)(1, 0) = 2 * x * y * dradial_dr2 + 2 * p[kP1] * x + 2 * p[kP2] * y;
  (*jac)(1, 1) = radial + 2 * y * y * dradial_dr2 + 6 * p[kP1] * y + 2 * p[kP2] * x;
}

}  // namespace

Vec2d IdealFromPixel(const CameraModel& camera, const Vec2d& pixel, const Vec2d* ideal_guess) {
  if (!camera.HasDistortion()) return pixel;
  const double* p = camera.params.data();
  const Vec2d xd((pixel.x() - p[kCx]) / p[kFx], (pixel.y() - p[kCy]) / p[kFy]);
  Vec2d xn = xd;
  if (ideal_guess != nullptr) {
    xn = Vec2d((ideal_guess->x() - p[kCx]) / p[kFx], (ideal_guess->y() - p[kCy]) / p[kFy]);
  }
  for (int iter = 0; iter < 30; ++iter) {
    Vec2d f;
    Eigen::Matrix2d j;
    DistortWithJacobian(p, xn.x(), xn.y(), &f, &j);
    const Vec2d r = f - xd;
    const Vec2d step = j.inverse() * r;
    xn -= step;
    if (step.squaredNorm() < 1e-30) break;
  }
  return Vec2d(p[kFx] * xn.x() + p[kCx], p[kFy] * xn.y() + p[kCy]);
}

Vec2d PixelFromIdeal(const CameraModel& camera, const Vec2d& ideal) {
  if (!camera.HasDistortion()) return ideal;
  const double* p = camera.params.data();
  const Vec3d ray((ideal.x() - p[kCx]) / p[kFx], (ideal.y() - p[kCy]) / p[kFy], 1.0);
  return ProjectToPixel(p, ray);
}

// ---------------------------------------------------------------------------------------------------
// Pixel grids (cached).

namespace {

struct GridCacheEntry {
  CameraModel camera;
  int margin = 0;
  std::shared_ptr<const PixelGrid> grid;
};

bool SameCamera(const CameraModel& a, const CameraModel& b) {
  return a.width == b.width && a.height == b.height && a.params == b.params;
}

std::shared_ptr<const PixelGrid> BuildPixelGrid(const CameraModel& camera, int margin) {
  auto grid = std::make_shared<PixelGrid>();
  grid->x0 = -margin;
  grid->y0 = -margin;
  grid->cols = camera.width + 2 * margin;
  grid->rows = camera.height + 2 * margin;
  grid->distorted = camera.HasDistortion();
  if (grid->distorted) {
    const int w = grid->cols + 1, h = grid->rows + 1;
    grid->corners.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
    for (int j = 0; j < h; ++j) {
      Vec2d guess(grid->x0 - 0.5, grid->y0 + j - 0.5);
      bool have_guess = false;
      for (int i = 0; i < w; ++i) {
        const Vec2d px(grid->x0 + i - 0.5, grid->y0 + j - 0.5);
        const Vec2d ideal = IdealFromPixel(camera, px, have_guess ? &guess : nullptr);
        grid->corners[static_cast<std::size_t>(j) * static_cast<std::size_t>(w) + static_cast<std::size_t>(i)] = ideal;
        guess = ideal + Vec2d(1, 0);
        have_guess = true;
      }
    }
    grid->centers.resize(static_cast<std::size_t>(grid->cols) * static_cast<std::size_t>(grid->rows));
    grid->footprints.resize(grid->centers.size());
    for (int j = 0; j < grid->rows; ++j) {
      for (int i = 0; i < grid->cols; ++i) {
        const Vec2d q[4] = {grid->Corner(i, j), grid->Corner(i + 1, j), grid->Corner(i + 1, j + 1), grid->Corner(i, j + 1)};
        const std::size_t k = static_cast<std::size_t>(j) * static_cast<std::size_t>(grid->cols) + static_cast<std::size_t>(i);
        grid->centers[k] = (q[0] + q[1] + q[2] + q[3]) / 4;
        const Vec2d d1 = q[2] - q[0], d2 = q[3] - q[1];
        grid->footprints[k] = std::sqrt(std::abs(d1.x() * d2.y() - d1.y() * d2.x()) / 2);
      }
    }
  }
  return grid;
}

}  // namespace

std::shared_ptr<const PixelGrid> GetPixelGrid(const CameraModel& camera, int margin_px) {
  thread_local std::list<GridCacheEntry> cache;
  for (auto it = cache.begin(); it != cache.end(); ++it) {
    if (it->margin == margin_px && SameCamera(it->camera, camera)) {
      cache.splice(cache.begin(), cache, it);
      return cache.front().grid;
    }
  }
  cache.push_front({camera, margin_px, BuildPixelGrid(camera, margin_px)});
  if (cache.size() > 4) cache.pop_back();
  return cache.front().grid;
}

// ---------------------------------------------------------------------------------------------------
// Depth order.

int FrontOrder(const Piece& a, const Piece& b, const Vec2d* points, int count) {
  int pos = 0, neg = 0;
  for (int i = 0; i < count; ++i) {
    const double wa = a.InvDepth(points[i]), wb = b.InvDepth(points[i]);
    const double tol = kDepthEps * std::max(std::abs(wa), std::abs(wb));
    const double diff = wa - wb;
    if (diff > tol) {
      ++pos;
    } else if (diff < -tol) {
      ++neg;
    }
  }
  if (pos == count) return 1;
  if (neg == count) return -1;
  if (pos == 0 && neg == 0) {  // coplanar: the upper layer, then the later face, is in front
    if (a.layer != b.layer) return a.layer > b.layer ? 1 : -1;
    return a.order > b.order ? 1 : -1;
  }
  return 0;
}

// ---------------------------------------------------------------------------------------------------
// Scene to meshes.

namespace {

Mesh MeshFromSolid(const Solid& s) {
  Mesh m;
  m.name = s.name;
  m.vertices_world = s.vertices;
  m.closed = s.closed;
  m.layer = s.layer;
  for (const Face& f : s.faces) {
    m.faces.push_back(f.vertices);
    m.face_material.push_back(&s.materials[static_cast<std::size_t>(f.material)]);
  }
  return m;
}

// A cylinder as a prism whose side vertices include the two contour generators seen from
// `camera_world`, so the rendered silhouette is the true one; elsewhere facets are fine enough that
// the polygonal rims deviate from the circles by less than `tol_px`.
Mesh MeshFromCylinder(const Cylinder& c, const Vec3d& camera_world, double focal_px, double tol_px) {
  Mesh m;
  m.name = c.name;
  m.closed = true;
  const Vec3d d = c.axis.normalized();
  const Vec3d rel = camera_world - c.base_center;
  const double axial = rel.dot(d);
  Vec3d v = rel - axial * d;
  const double h = v.norm();
  Vec3d e1;
  if (h > 1e-12 * c.radius) {
    e1 = v / h;
  } else {
    e1 = d.unitOrthogonal();
  }
  const Vec3d e2 = d.cross(e1);
  // Facet size from the rim's sagitta in pixels at the nearest distance.
  const double outside = axial < 0 ? -axial : (axial > c.height ? axial - c.height : 0.0);
  const double dist = std::max(std::hypot(std::max(h - c.radius, 0.0), outside), 1e-9 * c.radius);
  const double r_px = c.radius * focal_px / dist;
  double step = kPi / 12;
  if (r_px > tol_px) step = std::min(step, 2 * std::acos(1 - tol_px / r_px));
  step = std::max(step, 2 * kPi / 1024);
  std::vector<double> angles;
  if (h > c.radius * (1 + 1e-9)) {
    const double phi = std::acos(c.radius / h);
    const int n_front = std::max(2, static_cast<int>(std::ceil(2 * phi / step)));
    const int n_back = std::max(2, static_cast<int>(std::ceil((2 * kPi - 2 * phi) / step)));
    for (int k = 0; k < n_front; ++k) angles.push_back(-phi + 2 * phi * k / n_front);
    for (int k = 0; k < n_back; ++k) angles.push_back(phi + (2 * kPi - 2 * phi) * k / n_back);
  } else {
    const int n = std::max(24, static_cast<int>(std::ceil(2 * kPi / step)));
    for (int k = 0; k < n; ++k) angles.push_back(2 * kPi * k / n);
  }
  const int n = static_cast<int>(angles.size());
  for (const double a : angles) m.vertices_world.push_back(c.base_center + c.radius * (std::cos(a) * e1 + std::sin(a) * e2));
  for (const double a : angles) {
    m.vertices_world.push_back(c.base_center + c.radius * (std::cos(a) * e1 + std::sin(a) * e2) + c.height * d);
  }
  // Side facets, counter-clockwise seen from outside (angles increase from e1 towards e2 = d x e1).
  for (int k = 0; k < n; ++k) {
    const int k1 = (k + 1) % n;
    m.faces.push_back({k, k1, n + k1, n + k});
    m.face_material.push_back(&c.side);
  }
  m.cylinder_side_faces = n;
  std::vector<int> top, bottom;
  for (int k = 0; k < n; ++k) top.push_back(n + k);
  for (int k = n - 1; k >= 0; --k) bottom.push_back(k);
  m.faces.push_back(top);
  m.face_material.push_back(&c.top);
  m.faces.push_back(bottom);
  m.face_material.push_back(&c.bottom);
  return m;
}

// Newell normal (unnormalised).
Vec3d NewellNormal(const std::vector<Vec3d>& poly) {
  Vec3d n = Vec3d::Zero();
  for (std::size_t i = 0; i < poly.size(); ++i) n += poly[i].cross(poly[(i + 1) % poly.size()]);
  return n;
}

// A polygon whose edge i (from v[i] to v[i+1]) is flagged as a seam: an edge inside a surface that
// is drawn in several pieces (a concave face's triangles, a cylinder's facets), not a visible edge.
struct FlaggedPoly {
  std::vector<Vec3d> v;
  std::vector<char> seam;
};

// Splits a planar polygon into convex pieces of at most 8 vertices (ear clipping when concave); the
// cuts are seams.
std::vector<FlaggedPoly> ConvexPieces(const FlaggedPoly& poly, const Vec3d& normal) {
  const std::size_t n = poly.v.size();
  const Vec3d u = normal.unitOrthogonal();
  const Vec3d w = normal.cross(u);
  std::vector<Vec2d> q(n);
  for (std::size_t i = 0; i < n; ++i) q[i] = Vec2d(u.dot(poly.v[i]), w.dot(poly.v[i]));
  auto cross = [&](std::size_t a, std::size_t b, std::size_t c) {
    const Vec2d ab = q[b] - q[a], bc = q[c] - q[b];
    return ab.x() * bc.y() - ab.y() * bc.x();
  };
  double area = 0, scale = 0;
  for (std::size_t i = 0; i < n; ++i) {
    area += q[i].x() * q[(i + 1) % n].y() - q[(i + 1) % n].x() * q[i].y();
    scale = std::max(scale, (q[(i + 1) % n] - q[i]).squaredNorm());
  }
  const double sign = area >= 0 ? 1.0 : -1.0;
  bool convex = true;
  for (std::size_t i = 0; i < n && convex; ++i) {
    if (sign * cross((i + n - 1) % n, i, (i + 1) % n) < -1e-12 * scale) convex = false;
  }
  // The flag of the edge from original vertex a to original vertex b: an original edge keeps its own,
  // a diagonal is a seam.
  auto flag = [&](std::size_t a, std::size_t b) -> char { return b == (a + 1) % n ? poly.seam[a] : 1; };
  std::vector<FlaggedPoly> out;
  if (convex) {
    if (n <= 8) {
      out.push_back(poly);
      return out;
    }
    // Balanced split along chords (no hub vertex shared by every piece), down to <= 8 vertices.
    std::vector<std::vector<std::size_t>> todo = {{}};
    for (std::size_t i = 0; i < n; ++i) todo[0].push_back(i);
    while (!todo.empty()) {
      std::vector<std::size_t> idx = std::move(todo.back());
      todo.pop_back();
      const std::size_t k = idx.size();
      if (k <= 8) {
        FlaggedPoly piece;
        for (std::size_t i = 0; i < k; ++i) {
          piece.v.push_back(poly.v[idx[i]]);
          piece.seam.push_back(flag(idx[i], idx[(i + 1) % k]));
        }
        out.push_back(piece);
        continue;
      }
      const std::size_t half = k / 2;
      todo.emplace_back(idx.begin(), idx.begin() + static_cast<std::ptrdiff_t>(half) + 1);
      std::vector<std::size_t> second(idx.begin() + static_cast<std::ptrdiff_t>(half), idx.end());
      second.push_back(idx[0]);
      todo.push_back(std::move(second));
    }
    return out;
  }
  // Ear clipping.
  std::vector<std::size_t> idx(n);
  for (std::size_t i = 0; i < n; ++i) idx[i] = i;
  auto inside_tri = [&](const Vec2d& p, std::size_t a, std::size_t b, std::size_t c) {
    auto side = [&](const Vec2d& s0, const Vec2d& s1) {
      return sign * ((s1.x() - s0.x()) * (p.y() - s0.y()) - (s1.y() - s0.y()) * (p.x() - s0.x()));
    };
    return side(q[a], q[b]) > 0 && side(q[b], q[c]) > 0 && side(q[c], q[a]) > 0;
  };
  auto triangle = [&](std::size_t a, std::size_t b, std::size_t c) {
    return FlaggedPoly{{poly.v[a], poly.v[b], poly.v[c]}, {flag(a, b), flag(b, c), flag(c, a)}};
  };
  std::size_t guard = 0;
  while (idx.size() > 3 && guard++ < n * n) {
    bool clipped = false;
    for (std::size_t k = 0; k < idx.size(); ++k) {
      const std::size_t a = idx[(k + idx.size() - 1) % idx.size()], b = idx[k], c = idx[(k + 1) % idx.size()];
      if (sign * cross(a, b, c) <= 0) continue;
      bool ear = true;
      for (const std::size_t o : idx) {
        if (o != a && o != b && o != c && inside_tri(q[o], a, b, c)) {
          ear = false;
          break;
        }
      }
      if (!ear) continue;
      out.push_back(triangle(a, b, c));
      idx.erase(idx.begin() + static_cast<std::ptrdiff_t>(k));
      clipped = true;
      break;
    }
    if (!clipped) break;  // degenerate input: give up on the rest
  }
  if (idx.size() == 3) out.push_back(triangle(idx[0], idx[1], idx[2]));
  return out;
}

// Keeps the part with z >= near; the cut edge is a real boundary.
FlaggedPoly ClipNear(const FlaggedPoly& poly, double near) {
  FlaggedPoly out;
  const std::size_t n = poly.v.size();
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3d& a = poly.v[i];
    const Vec3d& b = poly.v[(i + 1) % n];
    const bool ia = a.z() >= near, ib = b.z() >= near;
    if (ia) {
      out.v.push_back(a);
      out.seam.push_back(poly.seam[i]);
    }
    if (ia != ib) {
      const double t = (near - a.z()) / (b.z() - a.z());
      Vec3d p = a + t * (b - a);
      p.z() = near;
      out.v.push_back(p);
      out.seam.push_back(ia ? 0 : poly.seam[i]);
    }
  }
  return out;
}

bool BuildPiece(const Prepared& prep, const FlaggedPoly& poly_cam, const Surface& s, int surface_index, int layer,
                int group, Piece* out) {
  if (poly_cam.v.size() < 3 || poly_cam.v.size() > static_cast<std::size_t>(kMaxPieceVerts)) return false;
  Piece p;
  std::array<char, kMaxPieceVerts> seam{};
  for (std::size_t k = 0; k < poly_cam.v.size(); ++k) {
    const Vec2d q = prep.IdealFromCam(poly_cam.v[k]);
    if (p.n > 0 && (q - p.v[static_cast<std::size_t>(p.n - 1)]).norm() <= 1e-12 * (1 + q.norm())) {
      seam[static_cast<std::size_t>(p.n - 1)] = poly_cam.seam[k];  // the zero-length edge disappears
      continue;
    }
    seam[static_cast<std::size_t>(p.n)] = poly_cam.seam[k];
    p.v[static_cast<std::size_t>(p.n++)] = q;
  }
  while (p.n >= 3 && (p.v[0] - p.v[static_cast<std::size_t>(p.n - 1)]).norm() <= 1e-12 * (1 + p.v[0].norm())) --p.n;
  if (p.n < 3) return false;
  double area = 0;
  for (int i = 0; i < p.n; ++i) {
    const Vec2d& a = p.v[static_cast<std::size_t>(i)];
    const Vec2d& b = p.v[static_cast<std::size_t>((i + 1) % p.n)];
    area += a.x() * b.y() - b.x() * a.y();
  }
  if (!(std::abs(area) > 1e-12)) return false;
  if (area < 0) {
    // Reversed order: new edge j runs along old edge n-2-j.
    std::array<char, kMaxPieceVerts> old = seam;
    std::reverse(p.v.begin(), p.v.begin() + p.n);
    for (int j = 0; j < p.n; ++j) seam[static_cast<std::size_t>(j)] = old[static_cast<std::size_t>((2 * p.n - 2 - j) % p.n)];
  }
  Vec2d centroid = Vec2d::Zero();
  for (int i = 0; i < p.n; ++i) centroid += p.v[static_cast<std::size_t>(i)];
  centroid /= p.n;
  p.xmin = p.ymin = 1e300;
  p.xmax = p.ymax = -1e300;
  p.seam_mask = 0;
  for (int i = 0; i < p.n; ++i) {
    const Vec2d& a = p.v[static_cast<std::size_t>(i)];
    const Vec2d& b = p.v[static_cast<std::size_t>((i + 1) % p.n)];
    Vec2d nrm(-(b.y() - a.y()), b.x() - a.x());
    const double len = nrm.norm();
    if (!(len > 0)) return false;
    nrm /= len;
    double c = -nrm.dot(a);
    if (nrm.dot(centroid) + c < 0) {
      nrm = -nrm;
      c = -c;
    }
    p.e[static_cast<std::size_t>(i)] = Vec3d(nrm.x(), nrm.y(), c);
    if (seam[static_cast<std::size_t>(i)] != 0) p.seam_mask |= 1u << i;
    p.xmin = std::min(p.xmin, a.x());
    p.xmax = std::max(p.xmax, a.x());
    p.ymin = std::min(p.ymin, a.y());
    p.ymax = std::max(p.ymax, a.y());
  }
  // 1/z on the plane normal . P = d along the ray (x - cx)/fx, (y - cy)/fy, 1.
  const Vec3d& nn = s.normal;
  p.w = Vec3d(nn.x() / (prep.fx * s.d), nn.y() / (prep.fy * s.d),
              (nn.z() - nn.x() * prep.cx / prep.fx - nn.y() * prep.cy / prep.fy) / s.d);
  p.surface = surface_index;
  p.layer = layer;
  p.order = surface_index;
  p.group = group;
  *out = p;
  return true;
}

double DirectIrradiance(const Prepared& prep, const Vec3d& normal) {
  double e = prep.ambient;
  for (std::size_t k = 0; k < prep.light_dirs.size(); ++k) {
    e += prep.light_intensity[k] * std::max(0.0, normal.dot(prep.light_dirs[k]));
  }
  return e;
}

// Adds the mesh's visible faces as surfaces and pieces. A cylinder's side facets form one group (a
// smooth surface: the edges between seen facets are seams); every other face is its own group.
void AddMesh(Prepared* prep, int mesh_index, const Cylinder* cylinder, int* next_group) {
  Mesh& m = prep->meshes[static_cast<std::size_t>(mesh_index)];
  const Rigid3d& t = prep->cam_from_world;
  m.vertices_cam.clear();
  for (const Vec3d& v : m.vertices_world) m.vertices_cam.push_back(t * v);
  const std::size_t nf = m.faces.size();
  m.face_surface.assign(nf, -1);
  m.face_normal_cam.assign(nf, Vec3d::Zero());
  std::vector<char> seen(nf, 0);
  std::vector<double> plane_d(nf, 0);
  for (std::size_t f = 0; f < nf; ++f) {
    std::vector<Vec3d> poly;
    for (const int vi : m.faces[f]) poly.push_back(m.vertices_cam[static_cast<std::size_t>(vi)]);
    const Vec3d raw_n = NewellNormal(poly);
    if (!(raw_n.norm() > 0)) continue;
    const Vec3d n = raw_n.normalized();
    const double d = n.dot(poly[0]);
    m.face_normal_cam[f] = n;
    plane_d[f] = d;
    double extent = 0;
    for (const Vec3d& v : poly) extent = std::max(extent, v.norm());
    if (std::abs(d) <= 1e-12 * extent) continue;  // edge-on
    if (m.closed && d > 0) continue;               // back face
    seen[f] = 1;
  }
  const int side_group = (*next_group)++;
  auto group_of = [&](std::size_t f) {
    return static_cast<int>(f) < m.cylinder_side_faces ? side_group : -1;
  };
  // Edges shared by two seen faces of the same group are seams.
  std::map<std::pair<int, int>, std::vector<std::size_t>> faces_of_edge;
  for (std::size_t f = 0; f < nf; ++f) {
    const auto& fv = m.faces[f];
    for (std::size_t i = 0; i < fv.size(); ++i) {
      const int a = fv[i], b = fv[(i + 1) % fv.size()];
      faces_of_edge[{std::min(a, b), std::max(a, b)}].push_back(f);
    }
  }
  for (std::size_t f = 0; f < nf; ++f) {
    if (!seen[f]) continue;
    Vec3d n = m.face_normal_cam[f];
    double d = plane_d[f];
    if (d > 0) {  // open surface seen from its back: flip
      n = -n;
      d = -d;
    }
    Surface s;
    s.normal = n;
    s.d = d;
    s.inv_d = 1 / d;
    const Material* mat = m.face_material[f];
    s.albedo = mat->albedo;
    if (mat->texture.Enabled()) {
      s.texture = &mat->texture;
      s.texture_plan = -1;
      for (std::size_t k = 0; k < prep->texture_plans.size(); ++k) {
        if (prep->texture_plans[k].texture == s.texture) s.texture_plan = static_cast<int>(k);
      }
      if (s.texture_plan < 0) {
        s.texture_plan = static_cast<int>(prep->texture_plans.size());
        prep->texture_plans.push_back(MakeTexturePlan(mat->texture));
      }
      // Texture frame: u along the first edge (Prepare replaces it by a solid face's explicit frame).
      const Vec3d n_world = t.rotation.transpose() * m.face_normal_cam[f];
      const Vec3d origin = m.vertices_world[static_cast<std::size_t>(m.faces[f][0])];
      const Vec3d u_axis = (m.vertices_world[static_cast<std::size_t>(m.faces[f][1])] - origin).normalized();
      const Vec3d v_axis = n_world.cross(u_axis);
      s.tex_u = t.rotation * u_axis;
      s.tex_v = t.rotation * v_axis;
      s.tex_u0 = -s.tex_u.dot(t.translation) - u_axis.dot(origin);
      s.tex_v0 = -s.tex_v.dot(t.translation) - v_axis.dot(origin);
    }
    int group = group_of(f);
    if (cylinder != nullptr && group == side_group) {
      s.cylinder = true;
      s.axis_point = t * cylinder->base_center;
      s.axis_dir = t.rotation * cylinder->axis.normalized();
    }
    if (group < 0) group = (*next_group)++;
    s.flat_irradiance = DirectIrradiance(*prep, n);
    for (std::size_t k = 0; k < prep->laser_spots.size(); ++k) {
      const PreparedSpot& ls = prep->laser_spots[k];
      if (std::abs(n.dot(ls.center) - d) < ls.reach) s.spots.push_back(static_cast<int>(k));
    }
    s.constant = s.texture == nullptr && !s.cylinder && s.spots.empty() && prep->spotlights.empty() &&
                 !prep->has_gradient;
    s.radiance = s.flat_irradiance * s.albedo;
    s.smooth = !s.cylinder && prep->spotlights.empty() && (s.texture == nullptr || !(s.texture->tile_size > 0));
    s.mesh = mesh_index;
    s.face = static_cast<int>(f);
    const int surface_index = static_cast<int>(prep->surfaces.size());
    prep->surfaces.push_back(s);
    m.face_surface[f] = surface_index;
    FlaggedPoly poly;
    const auto& fv = m.faces[f];
    for (std::size_t i = 0; i < fv.size(); ++i) {
      poly.v.push_back(m.vertices_cam[static_cast<std::size_t>(fv[i])]);
      const int a = fv[i], b = fv[(i + 1) % fv.size()];
      char seam = 0;
      for (const std::size_t g : faces_of_edge[{std::min(a, b), std::max(a, b)}]) {
        if (g != f && seen[g] && group_of(g) == group_of(f) && group_of(f) >= 0) seam = 1;
      }
      poly.seam.push_back(seam);
    }
    for (const FlaggedPoly& convex : ConvexPieces(poly, n)) {
      Piece piece;
      if (BuildPiece(*prep, ClipNear(convex, prep->near_clip), prep->surfaces.back(), surface_index, m.layer, group,
                     &piece)) {
        prep->pieces.push_back(piece);
      }
    }
  }
}

// Does convex piece p overlap the box (exact separating-axis test)? Sets *covers when p contains it.
bool OverlapsBox(const Piece& p, const std::array<double, 4>& box, bool* covers) {
  if (p.xmax < box[0] || p.xmin > box[2] || p.ymax < box[1] || p.ymin > box[3]) return false;
  bool all_in = true;
  for (int i = 0; i < p.n; ++i) {
    const Vec3d& h = p.e[static_cast<std::size_t>(i)];
    const double hi = h.x() * (h.x() > 0 ? box[2] : box[0]) + h.y() * (h.y() > 0 ? box[3] : box[1]) + h.z();
    if (hi < 0) return false;
    const double lo = h.x() * (h.x() > 0 ? box[0] : box[2]) + h.y() * (h.y() > 0 ? box[1] : box[3]) + h.z();
    if (lo < 0) all_in = false;
  }
  if (covers != nullptr) *covers = all_in;
  return true;
}

void BinPieces(Prepared* prep) {
  const PixelGrid& g = *prep->grid;
  prep->tiles_x = (g.cols + kTileSize - 1) / kTileSize;
  prep->tiles_y = (g.rows + kTileSize - 1) / kTileSize;
  const int nt = prep->tiles_x * prep->tiles_y;
  prep->tile_box.assign(static_cast<std::size_t>(nt), {0, 0, 0, 0});
  prep->tile_radius.assign(static_cast<std::size_t>(nt), 0);
  for (int ty = 0; ty < prep->tiles_y; ++ty) {
    for (int tx = 0; tx < prep->tiles_x; ++tx) {
      const int i0 = tx * kTileSize, j0 = ty * kTileSize;
      const int i1 = std::min(i0 + kTileSize, g.cols), j1 = std::min(j0 + kTileSize, g.rows);
      std::array<double, 4> b = {1e300, 1e300, -1e300, -1e300};
      double radius = 0;
      if (!g.distorted) {
        b = {g.x0 + i0 - 0.5, g.y0 + j0 - 0.5, g.x0 + i1 - 0.5, g.y0 + j1 - 0.5};
        radius = std::sqrt(0.5);
      } else {
        for (int j = j0; j <= j1; ++j) {
          for (int i = i0; i <= i1; ++i) {
            const Vec2d c = g.Corner(i, j);
            b[0] = std::min(b[0], c.x());
            b[1] = std::min(b[1], c.y());
            b[2] = std::max(b[2], c.x());
            b[3] = std::max(b[3], c.y());
          }
        }
        for (int j = j0; j < j1; ++j) {
          for (int i = i0; i < i1; ++i) {
            const Vec2d q[4] = {g.Corner(i, j), g.Corner(i + 1, j), g.Corner(i + 1, j + 1), g.Corner(i, j + 1)};
            const Vec2d c = (q[0] + q[1] + q[2] + q[3]) / 4;
            for (const Vec2d& v : q) radius = std::max(radius, (v - c).norm());
          }
        }
      }
      const std::size_t t = static_cast<std::size_t>(ty * prep->tiles_x + tx);
      prep->tile_box[t] = b;
      prep->tile_radius[t] = radius * (1 + 1e-9) + 1e-12;
    }
  }
  prep->tile_start.assign(static_cast<std::size_t>(nt) + 1, 0);
  prep->tile_items.clear();
  std::vector<std::vector<int>> per_tile(static_cast<std::size_t>(nt));
  const int sx = (prep->tiles_x + kSuperTile - 1) / kSuperTile, sy = (prep->tiles_y + kSuperTile - 1) / kSuperTile;
  std::vector<int> super_list;
  for (int sj = 0; sj < sy; ++sj) {
    for (int si = 0; si < sx; ++si) {
      const int tx0 = si * kSuperTile, ty0 = sj * kSuperTile;
      const int tx1 = std::min(tx0 + kSuperTile, prep->tiles_x), ty1 = std::min(ty0 + kSuperTile, prep->tiles_y);
      std::array<double, 4> sb = {1e300, 1e300, -1e300, -1e300};
      for (int ty = ty0; ty < ty1; ++ty) {
        for (int tx = tx0; tx < tx1; ++tx) {
          const auto& b = prep->tile_box[static_cast<std::size_t>(ty * prep->tiles_x + tx)];
          sb = {std::min(sb[0], b[0]), std::min(sb[1], b[1]), std::max(sb[2], b[2]), std::max(sb[3], b[3])};
        }
      }
      super_list.clear();
      for (std::size_t k = 0; k < prep->pieces.size(); ++k) {
        if (OverlapsBox(prep->pieces[k], sb, nullptr)) super_list.push_back(static_cast<int>(k));
      }
      for (int ty = ty0; ty < ty1; ++ty) {
        for (int tx = tx0; tx < tx1; ++tx) {
          const std::size_t t = static_cast<std::size_t>(ty * prep->tiles_x + tx);
          for (const int k : super_list) {
            if (OverlapsBox(prep->pieces[static_cast<std::size_t>(k)], prep->tile_box[t], nullptr)) {
              per_tile[t].push_back(k);
            }
          }
        }
      }
    }
  }
  for (int t = 0; t < nt; ++t) {
    prep->tile_start[static_cast<std::size_t>(t)] = static_cast<int>(prep->tile_items.size());
    const auto& lst = per_tile[static_cast<std::size_t>(t)];
    prep->tile_items.insert(prep->tile_items.end(), lst.begin(), lst.end());
  }
  prep->tile_start[static_cast<std::size_t>(nt)] = static_cast<int>(prep->tile_items.size());
}

}  // namespace

int Prepared::TileOfIdeal(const Vec2d& ideal) const {
  const Vec2d px = PixelFromIdeal(camera, ideal);
  const double fi = std::floor(px.x() + 0.5) - grid->x0, fj = std::floor(px.y() + 0.5) - grid->y0;
  if (!(fi >= 0 && fj >= 0 && fi < grid->cols && fj < grid->rows)) return -1;
  const int tx = static_cast<int>(fi) / kTileSize, ty = static_cast<int>(fj) / kTileSize;
  return ty * tiles_x + tx;
}

int FrontPieceAt(const Prepared& prep, const Vec2d& ideal) {
  const int t = prep.TileOfIdeal(ideal);
  if (t < 0) return -1;
  int best = -1;
  for (int k = prep.tile_start[static_cast<std::size_t>(t)]; k < prep.tile_start[static_cast<std::size_t>(t) + 1]; ++k) {
    const int pi = prep.tile_items[static_cast<std::size_t>(k)];
    const Piece& p = prep.pieces[static_cast<std::size_t>(pi)];
    if (p.Inside(ideal) < 0) continue;
    if (best < 0 || FrontOrder(p, prep.pieces[static_cast<std::size_t>(best)], &ideal, 1) > 0) best = pi;
  }
  return best;
}

Result<Prepared> Prepare(const Scene& scene, const CameraModel& camera, const Rigid3d& cam_from_world,
                         const RenderOptions& options, int margin_px) {
  Prepared prep;
  prep.camera = camera;
  prep.cam_from_world = cam_from_world;
  prep.fx = camera.fx();
  prep.fy = camera.fy();
  prep.inv_fx = 1 / prep.fx;
  prep.inv_fy = 1 / prep.fy;
  prep.cx = camera.cx();
  prep.cy = camera.cy();
  prep.near_clip = options.near_clip;
  prep.background = scene.background;
  // Vignetting only lowers the gain, and the PSF is a normalised positive kernel, so an error of
  // tolerance / exposure in radiance stays within the tolerance in DN.
  prep.shading_tolerance =
      options.exposure_dn > 0 ? options.shading_tolerance_dn / options.exposure_dn : options.shading_tolerance_dn;
  const Mat3d& r = cam_from_world.rotation;
  const Lighting& l = scene.lighting;
  prep.ambient = l.ambient;
  for (const DirectionalLight& d : l.directional) {
    prep.light_dirs.push_back(r * d.direction_to_light.normalized());
    prep.light_intensity.push_back(d.intensity);
  }
  for (SpotLight s : l.spotlights) {
    s.position = cam_from_world * s.position;
    s.direction = r * s.direction.normalized();
    s.cone_half_angle_rad = std::cos(s.cone_half_angle_rad);  // Shade wants the cosine
    prep.spotlights.push_back(s);
  }
  prep.gradient = l.gradient;
  prep.gradient.origin = cam_from_world * l.gradient.origin;
  prep.gradient.gradient = r * l.gradient.gradient;
  prep.has_gradient = l.gradient.gradient.squaredNorm() > 0;
  // Laser spots: which surfaces they may light.
  for (const LaserSpot& s : scene.laser_spots) {
    PreparedSpot ps;
    ps.center = cam_from_world * s.center;
    ps.sigma = s.sigma;
    ps.peak = s.peak;
    ps.color = s.color;
    ps.reach = 8 * s.sigma;
    prep.laser_spots.push_back(ps);
  }

  const Vec3d camera_world = cam_from_world.Inverse().translation;
  for (const Solid& s : scene.solids) {
    prep.meshes.push_back(MeshFromSolid(s));
  }
  for (const Cylinder& c : scene.cylinders) {
    prep.meshes.push_back(MeshFromCylinder(c, camera_world, std::max(prep.fx, prep.fy), 0.01));
  }
  const std::size_t n_solids = scene.solids.size();
  int next_group = 0;
  for (std::size_t i = 0; i < prep.meshes.size(); ++i) {
    const Cylinder* cyl = i >= n_solids ? &scene.cylinders[i - n_solids] : nullptr;
    const std::size_t first_surface = prep.surfaces.size();
    AddMesh(&prep, static_cast<int>(i), cyl, &next_group);
    // Explicit texture frames of solid faces.
    if (cyl == nullptr) {
      const Solid& s = scene.solids[i];
      for (std::size_t si = first_surface; si < prep.surfaces.size(); ++si) {
        Surface& surf = prep.surfaces[si];
        const Face& f = s.faces[static_cast<std::size_t>(surf.face)];
        if (surf.texture != nullptr && (f.texture_u.squaredNorm() > 0 || f.texture_v.squaredNorm() > 0)) {
          surf.tex_u = r * f.texture_u;
          surf.tex_v = r * f.texture_v;
          surf.tex_u0 = -surf.tex_u.dot(cam_from_world.translation) - f.texture_u.dot(f.texture_origin);
          surf.tex_v0 = -surf.tex_v.dot(cam_from_world.translation) - f.texture_v.dot(f.texture_origin);
        }
      }
    }
  }

  prep.grid = GetPixelGrid(camera, margin_px);
  BinPieces(&prep);
  // Laser spots: the moments of their perspective images, and the pixels of the spot layer.
  const double* cp = camera.params.data();
  for (std::size_t k = 0; k < prep.laser_spots.size(); ++k) {
    PreparedSpot& ps = prep.laser_spots[k];
    const Surface* home = nullptr;
    double best = 1e300;
    for (const Surface& surf : prep.surfaces) {
      const double dist = std::abs(surf.normal.dot(ps.center) - surf.d);
      if (dist < best && std::find(surf.spots.begin(), surf.spots.end(), static_cast<int>(k)) != surf.spots.end()) {
        best = dist;
        home = &surf;
      }
    }
    if (home == nullptr || !(ps.center.z() > prep.near_clip)) continue;  // on no seen surface
    const Vec2d centre_ideal = prep.IdealFromCam(ps.center);
    const int front = FrontPieceAt(prep, centre_ideal);
    ps.visible = front >= 0 && &prep.surfaces[static_cast<std::size_t>(prep.pieces[static_cast<std::size_t>(front)].surface)] == home;
    // Perspective image moments by Gauss-Legendre quadrature over +-6 sigma of the surface.
    const Vec3d e1 = home->normal.unitOrthogonal(), e2 = home->normal.cross(e1);
    const double h = 1e-4 * ps.sigma;
    double flux = 0;
    Vec2d m1 = Vec2d::Zero();
    Eigen::Matrix2d m2 = Eigen::Matrix2d::Zero();
    constexpr int kNodes = 24;
    const double half = 6 * ps.sigma;
    bool ok = true;
    for (int j = 0; j < kNodes && ok; ++j) {
      for (int i = 0; i < kNodes && ok; ++i) {
        const double a = half * (2 * GaussLegendreNode(kNodes, i) - 1), b = half * (2 * GaussLegendreNode(kNodes, j) - 1);
        const double w = 4 * half * half * GaussLegendreWeight(kNodes, i) * GaussLegendreWeight(kNodes, j);
        const Vec3d p = ps.center + a * e1 + b * e2;
        if (!(p.z() > prep.near_clip)) {
          ok = false;
          break;
        }
        Eigen::Matrix2d jac;
        jac.col(0) = (ProjectToPixel(cp, Vec3d(p + h * e1)) - ProjectToPixel(cp, Vec3d(p - h * e1))) / (2 * h);
        jac.col(1) = (ProjectToPixel(cp, Vec3d(p + h * e2)) - ProjectToPixel(cp, Vec3d(p - h * e2))) / (2 * h);
        const double wl = ps.peak * std::exp(-0.5 * (a * a + b * b) / (ps.sigma * ps.sigma)) * w * std::abs(jac.determinant());
        const Vec2d x = ProjectToPixel(cp, p);
        flux += wl;
        m1 += wl * x;
        m2 += wl * x * x.transpose();
      }
    }
    if (!ok || !(flux > 0)) continue;
    ps.flux = flux;
    ps.centroid_px = m1 / flux;
    ps.cov_px = m2 / flux - ps.centroid_px * ps.centroid_px.transpose();
    if (!ps.visible) continue;
    const double b2 = options.psf_sigma_px * options.psf_sigma_px;
    const Eigen::Matrix2d cov_layer = ps.cov_px + b2 * Eigen::Matrix2d::Identity();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov_layer);
    const double wide = std::sqrt(std::max(eig.eigenvalues()(1), 0.0));
    const double narrow = std::sqrt(std::max(eig.eigenvalues()(0), 0.0));
    if (!(narrow > 1e-6)) continue;  // seen edge-on
    if (options.psf_sigma_px > 0) {
      ps.image_layer = true;
      ps.inv_cov_layer = cov_layer.inverse();
      ps.amplitude = flux / (2 * kPi * std::sqrt(cov_layer.determinant()));
    }
    SpotBox box;
    const double reach = 7 * wide + 2;
    const Vec2d& px = ps.centroid_px;
    box.x0 = static_cast<int>(std::floor(px.x() - reach)) - prep.grid->x0;
    box.x1 = static_cast<int>(std::ceil(px.x() + reach)) - prep.grid->x0;
    box.y0 = static_cast<int>(std::floor(px.y() - reach)) - prep.grid->y0;
    box.y1 = static_cast<int>(std::ceil(px.y() + reach)) - prep.grid->y0;
    box.samples = std::clamp(static_cast<int>(std::ceil(4.0 / narrow)), 3, 24);
    box.spot = static_cast<int>(k);
    prep.spot_boxes.push_back(box);
  }
  return prep;
}

}  // namespace idi::sim::internal
