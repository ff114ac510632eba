#include "shared/sim/cell/cell_objects.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "shared/sim/render/shapes.h"
#include "shared/util/check.h"
#include "shared/util/units.h"

namespace idi::sim {
namespace {

// The x-z profile of an extruded object (counter-clockwise), as shapes.h builds it.
std::vector<Vec2d> ExtrusionProfile(const ObjectShape& s) {
  switch (s.kind) {
    case ObjectKind::kBox:
      return {{-s.size_x / 2, 0}, {s.size_x / 2, 0}, {s.size_x / 2, s.size_z}, {-s.size_x / 2, s.size_z}};
    case ObjectKind::kTriangularPrism:
      return {{-s.size_x / 2, 0}, {s.size_x / 2, 0}, {s.apex_x, s.size_z}};
    case ObjectKind::kLBracket: {
      const double a = -s.size_x / 2, b = s.size_x / 2, t = s.thickness;
      return {{a, 0}, {b, 0}, {b, t}, {a + t, t}, {a + t, s.size_z}, {a, s.size_z}};
    }
    case ObjectKind::kCylinder:
      break;
  }
  return {};
}

// A convex prism from a convex counter-clockwise x-z profile extruded over y in [-len/2, len/2].
ConvexPart ConvexExtrusion(const std::vector<Vec2d>& profile, double length) {
  ConvexPart part;
  const double h = length / 2;
  for (const Vec2d& q : profile) part.vertices.emplace_back(q.x(), h, q.y());
  for (const Vec2d& q : profile) part.vertices.emplace_back(q.x(), -h, q.y());
  const std::size_t n = profile.size();
  const int ni = static_cast<int>(n);
  for (std::size_t k = 0; k < n; ++k) {
    const Vec2d d = profile[(k + 1) % n] - profile[k];
    const Vec3d normal = Vec3d(d.y(), 0, -d.x()).normalized();
    part.normals.push_back(normal);
    part.offsets.push_back(normal.dot(Vec3d(profile[k].x(), 0, profile[k].y())));
    const int k0 = static_cast<int>(k), k1 = static_cast<int>((k + 1) % n);
    part.faces.push_back({k0, k1, ni + k1, ni + k0});
  }
  part.normals.push_back(Vec3d::UnitY());
  part.offsets.push_back(h);
  part.normals.push_back(-Vec3d::UnitY());
  part.offsets.push_back(h);
  std::vector<int> front, back;
  for (int k = 0; k < ni; ++k) {
    front.push_back(k);
    back.push_back(ni + k);
  }
  part.faces.push_back(front);
  part.faces.push_back(back);
  return part;
}

std::vector<Material> FaceMaterials(const ObjectShape& s, std::size_t faces) {
  std::vector<Material> m;
  if (s.face_albedos.size() != faces) return m;
  for (const double a : s.face_albedos) m.push_back(Gray(a));
  return m;
}

}  // namespace

const char* ObjectKindName(ObjectKind kind) {
  switch (kind) {
    case ObjectKind::kBox:
      return "box";
    case ObjectKind::kTriangularPrism:
      return "prism";
    case ObjectKind::kLBracket:
      return "bracket";
    case ObjectKind::kCylinder:
      return "cylinder";
  }
  return "?";
}

double ConvexPart::Distance(const Vec3d& p, Vec3d* closest) const {
  // The closest point lies on a face that faces p (positive separation): the plane's foot when it falls
  // inside the face polygon, else the nearest point of the polygon's edges.
  double best = std::numeric_limits<double>::infinity();
  Vec3d best_point = p;
  bool outside = false;
  for (std::size_t k = 0; k < normals.size(); ++k) {
    const double s = normals[k].dot(p) - offsets[k];
    if (s <= 0) continue;
    outside = true;
    const std::vector<int>& f = faces[k];
    const Vec3d foot = p - s * normals[k];
    int positive = 0, negative = 0;
    double edge_best = std::numeric_limits<double>::infinity();
    Vec3d edge_point = foot;
    for (std::size_t e = 0; e < f.size(); ++e) {
      const Vec3d& a = vertices[static_cast<std::size_t>(f[e])];
      const Vec3d& b = vertices[static_cast<std::size_t>(f[(e + 1) % f.size()])];
      const double side = (b - a).cross(foot - a).dot(normals[k]);
      (side >= 0 ? positive : negative) += 1;
      const Vec3d ab = b - a;
      const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-300), 0.0, 1.0);
      const Vec3d q = a + t * ab;
      const double dq = (p - q).norm();
      if (dq < edge_best) {
        edge_best = dq;
        edge_point = q;
      }
    }
    const bool inside_face = positive == 0 || negative == 0;
    const double d = inside_face ? s : edge_best;
    if (d < best) {
      best = d;
      best_point = inside_face ? foot : edge_point;
    }
  }
  if (!outside) {
    if (closest != nullptr) *closest = p;
    return 0;
  }
  if (closest != nullptr) *closest = best_point;
  return best;
}

