#include "shared/sim/render/scene.h"

#include <cmath>
#include <string>

namespace idi::sim {
namespace {

bool FiniteVec(const Vec3d& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }

std::string VecText(const Vec3d& v) {
  return "[" + FormatNumber(v.x()) + ", " + FormatNumber(v.y()) + ", " + FormatNumber(v.z()) + "]";
}

}  // namespace

Status Texture::Check() const {
  if (!std::isfinite(noise_amplitude) || noise_amplitude < 0 || noise_amplitude > 1) {
    return InvalidArgument("texture noise_amplitude must be in [0, 1], got " + FormatNumber(noise_amplitude));
  }
  if (noise_amplitude > 0 && !(noise_scale > 0 && std::isfinite(noise_scale))) {
    return InvalidArgument("texture noise_scale must be positive, got " + FormatNumber(noise_scale));
  }
  if (noise_octaves < 1 || noise_octaves > 12) {
    return InvalidArgument("texture noise_octaves must be in [1, 12], got " + std::to_string(noise_octaves));
  }
  if (!std::isfinite(tile_size) || tile_size < 0) {
    return InvalidArgument("texture tile_size must be >= 0, got " + FormatNumber(tile_size));
  }
  if (tile_size > 0 && !(grout_width >= 0 && grout_width < tile_size)) {
    return InvalidArgument("texture grout_width must be in [0, tile_size), got " + FormatNumber(grout_width));
  }
  if (!FiniteVec(grout_albedo) || grout_albedo.minCoeff() < 0 || grout_albedo.maxCoeff() > 1) {
    return InvalidArgument("texture grout albedo must be in [0, 1], got " + VecText(grout_albedo));
  }
  if (!std::isfinite(tile_jitter) || tile_jitter < 0 || tile_jitter > 1) {
    return InvalidArgument("texture tile_jitter must be in [0, 1], got " + FormatNumber(tile_jitter));
  }
  return Status::Ok();
}

Status Material::Check() const {
  if (!FiniteVec(albedo) || albedo.minCoeff() < 0 || albedo.maxCoeff() > 1) {
    return InvalidArgument("albedo must be in [0, 1], got " + VecText(albedo));
  }
  return texture.Check();
}

Status Solid::Check() const {
  const std::string where = "solid '" + name + "'";
  if (vertices.empty() || faces.empty()) {
    return InvalidArgument(where + " has no vertices or no faces");
  }
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    if (!FiniteVec(vertices[i])) {
      return InvalidArgument(where + ": vertex " + std::to_string(i) + " is not finite");
    }
  }
  if (materials.empty()) {
    return InvalidArgument(where + " has no material");
  }
  for (std::size_t m = 0; m < materials.size(); ++m) {
    IDI_RETURN_IF_ERROR(materials[m].Check().WithContext(where + " material " + std::to_string(m)));
  }
  for (std::size_t f = 0; f < faces.size(); ++f) {
    const Face& face = faces[f];
    const std::string fw = where + " face " + std::to_string(f);
    if (face.vertices.size() < 3) {
      return InvalidArgument(fw + " has fewer than 3 vertices");
    }
    for (const int v : face.vertices) {
      if (v < 0 || v >= static_cast<int>(vertices.size())) {
        return InvalidArgument(fw + " refers to vertex " + std::to_string(v) + " which does not exist");
      }
    }
    if (face.material < 0 || face.material >= static_cast<int>(materials.size())) {
      return InvalidArgument(fw + " refers to material " + std::to_string(face.material) + " which does not exist");
    }
    // Newell normal; a face must span an area and be planar to a relative 1e-6.
    Vec3d n = Vec3d::Zero();
    const std::size_t k = face.vertices.size();
    double extent = 0;
    for (std::size_t i = 0; i < k; ++i) {
      const Vec3d& a = vertices[static_cast<std::size_t>(face.vertices[i])];
      const Vec3d& b = vertices[static_cast<std::size_t>(face.vertices[(i + 1) % k])];
      n += a.cross(b);
      extent = std::max(extent, (b - a).norm());
    }
    if (!(n.norm() > 1e-12 * extent * extent) || extent == 0) {
      return InvalidArgument(fw + " is degenerate (zero area)");
    }
    n.normalize();
    const Vec3d& p0 = vertices[static_cast<std::size_t>(face.vertices[0])];
    for (const int v : face.vertices) {
      if (std::abs(n.dot(vertices[static_cast<std::size_t>(v)] - p0)) > 1e-6 * extent) {
        return InvalidArgument(fw + " is not planar (vertex " + std::to_string(v) + " is off its plane)");
      }
    }
    if (!FiniteVec(face.texture_origin) || !FiniteVec(face.texture_u) || !FiniteVec(face.texture_v)) {
      return InvalidArgument(fw + " has a non-finite texture frame");
    }
  }
  return Status::Ok();
}

