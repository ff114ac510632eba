// The objects of the workcell twin (§8.12.3: "various objects are placed on the rotary table"): a box, a
// triangular prism, a metal L-bracket and a cylinder, each with its render geometry (shared/sim/render),
// its exact solid geometry for the grasp physics (convex parts), its mass, and the ground truth of its
// corners and edges. Plus background clutter: boxes and cans on the floor around the table.
//
// Object frame (as shapes.h): origin at the centre of the footprint on the surface it stands on, z up.
#pragma once

#include <random>
#include <string>
#include <utility>
#include <vector>

#include "shared/geometry/rigid3.h"
#include "shared/sim/render/scene.h"

namespace idi::sim {

enum class ObjectKind { kBox, kTriangularPrism, kLBracket, kCylinder };
const char* ObjectKindName(ObjectKind kind);

// Dimensions in mm. Box: size_x, size_y, size_z. Prism: width (x), length (y), height, apex_x (the ridge's
// x). Bracket: width (foot, x), length (y), height (leg), thickness. Cylinder: radius, height.
struct ObjectShape {
  ObjectKind kind = ObjectKind::kBox;
  double size_x = 100, size_y = 80, size_z = 60;
  double apex_x = 0;
  double thickness = 10;
  double radius = 40;
  // Albedo per face (shapes.h order); empty: every face uses `albedo`.
  double albedo = 0.7;
  std::vector<double> face_albedos;
};

// A convex piece of an object's solid, in the object frame: inside where n.x <= d for every face.
struct ConvexPart {
  std::vector<Vec3d> vertices;
  std::vector<Vec3d> normals;  // outward, unit
  std::vector<double> offsets;
  std::vector<std::vector<int>> faces;  // the vertices of face k (on plane k), in order around it
  // The largest n.x - d over the faces (negative inside); the face index in `face`.
  double MaxSeparation(const Vec3d& p, int* face = nullptr) const;
  // Euclidean distance of an outside point from the solid and the closest point on its surface; 0 and
  // p itself for a point inside.
  double Distance(const Vec3d& p, Vec3d* closest = nullptr) const;
};

struct CellObject {
  std::string name;
  ObjectShape shape;
  Rigid3d world_from_object;
  double mass_kg = 0.3;
  bool target = true;  // the object to scan and pick (clutter: false)
};

// The object's render geometry in the world (a Solid, or a Cylinder for kCylinder).
void AddObjectToScene(const CellObject& object, Scene* scene);
// Its solid as convex parts in the object frame (a cylinder as a 180-gon prism: normals within 1 deg).
std::vector<ConvexPart> ObjectParts(const ObjectShape& shape);
// Corners and edges in the object frame (ground truth; a cylinder has none: its outlines depend on the view).
struct ObjectWireframe {
  std::vector<Vec3d> vertices;
  std::vector<std::pair<int, int>> edges;
};
ObjectWireframe ObjectCorners(const ObjectShape& shape);
// Height of the object's top above its footprint.
double ObjectHeight(const ObjectShape& shape);
// Radius of the object's footprint's circumscribed circle about the object origin.
double ObjectFootprintRadius(const ObjectShape& shape);
// Volume in mm^3 (for masses from densities).
double ObjectVolume(const ObjectShape& shape);
// Centre of mass in the object frame (uniform density).
Vec3d ObjectCentreOfMass(const ObjectShape& shape);

// A random object of `kind` of graspable size (the Barrett hand closes on 10-190 mm), with faces of
// distinct brightness, standing on the plane z = `surface_z` at `centre` (x, y) with a random yaw.
CellObject SampleObject(ObjectKind kind, const Vec3d& centre_on_surface, double max_offset_mm, std::mt19937_64& rng);

}  // namespace idi::sim
