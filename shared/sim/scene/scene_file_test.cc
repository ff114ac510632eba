#include "shared/sim/scene/scene_file.h"

#include <gtest/gtest.h>

#include <string>

#include "shared/camera/pinhole.h"

namespace idi::sim {
namespace {

// The status of parsing `text`, expected to fail; its message.
std::string ParseErrorOf(const std::string& text) {
  auto r = ParseWorkcellSceneYaml(text, "scene.yaml");
  EXPECT_FALSE(r.ok()) << "parsed, but should have failed:\n" << text;
  return r.ok() ? std::string() : r.status().message();
}

void ExpectMentions(const std::string& message, std::initializer_list<const char*> parts) {
  for (const char* p : parts) EXPECT_NE(message.find(p), std::string::npos) << "'" << p << "' not in: " << message;
}

TEST(SceneFileTest, EmptyFileIsTheStandardScene) {
  auto r = ParseWorkcellSceneYaml("", "empty.yaml");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const WorkcellSceneSpec s = StandardWorkcellScene();
  ASSERT_EQ(r->objects.size(), 4u);
  EXPECT_EQ(r->objects[2].name, "bracket");
  EXPECT_EQ(r->objects[2].shape.kind, ObjectKind::kLBracket);
  EXPECT_EQ(r->cameras.size(), 2u);
  EXPECT_EQ(r->clutter, s.clutter);
  EXPECT_TRUE(s.Check().ok()) << s.Check().ToString();
}

TEST(SceneFileTest, ParsesEveryKey) {
  const std::string text = R"(
seed: 7
table: {centre_mm: [2800, -450, -380], radius_mm: 350, thickness_mm: 30, albedo: 0.3}
objects:
  - {name: crate, kind: box, size_mm: [100, 60, 50], at_mm: [10, -20], yaw_deg: 90, albedo: 0.4}
  - {name: wedge, kind: prism, size_mm: [80, 100, 60], apex_x_mm: 10, at_mm: [100, 100]}
  - {name: ell, kind: bracket, size_mm: [90, 80, 70], thickness_mm: 8, at_mm: [-120, 60],
     face_albedos: [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8]}
  - {name: can, kind: cylinder, radius_mm: 30, height_mm: 90, at_mm: [-100, -150]}
clutter: 2
tiled_floor: false
cameras:
  - {name: a, model: head, fx_px: 1000, distortion: [-0.1, 0.01, 0, 0, 0],
     position_mm: [1900, -500, 400], look_at_mm: [2800, -450, -380], roll_deg: 5}
  - {name: b, width_px: 320, height_px: 240, fx_px: 600, fy_px: 600, cx_px: 159.5, cy_px: 119.5,
     position_mm: [1900, -700, 400], look_at_mm: [2800, -450, -380]}
lighting:
  ambient: 0.2
  directional: [{direction: [0, 0, 1], intensity: 0.5}, {direction: [1, 0, 1], intensity: 0.2}]
  spotlights: [{position_mm: [2800, -450, 1000], direction: [0, 0, -1], intensity: 0.4,
                reference_distance_mm: 1000, cone_half_angle_deg: 30, falloff_exponent: 2}]
  gradient: {origin_mm: [2800, -450, -380], per_mm: [0.0002, 0, 0], min_factor: 0.1}
laser_spots: [{center_mm: [2800, -450, -380], sigma_mm: 3, peak: 20}]
image: {exposure_dn: 180, color: true}
optics: {psf_sigma_px: 0.7, vignetting: 0.2}
noise: {enabled: true, read_noise_dn: 1.5, gain_dn_per_electron: 0.05, black_level_dn: 2}
)";
  auto r = ParseWorkcellSceneYaml(text, "full.yaml");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const WorkcellSceneSpec& s = *r;
  EXPECT_EQ(s.seed, 7u);
  EXPECT_DOUBLE_EQ(s.table.radius_mm, 350);
  ASSERT_EQ(s.objects.size(), 4u);
  EXPECT_EQ(s.objects[1].shape.kind, ObjectKind::kTriangularPrism);
  EXPECT_DOUBLE_EQ(s.objects[1].shape.apex_x, 10);
  EXPECT_DOUBLE_EQ(s.objects[2].shape.thickness, 8);
  EXPECT_EQ(s.objects[2].shape.face_albedos.size(), 8u);
  EXPECT_DOUBLE_EQ(s.objects[3].shape.radius, 30);
  EXPECT_DOUBLE_EQ(s.objects[3].shape.size_z, 90);
  EXPECT_EQ(s.clutter, 2);
  EXPECT_FALSE(s.tiled_floor);
  ASSERT_EQ(s.cameras.size(), 2u);
  EXPECT_DOUBLE_EQ(s.cameras[0].camera.fx(), 1000);
  EXPECT_DOUBLE_EQ(s.cameras[0].camera.fy(), 1240);  // the head camera's, not overridden
  EXPECT_DOUBLE_EQ(s.cameras[0].camera.params[kK1], -0.1);
  EXPECT_EQ(s.cameras[1].camera.width, 320);
  EXPECT_EQ(s.lighting.directional.size(), 2u);
  ASSERT_EQ(s.lighting.spotlights.size(), 1u);
  EXPECT_NEAR(s.lighting.spotlights[0].cone_half_angle_rad, 30 * 3.14159265358979 / 180, 1e-12);
  EXPECT_DOUBLE_EQ(s.lighting.gradient.min_factor, 0.1);
  ASSERT_EQ(s.laser_spots.size(), 1u);
  EXPECT_DOUBLE_EQ(s.laser_spots[0].peak, 20);
  EXPECT_TRUE(s.render.color);
  EXPECT_DOUBLE_EQ(s.render.exposure_dn, 180);
  EXPECT_DOUBLE_EQ(s.render.psf_sigma_px, 0.7);
  EXPECT_DOUBLE_EQ(s.render.vignetting, 0.2);
  EXPECT_DOUBLE_EQ(s.render.sensor.read_noise_dn, 1.5);
  EXPECT_DOUBLE_EQ(s.render.sensor.gain_dn_per_electron, 0.05);
  EXPECT_DOUBLE_EQ(s.render.sensor.black_level_dn, 2);
}

TEST(SceneFileTest, UnknownKeysAreRejectedWithFileLineAndKey) {
  ExpectMentions(ParseErrorOf("seed: 1\nlightning: {ambient: 0.3}\n"), {"scene.yaml:2", "unknown key 'lightning'"});
  ExpectMentions(ParseErrorOf("noise:\n  read_noise: 1\n"), {"scene.yaml:2", "noise.read_noise", "read_noise_dn"});
  ExpectMentions(ParseErrorOf("objects:\n  - {kind: box, size_mm: [50, 50, 50], colour: 3}\n"),
                 {"scene.yaml:2", "objects[0].colour"});
  ExpectMentions(ParseErrorOf("cameras:\n  - {name: a, focal: 3}\n"), {"cameras[0].focal"});
  ExpectMentions(ParseErrorOf("optics: {supersampling: 8}\n"), {"optics.supersampling", "exactly"});
  // A key of another kind of object.
  ExpectMentions(ParseErrorOf("objects:\n  - {kind: box, size_mm: [50, 50, 50], radius_mm: 3}\n"),
                 {"objects[0].radius_mm", "cylinders"});
}

TEST(SceneFileTest, ObjectBehindTheCameraIsRejected) {
  // The camera stands beyond the table looking away from it: every object is behind it.
  const std::string text = R"(
objects: [{name: box, kind: box, size_mm: [100, 80, 60]}]
cameras: [{name: back, position_mm: [2000, -500, 300], look_at_mm: [1000, -500, 300]}]
)";
  ExpectMentions(ParseErrorOf(text), {"scene.yaml", "objects[0] 'box'", "behind", "cameras[0] 'back'"});
}