Status Cylinder::Check() const {
  const std::string where = "cylinder '" + name + "'";
  if (!FiniteVec(base_center) || !FiniteVec(axis) || std::abs(axis.norm() - 1) > 1e-6) {
    return InvalidArgument(where + ": base centre must be finite and the axis a unit vector");
  }
  if (!(radius > 0 && std::isfinite(radius)) || !(height > 0 && std::isfinite(height))) {
    return InvalidArgument(where + ": radius and height must be positive and finite");
  }
  IDI_RETURN_IF_ERROR(side.Check().WithContext(where + " side"));
  IDI_RETURN_IF_ERROR(top.Check().WithContext(where + " top"));
  return bottom.Check().WithContext(where + " bottom");
}

Status Lighting::Check() const {
  if (!std::isfinite(ambient) || ambient < 0) {
    return InvalidArgument("lighting: ambient must be >= 0, got " + FormatNumber(ambient));
  }
  for (std::size_t i = 0; i < directional.size(); ++i) {
    const auto& d = directional[i];
    if (!FiniteVec(d.direction_to_light) || d.direction_to_light.norm() < 1e-12 || !std::isfinite(d.intensity) ||
        d.intensity < 0) {
      return InvalidArgument("lighting: directional light " + std::to_string(i) +
                             " needs a non-zero finite direction and an intensity >= 0");
    }
  }
  for (std::size_t i = 0; i < spotlights.size(); ++i) {
    const auto& s = spotlights[i];
    if (!FiniteVec(s.position) || !FiniteVec(s.direction) || s.direction.norm() < 1e-12 ||
        !std::isfinite(s.intensity) || s.intensity < 0 || !(s.reference_distance > 0) ||
        !(s.cone_half_angle_rad > 0 && s.cone_half_angle_rad < 1.5707963) || !(s.falloff_exponent >= 0)) {
      return InvalidArgument("lighting: spotlight " + std::to_string(i) +
                             " needs finite position and direction, intensity >= 0, reference distance > 0, "
                             "cone half angle in (0, 90) deg and falloff exponent >= 0");
    }
  }
  if (!FiniteVec(gradient.origin) || !FiniteVec(gradient.gradient) || !(gradient.min_factor >= 0)) {
    return InvalidArgument("lighting: the illumination gradient must be finite with min_factor >= 0");
  }
  return Status::Ok();
}

Status Scene::Check() const {
  for (const Solid& s : solids) {
    IDI_RETURN_IF_ERROR(s.Check());
  }
  for (const Cylinder& c : cylinders) {
    IDI_RETURN_IF_ERROR(c.Check());
  }
  IDI_RETURN_IF_ERROR(lighting.Check());
  for (std::size_t i = 0; i < laser_spots.size(); ++i) {
    const LaserSpot& s = laser_spots[i];
    if (!FiniteVec(s.center) || !(s.sigma > 0 && std::isfinite(s.sigma)) || !(s.peak >= 0 && s.peak <= 1e6) ||
        !FiniteVec(s.color) || s.color.minCoeff() < 0 || s.color.maxCoeff() > 1e3) {
      return InvalidArgument("laser spot " + std::to_string(i) +
                             ": needs a finite centre, sigma > 0, peak in [0, 1e6] and a colour in [0, 1e3]");
    }
  }
  if (!FiniteVec(background) || background.minCoeff() < 0) {
    return InvalidArgument("background radiance must be finite and >= 0");
  }
  return Status::Ok();
}

}  // namespace idi::sim
