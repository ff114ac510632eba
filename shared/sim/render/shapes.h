// Builders for the standard solids of the digital twin. Every object has its own frame: origin at the
// centre of its footprint on the plane it stands on, z up; `world_from_object` places it.
#pragma once

#include <string>
#include <vector>

#include "shared/sim/render/scene.h"

namespace idi::sim {

// A profile (counter-clockwise in the object's x-z plane) extruded along y from -length/2 to +length/2.
// Faces, in order: one side face per profile edge (edge k from point k to k+1), then the +y cap, then
// the -y cap. `face_materials`, when not empty, gives each face's material in that order (size must be
// the face count); otherwise every face uses `material`.
Solid MakeExtrusion(const std::string& name, const Rigid3d& world_from_object, const std::vector<Vec2d>& profile_xz,
                    double length, const Material& material, const std::vector<Material>& face_materials = {});

// A box size.x by size.y by size.z standing on its base. Faces: bottom, +x, top, -x, +y, -y.
Solid MakeBox(const std::string& name, const Rigid3d& world_from_object, const Vec3d& size, const Material& material,
              const std::vector<Material>& face_materials = {});

// A triangular prism: the triangle (-width/2, 0), (width/2, 0), (apex_x, height) in x-z, extruded
// along y by `length`. Faces: bottom, the two slanted sides, +y, -y.
Solid MakeTriangularPrism(const std::string& name, const Rigid3d& world_from_object, double width, double height,
                          double length, double apex_x, const Material& material,
                          const std::vector<Material>& face_materials = {});

// An L-shaped bracket: a foot of `width` along x and a leg of `height` along z at the -x end, both
// `thickness` thick, extruded along y by `length`. Its two end faces are concave hexagons.
Solid MakeLBracket(const std::string& name, const Rigid3d& world_from_object, double width, double height,
                   double length, double thickness, const Material& material,
                   const std::vector<Material>& face_materials = {});

// A planar polygon (convex or concave, vertices in order), visible from both sides.
Solid MakePolygon(const std::string& name, const std::vector<Vec3d>& vertices, const Material& material,
                  int layer = 0);

// A rectangle centred at `center` spanning +-half_u along unit u_axis and +-half_v along unit v_axis
// (a wall or a floor), visible from both sides; its texture coordinates are (u, v) from the centre.
Solid MakeRectangle(const std::string& name, const Vec3d& center, const Vec3d& u_axis, const Vec3d& v_axis,
                    double half_u, double half_v, const Material& material);

// A strip of tape of `width` lying on the plane z = `z` along the polyline `centerline` (x, y), with
// mitred joints and square ends; layer 1 so it lies on top of a floor at the same height.
// InvalidArgument when a joint turns by more than 150 deg or a segment is too short for its joints.
Result<Solid> MakeTapeStrip(const std::string& name, const std::vector<Vec2d>& centerline, double width, double z,
                            const Material& material);

// The unit normal of a face by Newell's method (outward for a counter-clockwise face).
Vec3d FaceNormal(const Solid& solid, const Face& face);

}  // namespace idi::sim
