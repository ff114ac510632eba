#include "shared/sim/render/shapes.h"

#include <cmath>

namespace idi::sim {

Vec3d FaceNormal(const Solid& solid, const Face& face) {
  Vec3d n = Vec3d::Zero();
  const std::size_t k = face.vertices.size();
  for (std::size_t i = 0; i < k; ++i) {
    const Vec3d& a = solid.vertices[static_cast<std::size_t>(face.vertices[i])];
    const Vec3d& b = solid.vertices[static_cast<std::size_t>(face.vertices[(i + 1) % k])];
    n += a.cross(b);
  }
  return n.normalized();
}

namespace {

// Appends a face and orients it so its Newell normal points along `outward`.
void AddOrientedFace(Solid* s, std::vector<int> verts, const Vec3d& outward, int material) {
  Face f;
  f.vertices = std::move(verts);
  f.material = material;
  if (FaceNormal(*s, f).dot(outward) < 0) {
    std::reverse(f.vertices.begin(), f.vertices.end());
  }
  s->faces.push_back(std::move(f));
}

double SignedArea2(const std::vector<Vec2d>& p) {
  double a = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Vec2d& u = p[i];
    const Vec2d& v = p[(i + 1) % p.size()];
    a += u.x() * v.y() - v.x() * u.y();
  }
  return a;
}

}  // namespace

Solid MakeExtrusion(const std::string& name, const Rigid3d& world_from_object, const std::vector<Vec2d>& profile_xz,
                    double length, const Material& material, const std::vector<Material>& face_materials) {
  std::vector<Vec2d> prof = profile_xz;
  if (SignedArea2(prof) < 0) {
    std::reverse(prof.begin(), prof.end());
  }
  const std::size_t n = prof.size();
  Solid s;
  s.name = name;
  s.closed = true;
  const double h = length / 2;
  for (const Vec2d& q : prof) s.vertices.push_back(world_from_object * Vec3d(q.x(), h, q.y()));   // +y cap: 0..n-1
  for (const Vec2d& q : prof) s.vertices.push_back(world_from_object * Vec3d(q.x(), -h, q.y()));  // -y cap: n..2n-1
  const std::size_t face_count = n + 2;
  if (face_materials.size() == face_count) {
    s.materials = face_materials;
  } else {
    s.materials = {material};
  }
  auto mat = [&](std::size_t f) { return face_materials.size() == face_count ? static_cast<int>(f) : 0; };
  const Mat3d& r = world_from_object.rotation;
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t k1 = (k + 1) % n;
    // Counter-clockwise profile in (x, z): the outward normal of edge k is its direction turned right.
    const Vec2d d = prof[k1] - prof[k];
    const Vec3d outward = r * Vec3d(d.y(), 0, -d.x());
    AddOrientedFace(&s, {static_cast<int>(k), static_cast<int>(k1), static_cast<int>(n + k1), static_cast<int>(n + k)},
                    outward, mat(k));
  }
  std::vector<int> front, back;
  for (std::size_t k = 0; k < n; ++k) {
    front.push_back(static_cast<int>(k));
    back.push_back(static_cast<int>(n + k));
  }
  AddOrientedFace(&s, front, r * Vec3d::UnitY(), mat(n));
  AddOrientedFace(&s, back, -(r * Vec3d::UnitY()), mat(n + 1));
  return s;
}

Solid MakeBox(const std::string& name, const Rigid3d& world_from_object, const Vec3d& size, const Material& material,
              const std::vector<Material>& face_materials) {
  const double hx = size.x() / 2;
  return MakeExtrusion(name, world_from_object, {{-hx, 0}, {hx, 0}, {hx, size.z()}, {-hx, size.z()}}, size.y(),
                       material, face_materials);
}

Solid MakeTriangularPrism(const std::string& name, const Rigid3d& world_from_object, double width, double height,
                          double length, double apex_x, const Material& material,
                          const std::vector<Material>& face_materials) {
  return MakeExtrusion(name, world_from_object, {{-width / 2, 0}, {width / 2, 0}, {apex_x, height}}, length, material,
                       face_materials);
}

Solid MakeLBracket(const std::string& name, const Rigid3d& world_from_object, double width, double height,
                   double length, double thickness, const Material& material,
                   const std::vector<Material>& face_materials) {
  const double a = -width / 2, b = width / 2, t = thickness;
  return MakeExtrusion(name, world_from_object, {{a, 0}, {b, 0}, {b, t}, {a + t, t}, {a + t, height}, {a, height}},
                       length, material, face_materials);
}