TEST(SceneFileTest, NegativeNoiseIsRejected) {
  ExpectMentions(ParseErrorOf("noise: {read_noise_dn: -0.5}\n"), {"scene.yaml:1", "noise.read_noise_dn", ">= 0"});
  ExpectMentions(ParseErrorOf("noise:\n  gain_dn_per_electron: -1\n"), {"scene.yaml:2", "noise.gain_dn_per_electron"});
  ExpectMentions(ParseErrorOf("optics: {psf_sigma_px: -1}\n"), {"psf_sigma_px"});
  ExpectMentions(ParseErrorOf("optics: {vignetting: 1.5}\n"), {"vignetting"});
}

TEST(SceneFileTest, NanAndGarbageAreRejected) {
  ExpectMentions(ParseErrorOf("noise: {read_noise_dn: .nan}\n"), {"scene.yaml:1", "noise.read_noise_dn", "finite"});
  ExpectMentions(ParseErrorOf("table: {radius_mm: .inf}\n"), {"table.radius_mm", "finite"});
  ExpectMentions(ParseErrorOf("cameras: [{position_mm: [1, nan, 3]}]\n"), {"cameras[0].position_mm[1]"});
  ExpectMentions(ParseErrorOf("objects: [{kind: box, size_mm: [50, 50, abc]}]\n"), {"objects[0].size_mm[2]", "number"});
  ExpectMentions(ParseErrorOf("clutter: 2.5\n"), {"clutter", "integer"});
  ExpectMentions(ParseErrorOf("objects: [{kind: sphere}]\n"), {"objects[0].kind", "sphere"});
  ExpectMentions(ParseErrorOf("seed: [1, 2\n"), {"scene.yaml:"});
  ExpectMentions(ParseErrorOf("- 1\n- 2\n"), {"the scene must be a map"});
  // yaml-cpp keeps a repeated key and reads its first value: the second was silently ignored.
  ExpectMentions(ParseErrorOf("seed: 1\nseed: 2\n"), {"scene.yaml:2", "key 'seed' given twice"});
  // A name saved as Latin-1 (0xE9 alone): the truth JSON cannot hold it (the render wrote the image,
  // then failed writing its JSON). UTF-8 names are fine.
  ExpectMentions(ParseErrorOf("cameras: [{name: \"caf\xE9\"}]\n"), {"cameras[0].name", "not valid UTF-8"});
  ExpectMentions(ParseErrorOf("objects: [{name: \"a\xC0\xAF\", kind: box}]\n"), {"objects[0].name", "UTF-8"});
  EXPECT_TRUE(ParseWorkcellSceneYaml("cameras: [{name: \"caf\xC3\xA9\"}]\n", "scene.yaml").ok());
  ExpectMentions(ParseErrorOf("noise: {read_noise_dn: 1, read_noise_dn: 2}\n"), {"'noise.read_noise_dn' given twice"});
  // Barrel distortion the model cannot hold at this focal length: the corners' rays fold back (before,
  // it was rendered, the corners with a wrong footprint and the truth with points from the fold).
  ExpectMentions(ParseErrorOf("cameras: [{name: fisheye, fx_px: 400, distortion: [-0.3, 0, 0, 0, 0]}]\n"),
                 {"cameras[0] 'fisheye'", "distortion", "folds back"});
}