double ConvexPart::MaxSeparation(const Vec3d& p, int* face) const {
  double best = -1e300;
  for (std::size_t k = 0; k < normals.size(); ++k) {
    const double s = normals[k].dot(p) - offsets[k];
    if (s > best) {
      best = s;
      if (face != nullptr) *face = static_cast<int>(k);
    }
  }
  return best;
}

void AddObjectToScene(const CellObject& o, Scene* scene) {
  const ObjectShape& s = o.shape;
  switch (s.kind) {
    case ObjectKind::kBox:
      scene->solids.push_back(MakeBox(o.name, o.world_from_object, Vec3d(s.size_x, s.size_y, s.size_z), Gray(s.albedo),
                                      FaceMaterials(s, 6)));
      return;
    case ObjectKind::kTriangularPrism:
      scene->solids.push_back(MakeTriangularPrism(o.name, o.world_from_object, s.size_x, s.size_z, s.size_y, s.apex_x,
                                                  Gray(s.albedo), FaceMaterials(s, 5)));
      return;
    case ObjectKind::kLBracket:
      scene->solids.push_back(MakeLBracket(o.name, o.world_from_object, s.size_x, s.size_z, s.size_y, s.thickness,
                                           Gray(s.albedo), FaceMaterials(s, 8)));
      return;
    case ObjectKind::kCylinder: {
      Cylinder c;
      c.name = o.name;
      c.base_center = o.world_from_object.translation;
      c.axis = o.world_from_object.rotation.col(2);
      c.radius = s.radius;
      c.height = s.size_z;
      const double side = s.face_albedos.size() == 3 ? s.face_albedos[0] : s.albedo;
      c.side = Gray(side);
      c.top = Gray(s.face_albedos.size() == 3 ? s.face_albedos[1] : std::min(1.0, s.albedo + 0.15));
      c.bottom = Gray(s.face_albedos.size() == 3 ? s.face_albedos[2] : s.albedo);
      scene->cylinders.push_back(c);
      return;
    }
  }
}

std::vector<ConvexPart> ObjectParts(const ObjectShape& s) {
  switch (s.kind) {
    case ObjectKind::kBox:
    case ObjectKind::kTriangularPrism:
      return {ConvexExtrusion(ExtrusionProfile(s), s.size_y)};
    case ObjectKind::kLBracket: {
      const double a = -s.size_x / 2, b = s.size_x / 2, t = s.thickness;
      return {ConvexExtrusion({{a, 0}, {b, 0}, {b, t}, {a, t}}, s.size_y),
              ConvexExtrusion({{a, 0}, {a + t, 0}, {a + t, s.size_z}, {a, s.size_z}}, s.size_y)};
    }
    case ObjectKind::kCylinder: {
      // A regular 180-gon about z: the circumscribed polygon's faces touch the true surface, so contacts
      // and normals are exact to the facet (1 deg) and the radius to 0.015 %.
      ConvexPart part;
      constexpr int kFacets = 180;
      const double r_vertex = s.radius / std::cos(kPi / kFacets);
      // Vertex 2k (bottom) and 2k + 1 (top) at angle (k - 0.5) facets; face k spans vertices k and k + 1.
      for (int k = 0; k < kFacets; ++k) {
        const double a = 2 * kPi * (k - 0.5) / kFacets;
        part.vertices.emplace_back(r_vertex * std::cos(a), r_vertex * std::sin(a), 0.0);
        part.vertices.emplace_back(r_vertex * std::cos(a), r_vertex * std::sin(a), s.size_z);
      }
      std::vector<int> top, bottom;
      for (int k = 0; k < kFacets; ++k) {
        const double an = 2 * kPi * k / kFacets;
        part.normals.emplace_back(std::cos(an), std::sin(an), 0.0);
        part.offsets.push_back(s.radius);
        const int k1 = (k + 1) % kFacets;
        part.faces.push_back({2 * k, 2 * k1, 2 * k1 + 1, 2 * k + 1});
        bottom.push_back(2 * k);
        top.push_back(2 * k + 1);
      }
      part.normals.push_back(Vec3d::UnitZ());
      part.offsets.push_back(s.size_z);
      part.faces.push_back(top);
      part.normals.push_back(-Vec3d::UnitZ());
      part.offsets.push_back(0.0);
      part.faces.push_back(bottom);
      return {part};
    }
  }
  return {};
}

