// The digital twin's scene description: what the renderer draws. Plain structs, world frame, one
// length unit per scene (mm in the workcell, m on the vehicle; the renderer never assumes which).
//
// Geometry is a list of polyhedral solids (planar faces, convex or concave) plus cylinders. A solid is
// either closed (a box, prism, bracket: faces wound counter-clockwise seen from outside, back faces
// hidden) or open (a wall, floor, tape strip: visible from both sides). Shading is Lambertian:
// radiance = albedo x (ambient + directional + spotlights) x gradient + laser spots, in relative units
// where 1 is a white surface under unit irradiance; RenderOptions::exposure_dn maps that to pixels.
// Builders for the standard shapes are in shapes.h.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "shared/geometry/rigid3.h"
#include "shared/util/status.h"

namespace idi::sim {

// Procedural surface texture: an albedo multiplier (value noise) and/or a tile pattern with grout
// lines. Evaluated in 2D texture coordinates (scene length units) on each face; filtered over the
// pixel footprint so that fine texture averages out instead of aliasing.
struct Texture {
  // Value noise: albedo *= 1 + noise_amplitude * n, n in [-1, 1], summed over octaves.
  double noise_amplitude = 0;   // 0 = no noise
  double noise_scale = 1;       // wavelength of the coarsest octave
  int noise_octaves = 4;        // each next octave halves the wavelength and the amplitude
  // Tiles: square tiles of tile_size separated by grout lines of grout_width.
  double tile_size = 0;         // 0 = no tiles
  double grout_width = 0;
  Vec3d grout_albedo = Vec3d(0.3, 0.3, 0.3);
  double tile_jitter = 0;       // each tile's albedo *= 1 + tile_jitter * u, u in [-1, 1] per tile
  uint64_t seed = 1;

  bool Enabled() const { return noise_amplitude != 0 || tile_size > 0; }
  Status Check() const;
};

struct Material {
  Vec3d albedo = Vec3d(0.6, 0.6, 0.6);  // linear RGB reflectance in [0, 1]; gray = equal channels
  Texture texture;
  Status Check() const;
};

// Convenience: a gray material.
inline Material Gray(double albedo) { return Material{Vec3d(albedo, albedo, albedo), {}}; }
inline Material Rgb(double r, double g, double b) { return Material{Vec3d(r, g, b), {}}; }

struct Face {
  std::vector<int> vertices;  // indices into Solid::vertices, counter-clockwise seen from outside
  int material = 0;           // index into Solid::materials
  // Texture coordinates: u = u_axis . (p - texture_origin), v likewise. When both axes are zero the
  // renderer derives them (u along the face's first edge).
  Vec3d texture_origin = Vec3d::Zero();
  Vec3d texture_u = Vec3d::Zero();
  Vec3d texture_v = Vec3d::Zero();
};

struct Solid {
  std::string name;
  std::vector<Vec3d> vertices;  // world frame
  std::vector<Face> faces;
  std::vector<Material> materials = {Material{}};
  bool closed = true;  // closed: back faces are hidden; open: every face is seen from both sides
  // Coplanar faces of different solids (tape lying on the floor) are ordered by layer: higher is on top.
  int layer = 0;
  Status Check() const;
};

// A right circular cylinder; rendered with silhouettes exact for the camera (not faceted outlines).
struct Cylinder {
  std::string name;
  Vec3d base_center = Vec3d::Zero();
  Vec3d axis = Vec3d::UnitZ();  // unit, from the base towards the top
  double radius = 1;
  double height = 1;
  Material side;
  Material top;
  Material bottom;
  Status Check() const;
};

struct DirectionalLight {
  Vec3d direction_to_light = Vec3d(0, 0, 1);  // world frame, towards the light (normalised on use)
  double intensity = 0.6;
};

// A spotlight: irradiance intensity * cos(incidence) * (reference_distance / distance)^2 inside the
// cone, falling off as cos(angle off axis)^falloff_exponent and smoothly to zero at the cone edge.
struct SpotLight {
  Vec3d position = Vec3d::Zero();
  Vec3d direction = Vec3d(0, 0, -1);
  double intensity = 0.5;
  double reference_distance = 1;
  double cone_half_angle_rad = 0.8;
  double falloff_exponent = 2;
};

// Smooth uneven illumination: all irradiance is scaled by max(min_factor, 1 + gradient.(p - origin)).
struct IlluminationGradient {
  Vec3d origin = Vec3d::Zero();
  Vec3d gradient = Vec3d::Zero();  // relative change per scene length unit
  double min_factor = 0.05;
};

struct Lighting {
  double ambient = 0.35;
  std::vector<DirectionalLight> directional = {DirectionalLight{}};
  std::vector<SpotLight> spotlights;
  IlluminationGradient gradient;
  Status Check() const;
};

// A laser spot: radiance peak * color * exp(-|p - center|^2 / (2 sigma^2)) added on whatever surface
// lies at p (so an occluded spot is not seen). A peak well above 1 saturates the sensor.
struct LaserSpot {
  Vec3d center = Vec3d::Zero();
  double sigma = 1;
  double peak = 5;
  Vec3d color = Vec3d(1.0, 0.12, 0.08);  // relative RGB of a red laser
};

struct Scene {
  std::vector<Solid> solids;
  std::vector<Cylinder> cylinders;
  Lighting lighting;
  std::vector<LaserSpot> laser_spots;
  Vec3d background = Vec3d::Zero();  // radiance where no surface is hit
  // Validates every part; messages name the solid, face or light.
  Status Check() const;
};

}  // namespace idi::sim