TEST(SceneFileTest, ImpossibleObjectsAreRejected) {
  ExpectMentions(ParseErrorOf("objects: [{name: big, kind: box, size_mm: [100, 100, 50], at_mm: [280, 0]}]\n"),
                 {"objects[0] 'big'", "does not fit on the table"});
  ExpectMentions(ParseErrorOf("objects: [{kind: box, size_mm: [0, 10, 10]}]\n"), {"size_mm > 0"});
  ExpectMentions(ParseErrorOf("objects: [{kind: bracket, size_mm: [50, 50, 50]}]\n"), {"needs thickness_mm"});
  ExpectMentions(ParseErrorOf("objects: [{kind: cylinder, radius_mm: 20}]\n"), {"needs height_mm"});
  ExpectMentions(ParseErrorOf("objects: [{kind: box, size_mm: [50, 50, 50], face_albedos: [0.5]}]\n"),
                 {"face_albedos", "6"});
  ExpectMentions(ParseErrorOf("objects: [{name: a, kind: box, size_mm: [50, 50, 50]}, "
                              "{name: a, kind: box, size_mm: [50, 50, 50], at_mm: [100, 0]}]\n"),
                 {"objects[1] 'a'", "used by another"});
  ExpectMentions(ParseErrorOf("cameras: [{position_mm: [2825, -500, 1000], look_at_mm: [2825, -500, -400]}]\n"),
                 {"vertical"});
}

TEST(SceneFileTest, MissingFileIsNamed) {
  auto r = LoadWorkcellSceneFile("/nonexistent/dir/scene.yaml");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kNotFound);
  ExpectMentions(r.status().message(), {"/nonexistent/dir/scene.yaml"});
}

TEST(SceneFileTest, CameraLooksAtItsTargetWithImageUpAlongWorldZ) {
  SceneCameraSpec c;
  c.position_mm = Vec3d(0, 0, 1000);
  c.look_at_mm = Vec3d(1000, 0, 0);
  const Rigid3d cam_from_world = c.CamFromWorld();
  const Vec3d target = cam_from_world * c.look_at_mm;
  EXPECT_NEAR(target.x(), 0, 1e-9);
  EXPECT_NEAR(target.y(), 0, 1e-9);
  EXPECT_GT(target.z(), 0);
  // A point above the target appears above it in the image (smaller y); one to the world's left
  // (+y when looking along +x) appears on the image's left (smaller x).
  EXPECT_LT((cam_from_world * Vec3d(1000, 0, 100)).y(), 0);
  EXPECT_LT((cam_from_world * Vec3d(1000, 100, 0)).x(), 0);
  EXPECT_NEAR(cam_from_world.rotation.determinant(), 1.0, 1e-12);
}

TEST(SceneFileTest, BuiltStandardSceneShowsEveryObjectInEveryCamera) {
  auto built = BuildWorkcellScene(StandardWorkcellScene());
  ASSERT_TRUE(built.ok()) << built.status().ToString();
  ASSERT_EQ(built->views.size(), 2u);
  ASSERT_EQ(built->objects.size(), 4u);
  // Walls, floor, table, pedestal, 6 clutter and 4 objects are in the scene.
  int named = 0;
  for (const Solid& s : built->scene.solids) {
    for (const CellObject& o : built->objects) named += s.name == o.name ? 1 : 0;
  }
  for (const Cylinder& c : built->scene.cylinders) {
    for (const CellObject& o : built->objects) named += c.name == o.name ? 1 : 0;
  }
  EXPECT_EQ(named, 4);
  for (const SceneView& v : built->views) {
    for (const CellObject& o : built->objects) {
      const Vec3d top = o.world_from_object * Vec3d(0, 0, ObjectHeight(o.shape));
      const auto px = Project(v.camera, v.cam_from_world * top);
      ASSERT_TRUE(px.has_value()) << o.name;
      EXPECT_TRUE(v.camera.InImage(*px, 20)) << o.name << " at " << px->transpose() << " in " << v.name;
    }
  }
  EXPECT_NE(built->views[0].render.seed, built->views[1].render.seed);
}

}  // namespace
}  // namespace idi::sim