ObjectWireframe ObjectCorners(const ObjectShape& s) {
  ObjectWireframe w;
  if (s.kind == ObjectKind::kCylinder) return w;
  const std::vector<Vec2d> prof = ExtrusionProfile(s);
  const int n = static_cast<int>(prof.size());
  for (const Vec2d& q : prof) w.vertices.emplace_back(q.x(), s.size_y / 2, q.y());
  for (const Vec2d& q : prof) w.vertices.emplace_back(q.x(), -s.size_y / 2, q.y());
  for (int k = 0; k < n; ++k) {
    w.edges.emplace_back(k, (k + 1) % n);
    w.edges.emplace_back(n + k, n + (k + 1) % n);
    w.edges.emplace_back(k, n + k);
  }
  return w;
}

double ObjectHeight(const ObjectShape& s) { return s.size_z; }

double ObjectFootprintRadius(const ObjectShape& s) {
  if (s.kind == ObjectKind::kCylinder) return s.radius;
  return std::hypot(s.size_x / 2, s.size_y / 2);
}

double ObjectVolume(const ObjectShape& s) {
  switch (s.kind) {
    case ObjectKind::kBox:
      return s.size_x * s.size_y * s.size_z;
    case ObjectKind::kTriangularPrism:
      return 0.5 * s.size_x * s.size_z * s.size_y;
    case ObjectKind::kLBracket:
      return (s.size_x * s.thickness + (s.size_z - s.thickness) * s.thickness) * s.size_y;
    case ObjectKind::kCylinder:
      return kPi * s.radius * s.radius * s.size_z;
  }
  return 0;
}

Vec3d ObjectCentreOfMass(const ObjectShape& s) {
  switch (s.kind) {
    case ObjectKind::kBox:
    case ObjectKind::kCylinder:
      return Vec3d(0, 0, s.size_z / 2);
    case ObjectKind::kTriangularPrism:
      return Vec3d(s.apex_x / 3, 0, s.size_z / 3);
    case ObjectKind::kLBracket: {
      const double t = s.thickness, foot = s.size_x * t, leg = (s.size_z - t) * t;
      const Vec3d c_foot(0, 0, t / 2), c_leg(-s.size_x / 2 + t / 2, 0, t + (s.size_z - t) / 2);
      return (foot * c_foot + leg * c_leg) / (foot + leg);
    }
  }
  return Vec3d::Zero();
}

CellObject SampleObject(ObjectKind kind, const Vec3d& centre, double max_offset_mm, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto between = [&](double lo, double hi) { return lo + (hi - lo) * u(rng); };
  CellObject o;
  o.shape.kind = kind;
  o.name = ObjectKindName(kind);
  double density_g_cm3 = 0.6;  // wood
  // Faces of distinct brightness (painted faces; shading adds to the difference): evenly spread over
  // [0.45, 0.9] with a little jitter, in random order.
  auto albedos = [&](std::size_t n) {
    std::vector<double> a;
    for (std::size_t k = 0; k < n; ++k) {
      a.push_back(0.45 + 0.45 * static_cast<double>(k) / static_cast<double>(n - 1) + between(-0.01, 0.01));
    }
    std::shuffle(a.begin(), a.end(), rng);
    return a;
  };
  switch (kind) {
    case ObjectKind::kBox:
      o.shape.size_x = between(80, 140);
      o.shape.size_y = between(60, 120);
      o.shape.size_z = between(50, 100);
      o.shape.face_albedos = albedos(6);
      break;
    case ObjectKind::kTriangularPrism:
      o.shape.size_x = between(80, 130);
      o.shape.size_y = between(90, 150);
      o.shape.size_z = between(50, 90);
      o.shape.apex_x = between(-0.2, 0.2) * o.shape.size_x;
      o.shape.face_albedos = albedos(5);
      break;
    case ObjectKind::kLBracket:
      o.shape.size_x = between(80, 130);
      o.shape.size_y = between(50, 90);
      o.shape.size_z = between(60, 110);
      o.shape.thickness = between(12, 20);
      o.shape.face_albedos = albedos(8);
      density_g_cm3 = 2.7;  // aluminium
      break;
    case ObjectKind::kCylinder:
      o.shape.radius = between(30, 60);
      o.shape.size_z = between(70, 130);
      o.shape.size_x = o.shape.size_y = 2 * o.shape.radius;
      o.shape.face_albedos = {between(0.5, 0.75), between(0.8, 0.95), 0.5};
      break;
  }
  o.shape.albedo = 0.7;
  o.mass_kg = density_g_cm3 * ObjectVolume(o.shape) * 1e-6;
  const double r = max_offset_mm * std::sqrt(u(rng)), a = between(0, 2 * kPi);
  o.world_from_object = Translation(Vec3d(centre + Vec3d(r * std::cos(a), r * std::sin(a), 0.0))) * RotZ(between(-kPi, kPi));
  return o;
}

}  // namespace idi::sim
