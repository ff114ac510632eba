// Scene files of the workcell twin: a YAML description of what the cell's cameras look at (objects on
// the rotary table of shared/sim/cell, clutter, cameras, lighting, image formation and noise), loaded
// with strict validation, and the scene and camera views it builds for the renderer (shared/sim/render).
//
// Every key is optional; a missing key keeps the standard workcell scene's value (StandardWorkcellScene,
// the same scene as workcell/app/scenes/standard.yaml). Unknown keys, non-finite numbers, negative noise
// levels, objects that do not fit on the table and objects behind a camera are errors whose message
// names the file, the line and the key. Lengths in mm, angles in degrees (code: radians).
//
//   seed: 1                         the world (clutter, textures) and the noise; same seed, same images
//   table: {centre_mm: [x, y, z], radius_mm, thickness_mm, albedo}     the rotary table's top centre
//   objects:                        standing on the table top (replaces the standard objects)
//     - name: box                   unique; names the object in the ground truth
//       kind: box | prism | bracket | cylinder
//       size_mm: [x, y, z]          box; prism: [width, length, height]; bracket: [foot, length, leg]
//       apex_x_mm: 0                prism: x of the ridge
//       thickness_mm: 10            bracket
//       radius_mm, height_mm        cylinder
//       at_mm: [x, y]               footprint centre relative to the table's centre (world axes)
//       yaw_deg: 0                  rotation about the vertical
//       albedo: 0.7                 or face_albedos: one per face (box 6, prism 5, bracket 8, cylinder 3)
//   clutter: 6                      boxes and drums on the floor around the table
//   tiled_floor: true
//   cameras:                        each renders one image (replaces the standard pair)
//     - name: left
//       model: head                 the Biclops camera's nominal intrinsics (640x480, f 1240 px) ...
//       width_px, height_px, fx_px, fy_px, cx_px, cy_px   ... or any of them given
//       distortion: [k1, k2, p1, p2, k3]
//       position_mm: [x, y, z]      optical centre
//       look_at_mm: [x, y, z]       the point on the optical axis; image "up" is the world's +z
//       roll_deg: 0                 about the optical axis
//   lighting:
//     ambient: 0.35
//     directional: [{direction: [x, y, z], intensity: 0.6}]           direction towards the light
//     spotlights: [{position_mm, direction, intensity, reference_distance_mm, cone_half_angle_deg,
//                   falloff_exponent}]
//     gradient: {origin_mm: [x, y, z], per_mm: [x, y, z], min_factor: 0.05}   uneven illumination
//   laser_spots: [{center_mm: [x, y, z], sigma_mm: 2, peak: 60}]
//   image: {exposure_dn: 200, color: false}
//   optics: {psf_sigma_px: 1.0, vignetting: 0.0}                     blur (Gaussian PSF), vignetting
//   noise: {enabled: true, read_noise_dn: 0.8, gain_dn_per_electron: 0.1, black_level_dn: 0}
//                                   read noise (Gaussian) and shot noise (Poisson, variance gain x signal)
//
// Pixels are area-integrated exactly (render.h: exact coverage of every face inside each pixel, better
// than any n x n supersampling), so there is no supersampling key.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "shared/camera/pinhole.h"
#include "shared/geometry/rigid3.h"
#include "shared/sim/cell/cell_objects.h"
#include "shared/sim/cell/cell_twin.h"
#include "shared/sim/render/render.h"
#include "shared/sim/render/scene.h"
#include "shared/util/status.h"

namespace idi::sim {

// An object standing on the rotary table's top.
struct TableObjectSpec {
  std::string name;
  ObjectShape shape;
  Vec2d at_mm = Vec2d::Zero();  // footprint centre, relative to the table's top centre (world x, y)
  double yaw_deg = 0;
};

// A camera placed by its optical centre and a point it looks at (image up = world +z, then rolled).
struct SceneCameraSpec {
  std::string name;
  CameraModel camera;
  Vec3d position_mm = Vec3d::Zero();
  Vec3d look_at_mm = Vec3d::UnitX();
  double roll_deg = 0;
  // The camera's pose; undefined unless Check() of the scene passed (the axis must not be vertical).
  Rigid3d CamFromWorld() const;
};

struct WorkcellSceneSpec {
  std::string source = "(standard scene)";  // file name, for messages
  uint64_t seed = 1;
  RotaryTable table;
  std::vector<TableObjectSpec> objects;
  int clutter = 6;
  bool tiled_floor = true;
  std::vector<SceneCameraSpec> cameras;
  Lighting lighting;
  std::vector<LaserSpot> laser_spots;
  RenderOptions render;  // exposure, colour, PSF, vignetting, sensor noise (the seed comes from `seed`)

  // Messages name the source and the key (objects[1] 'prism': ...).
  Status Check() const;
};

// The standard workcell scene: a box, a triangular prism, an L-bracket and a cylinder on the rotary
// table, six clutter objects on the tiled floor, and the Biclops head's two cameras 1.2 m from the
// table looking 40 deg down at it.
WorkcellSceneSpec StandardWorkcellScene();

// Parses a scene file's text (`source` names it in messages); missing keys keep the standard values.
Result<WorkcellSceneSpec> ParseWorkcellSceneYaml(const std::string& text, const std::string& source);
// Reads and parses a scene file; NotFound naming the path when it cannot be read.
Result<WorkcellSceneSpec> LoadWorkcellSceneFile(const std::string& path);

// One camera's view of the built scene.
struct SceneView {
  std::string name;
  CameraModel camera;
  Rigid3d cam_from_world;
  RenderOptions render;  // the scene's options with this view's noise seed
};

struct BuiltWorkcellScene {
  Scene scene;                      // what the renderer draws (walls, floor, table, clutter, objects)
  std::vector<CellObject> objects;  // the table's objects in the world (ground truth)
  std::vector<SceneView> views;
};

// The renderer's scene (through the cell twin, so it is the twin's cell) and one view per camera.
Result<BuiltWorkcellScene> BuildWorkcellScene(const WorkcellSceneSpec& spec);

}  // namespace idi::sim
