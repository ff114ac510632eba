// Exact ray casting against the scene (world frame): where a laser beam meets a surface.
#include <cmath>

#include "shared/sim/render/render.h"
#include "shared/sim/render/shapes.h"

namespace idi::sim {
namespace {

// Even-odd point-in-polygon test in the face's plane.
bool PointInFace(const Solid& s, const Face& f, const Vec3d& n, const Vec3d& p) {
  const Vec3d u = n.unitOrthogonal();
  const Vec3d v = n.cross(u);
  const Vec2d q(u.dot(p), v.dot(p));
  bool inside = false;
  const std::size_t k = f.vertices.size();
  for (std::size_t i = 0, j = k - 1; i < k; j = i++) {
    const Vec3d& a3 = s.vertices[static_cast<std::size_t>(f.vertices[i])];
    const Vec3d& b3 = s.vertices[static_cast<std::size_t>(f.vertices[j])];
    const Vec2d a(u.dot(a3), v.dot(a3)), b(u.dot(b3), v.dot(b3));
    if ((a.y() > q.y()) != (b.y() > q.y()) && q.x() < (b.x() - a.x()) * (q.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      inside = !inside;
    }
  }
  return inside;
}

void Consider(std::optional<RayHit>* best, double t, const Vec3d& point, Vec3d normal, const Vec3d& dir,
              const std::string& object) {
  if (!(t > 0) || (best->has_value() && t >= (*best)->distance)) return;
  if (normal.dot(dir) > 0) normal = -normal;
  *best = RayHit{t, point, normal, object};
}

}  // namespace

std::optional<RayHit> CastRay(const Scene& scene, const Vec3d& origin, const Vec3d& direction) {
  if (!origin.allFinite() || !direction.allFinite() || !(direction.norm() > 0)) return std::nullopt;
  const Vec3d dir = direction.normalized();
  std::optional<RayHit> best;
  const double eps = 1e-9 * (1 + origin.norm());
  for (const Solid& s : scene.solids) {
    for (const Face& f : s.faces) {
      if (f.vertices.size() < 3) continue;
      const Vec3d n = FaceNormal(s, f);
      const double denom = n.dot(dir);
      if (std::abs(denom) < 1e-15) continue;
      const double t = n.dot(s.vertices[static_cast<std::size_t>(f.vertices[0])] - origin) / denom;
      if (!(t > eps)) continue;
      const Vec3d p = origin + t * dir;
      if (PointInFace(s, f, n, p)) Consider(&best, t, p, n, dir, s.name);
    }
  }
  for (const Cylinder& c : scene.cylinders) {
    const Vec3d a = c.axis.normalized();
    const Vec3d rel = origin - c.base_center;
    // Side: |(rel + t dir) - ((rel + t dir).a) a|^2 = r^2.
    const Vec3d dp = dir - dir.dot(a) * a, rp = rel - rel.dot(a) * a;
    const double qa = dp.squaredNorm(), qb = 2 * dp.dot(rp), qc = rp.squaredNorm() - c.radius * c.radius;
    const double disc = qb * qb - 4 * qa * qc;
    if (qa > 1e-30 && disc >= 0) {
      for (const double sgn : {-1.0, 1.0}) {
        const double t = (-qb + sgn * std::sqrt(disc)) / (2 * qa);
        if (!(t > eps)) continue;
        const Vec3d p = origin + t * dir;
        const double h = (p - c.base_center).dot(a);
        if (h < 0 || h > c.height) continue;
        const Vec3d n = ((p - c.base_center) - h * a).normalized();
        Consider(&best, t, p, n, dir, c.name);
      }
    }
    // Caps.
    const double da = dir.dot(a);
    if (std::abs(da) > 1e-15) {
      for (const double h : {0.0, c.height}) {
        const double t = (h - rel.dot(a)) / da;
        if (!(t > eps)) continue;
        const Vec3d p = origin + t * dir;
        const Vec3d off = (p - c.base_center) - h * a;
        if (off.norm() <= c.radius) Consider(&best, t, p, h == 0 ? Vec3d(-a) : a, dir, c.name);
      }
    }
  }
  return best;
}

}  // namespace idi::sim