Solid MakePolygon(const std::string& name, const std::vector<Vec3d>& vertices, const Material& material, int layer) {
  Solid s;
  s.name = name;
  s.closed = false;
  s.layer = layer;
  s.vertices = vertices;
  s.materials = {material};
  Face f;
  for (std::size_t i = 0; i < vertices.size(); ++i) f.vertices.push_back(static_cast<int>(i));
  s.faces.push_back(f);
  return s;
}

Solid MakeRectangle(const std::string& name, const Vec3d& center, const Vec3d& u_axis, const Vec3d& v_axis,
                    double half_u, double half_v, const Material& material) {
  Solid s = MakePolygon(name,
                        {center - half_u * u_axis - half_v * v_axis, center + half_u * u_axis - half_v * v_axis,
                         center + half_u * u_axis + half_v * v_axis, center - half_u * u_axis + half_v * v_axis},
                        material);
  s.faces[0].texture_origin = center;
  s.faces[0].texture_u = u_axis;
  s.faces[0].texture_v = v_axis;
  return s;
}

Result<Solid> MakeTapeStrip(const std::string& name, const std::vector<Vec2d>& centerline, double width, double z,
                            const Material& material) {
  const std::size_t n = centerline.size();
  if (n < 2 || !(width > 0)) {
    return InvalidArgument("tape '" + name + "': needs at least 2 points and a positive width");
  }
  std::vector<Vec2d> dir(n - 1);
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const Vec2d d = centerline[i + 1] - centerline[i];
    if (!(d.norm() > 1e-9 * width)) {
      return InvalidArgument("tape '" + name + "': points " + std::to_string(i) + " and " + std::to_string(i + 1) +
                             " coincide");
    }
    dir[i] = d.normalized();
  }
  const double hw = width / 2;
  std::vector<Vec2d> left(n), right(n);
  for (std::size_t i = 0; i < n; ++i) {
    Vec2d offset;
    if (i == 0 || i == n - 1) {
      const Vec2d d = dir[i == 0 ? 0 : n - 2];
      offset = hw * Vec2d(-d.y(), d.x());
    } else {
      const Vec2d n0(-dir[i - 1].y(), dir[i - 1].x()), n1(-dir[i].y(), dir[i].x());
      const double cos_turn = dir[i - 1].dot(dir[i]);
      if (cos_turn < std::cos(150.0 * M_PI / 180.0)) {
        return InvalidArgument("tape '" + name + "': the turn at point " + std::to_string(i) +
                               " is sharper than 150 deg");
      }
      const Vec2d m = (n0 + n1).normalized();
      offset = (hw / m.dot(n0)) * m;  // mitre: on both offset lines
    }
    left[i] = centerline[i] + offset;
    right[i] = centerline[i] - offset;
  }
  Solid s;
  s.name = name;
  s.closed = false;
  s.layer = 1;
  s.materials = {material};
  for (std::size_t i = 0; i < n; ++i) {
    s.vertices.emplace_back(left[i].x(), left[i].y(), z);   // 2i
    s.vertices.emplace_back(right[i].x(), right[i].y(), z);  // 2i + 1
  }
  for (std::size_t i = 0; i + 1 < n; ++i) {
    // Each quad must stay convex: its mitred ends must not cross along the segment.
    const double len = (centerline[i + 1] - centerline[i]).norm();
    const double l0 = (left[i] - centerline[i]).dot(dir[i]), l1 = (left[i + 1] - centerline[i]).dot(dir[i]);
    const double r0 = (right[i] - centerline[i]).dot(dir[i]), r1 = (right[i + 1] - centerline[i]).dot(dir[i]);
    if (!(l1 - l0 > 1e-9 * len) || !(r1 - r0 > 1e-9 * len)) {
      return InvalidArgument("tape '" + name + "': segment " + std::to_string(i) + " (length " + FormatNumber(len) +
                             ") is too short for the turns at its ends and the tape width");
    }
    Face f;
    const int a = static_cast<int>(2 * i);
    // Counter-clockwise seen from +z: right_i, right_i+1, left_i+1, left_i.
    f.vertices = {a + 1, a + 3, a + 2, a};
    f.texture_origin = Vec3d(centerline[0].x(), centerline[0].y(), z);
    f.texture_u = Vec3d::UnitX();
    f.texture_v = Vec3d::UnitY();
    s.faces.push_back(f);
  }
  return s;
}

}  // namespace idi::sim
