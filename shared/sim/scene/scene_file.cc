#include "shared/sim/scene/scene_file.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "shared/kinematics/biclops.h"
#include "shared/util/atomic_file.h"
#include "shared/util/units.h"

namespace idi::sim {
namespace {

// ---- Reading YAML strictly: every message names the file, the line and the key's full path.

std::string SceneWhere(const std::string& source, const YAML::Node& node) {
  if (!node.IsDefined() || node.Mark().line < 0) return source;
  return source + ":" + std::to_string(node.Mark().line + 1);
}

std::string Join(const std::vector<std::string>& names) {
  std::string s;
  for (const std::string& n : names) s += (s.empty() ? "" : ", ") + n;
  return s;
}

// Well-formed UTF-8 (no overlong forms, surrogates or code points beyond U+10FFFF): names go into the
// ground truth's JSON, which cannot hold other bytes.
bool IsValidUtf8(const std::string& s) {
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    int n = 0;
    unsigned cp = 0;
    if (c < 0x80) {
      ++i;
      continue;
    } else if ((c & 0xE0) == 0xC0) {
      n = 1;
      cp = c & 0x1Fu;
    } else if ((c & 0xF0) == 0xE0) {
      n = 2;
      cp = c & 0x0Fu;
    } else if ((c & 0xF8) == 0xF0) {
      n = 3;
      cp = c & 0x07u;
    } else {
      return false;
    }
    if (i + static_cast<std::size_t>(n) >= s.size()) return false;  // the sequence is cut off
    for (int k = 1; k <= n; ++k) {
      const auto d = static_cast<unsigned char>(s[i + static_cast<std::size_t>(k)]);
      if ((d & 0xC0) != 0x80) return false;
      cp = (cp << 6) | (d & 0x3Fu);
    }
    const unsigned min_cp[] = {0, 0x80, 0x800, 0x10000};
    if (cp < min_cp[n] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return false;
    i += static_cast<std::size_t>(n) + 1;
  }
  return true;
}

std::string KeyPath(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }

// A YAML map whose keys must all be in `allowed`.
Status CheckSceneMap(const YAML::Node& node, const std::string& source, const std::string& path,
                     const std::vector<std::string>& allowed) {
  if (!node.IsMap()) {
    return InvalidArgument(SceneWhere(source, node) + ": " + (path.empty() ? "the scene" : path) + " must be a map");
  }
  std::set<std::string> seen;
  for (const auto& kv : node) {
    const std::string key = kv.first.Scalar();
    // yaml-cpp keeps both entries of a repeated key and reads the first: the second would be ignored.
    if (!seen.insert(key).second) {
      return InvalidArgument(SceneWhere(source, kv.first) + ": key '" + KeyPath(path, key) + "' given twice");
    }
    if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
    std::string hint;
    if (key == "supersampling") {
      hint = "; the renderer integrates every pixel's area exactly (no supersampling to set)";
    }
    return InvalidArgument(SceneWhere(source, kv.first) + ": unknown key '" + KeyPath(path, key) +
                           "' (expected one of: " + Join(allowed) + ")" + hint);
  }
  return Status::Ok();
}

Result<double> SceneNumber(const YAML::Node& node, const std::string& source, const std::string& key) {
  if (!node.IsScalar()) return InvalidArgument(SceneWhere(source, node) + ": " + key + " must be a number");
  double v = 0;
  try {
    v = node.as<double>();
  } catch (const YAML::Exception&) {
    return InvalidArgument(SceneWhere(source, node) + ": " + key + " must be a number, got '" + node.Scalar() + "'");
  }
  if (!std::isfinite(v)) {
    return InvalidArgument(SceneWhere(source, node) + ": " + key + " must be a finite number, got " + node.Scalar());
  }
  return v;
}

Result<bool> SceneBool(const YAML::Node& node, const std::string& source, const std::string& key) {
  try {
    if (node.IsScalar()) return node.as<bool>();
  } catch (const YAML::Exception&) {
  }
  return InvalidArgument(SceneWhere(source, node) + ": " + key + " must be true or false");
}

Result<std::vector<double>> SceneNumbers(const YAML::Node& node, const std::string& source, const std::string& key,
                                         std::size_t count) {
  if (!node.IsSequence() || node.size() != count) {
    return InvalidArgument(SceneWhere(source, node) + ": " + key + " must be a list of " + std::to_string(count) +
                           " numbers");
  }
  std::vector<double> out;
  for (std::size_t i = 0; i < count; ++i) {
    IDI_ASSIGN_OR_RETURN(const double v, SceneNumber(node[i], source, key + "[" + std::to_string(i) + "]"));
    out.push_back(v);
  }
  return out;
}

Result<Vec3d> SceneVec3(const YAML::Node& node, const std::string& source, const std::string& key) {
  IDI_ASSIGN_OR_RETURN(const std::vector<double> v, SceneNumbers(node, source, key, 3));
  return Vec3d(v[0], v[1], v[2]);
}

Result<Vec2d> SceneVec2(const YAML::Node& node, const std::string& source, const std::string& key) {
  IDI_ASSIGN_OR_RETURN(const std::vector<double> v, SceneNumbers(node, source, key, 2));
  return Vec2d(v[0], v[1]);
}

// Optional fields of one map: each setter reads the key when it is present.
class SceneFields {
 public:
  SceneFields(const YAML::Node& map, const std::string& source, const std::string& path)
      : map_(map), source_(source), path_(path) {}
  Status Number(const char* key, double* out) {
    if (!Has(key)) return Status::Ok();
    IDI_ASSIGN_OR_RETURN(*out, SceneNumber(map_[key], source_, KeyPath(path_, key)));
    return Status::Ok();
  }
  Status Integer(const char* key, int* out) {
    if (!Has(key)) return Status::Ok();
    IDI_ASSIGN_OR_RETURN(const double v, SceneNumber(map_[key], source_, KeyPath(path_, key)));
    if (v != std::floor(v) || std::abs(v) > 1e9) {
      return InvalidArgument(SceneWhere(source_, map_[key]) + ": " + KeyPath(path_, key) + " must be an integer");
    }
    *out = static_cast<int>(v);
    return Status::Ok();
  }
  Status Bool(const char* key, bool* out) {
    if (!Has(key)) return Status::Ok();
    IDI_ASSIGN_OR_RETURN(*out, SceneBool(map_[key], source_, KeyPath(path_, key)));
    return Status::Ok();
  }
  Status Vector3(const char* key, Vec3d* out) {
    if (!Has(key)) return Status::Ok();
    IDI_ASSIGN_OR_RETURN(*out, SceneVec3(map_[key], source_, KeyPath(path_, key)));
    return Status::Ok();
  }
  Status Vector2(const char* key, Vec2d* out) {
    if (!Has(key)) return Status::Ok();
    IDI_ASSIGN_OR_RETURN(*out, SceneVec2(map_[key], source_, KeyPath(path_, key)));
    return Status::Ok();
  }
  Status String(const char* key, std::string* out) {
    if (!Has(key)) return Status::Ok();
    if (!map_[key].IsScalar()) {
      return InvalidArgument(SceneWhere(source_, map_[key]) + ": " + KeyPath(path_, key) + " must be a string");
    }
    if (!IsValidUtf8(map_[key].Scalar())) {
      return InvalidArgument(SceneWhere(source_, map_[key]) + ": " + KeyPath(path_, key) +
                             " is not valid UTF-8 (save the file as UTF-8)");
    }
    *out = map_[key].Scalar();
    return Status::Ok();
  }
  bool Has(const char* key) const { return static_cast<bool>(map_[key]); }
  const YAML::Node& map() const { return map_; }

 private:
  const YAML::Node map_;
  const std::string& source_;
  std::string path_;
};

// ---- Sections.

Result<ObjectKind> ParseObjectKind(const YAML::Node& node, const std::string& source, const std::string& key) {
  const std::string s = node.IsScalar() ? node.Scalar() : "";
  if (s == "box") return ObjectKind::kBox;
  if (s == "prism") return ObjectKind::kTriangularPrism;
  if (s == "bracket") return ObjectKind::kLBracket;
  if (s == "cylinder") return ObjectKind::kCylinder;
  return InvalidArgument(SceneWhere(source, node) + ": " + key + " must be box, prism, bracket or cylinder, got '" + s +
                         "'");
}

int FaceCount(ObjectKind kind) {
  switch (kind) {
    case ObjectKind::kBox:
      return 6;
    case ObjectKind::kTriangularPrism:
      return 5;
    case ObjectKind::kLBracket:
      return 8;
    case ObjectKind::kCylinder:
      return 3;
  }
  return 0;
}

Result<TableObjectSpec> ParseTableObject(const YAML::Node& node, const std::string& source, const std::string& path) {
  IDI_RETURN_IF_ERROR(CheckSceneMap(node, source, path,
                                    {"name", "kind", "size_mm", "apex_x_mm", "thickness_mm", "radius_mm", "height_mm",
                                     "at_mm", "yaw_deg", "albedo", "face_albedos"}));
  TableObjectSpec o;
  SceneFields f(node, source, path);
  if (!f.Has("kind")) return InvalidArgument(SceneWhere(source, node) + ": " + path + " needs a kind");
  IDI_ASSIGN_OR_RETURN(o.shape.kind, ParseObjectKind(node["kind"], source, path + ".kind"));
  o.name = ObjectKindName(o.shape.kind);
  IDI_RETURN_IF_ERROR(f.String("name", &o.name));
  const bool cylinder = o.shape.kind == ObjectKind::kCylinder;
  // Dimensions: the keys of this kind are required, the others are errors.
  auto reject = [&](const char* key, const char* kinds) -> Status {
    if (!f.Has(key)) return Status::Ok();
    return InvalidArgument(SceneWhere(source, node[key]) + ": " + KeyPath(path, key) + " applies to " + kinds +
                           ", not to a " + ObjectKindName(o.shape.kind));
  };
  auto require = [&](const char* key) -> Status {
    if (f.Has(key)) return Status::Ok();
    return InvalidArgument(SceneWhere(source, node) + ": " + path + " (a " + ObjectKindName(o.shape.kind) + ") needs " +
                           key);
  };
  if (cylinder) {
    IDI_RETURN_IF_ERROR(reject("size_mm", "boxes, prisms and brackets"));
    IDI_RETURN_IF_ERROR(require("radius_mm"));
    IDI_RETURN_IF_ERROR(require("height_mm"));
    IDI_RETURN_IF_ERROR(f.Number("radius_mm", &o.shape.radius));
    IDI_RETURN_IF_ERROR(f.Number("height_mm", &o.shape.size_z));
  } else {
    IDI_RETURN_IF_ERROR(reject("radius_mm", "cylinders"));
    IDI_RETURN_IF_ERROR(reject("height_mm", "cylinders (the others give size_mm)"));
    IDI_RETURN_IF_ERROR(require("size_mm"));
    Vec3d size;
    IDI_RETURN_IF_ERROR(f.Vector3("size_mm", &size));
    o.shape.size_x = size.x();
    o.shape.size_y = size.y();
    o.shape.size_z = size.z();
  }
  if (o.shape.kind != ObjectKind::kTriangularPrism) IDI_RETURN_IF_ERROR(reject("apex_x_mm", "prisms"));
  if (o.shape.kind != ObjectKind::kLBracket) IDI_RETURN_IF_ERROR(reject("thickness_mm", "brackets"));
  if (o.shape.kind == ObjectKind::kLBracket) IDI_RETURN_IF_ERROR(require("thickness_mm"));
  IDI_RETURN_IF_ERROR(f.Number("apex_x_mm", &o.shape.apex_x));
  IDI_RETURN_IF_ERROR(f.Number("thickness_mm", &o.shape.thickness));
  IDI_RETURN_IF_ERROR(f.Vector2("at_mm", &o.at_mm));
  IDI_RETURN_IF_ERROR(f.Number("yaw_deg", &o.yaw_deg));
  IDI_RETURN_IF_ERROR(f.Number("albedo", &o.shape.albedo));
  if (f.Has("face_albedos")) {
    const YAML::Node& fa = node["face_albedos"];
    const std::size_t n = static_cast<std::size_t>(FaceCount(o.shape.kind));
    if (!fa.IsSequence() || fa.size() != n) {
      return InvalidArgument(SceneWhere(source, fa) + ": " + path + ".face_albedos must list " + std::to_string(n) +
                             " albedos for a " + ObjectKindName(o.shape.kind));
    }
    IDI_ASSIGN_OR_RETURN(o.shape.face_albedos, SceneNumbers(fa, source, path + ".face_albedos", n));
  }
  return o;
}

Result<SceneCameraSpec> ParseCamera(const YAML::Node& node, const std::string& source, const std::string& path,
                                    const SceneCameraSpec& defaults) {
  IDI_RETURN_IF_ERROR(CheckSceneMap(node, source, path,
                                    {"name", "model", "width_px", "height_px", "fx_px", "fy_px", "cx_px", "cy_px",
                                     "distortion", "position_mm", "look_at_mm", "roll_deg"}));
  SceneCameraSpec c = defaults;
  SceneFields f(node, source, path);
  IDI_RETURN_IF_ERROR(f.String("name", &c.name));
  if (f.Has("model")) {
    const YAML::Node& m = node["model"];
    if (!m.IsScalar() || m.Scalar() != "head") {
      return InvalidArgument(SceneWhere(source, m) + ": " + path + ".model must be 'head' (the Biclops camera)");
    }
    c.camera = BiclopsNominalCamera(BiclopsSide::kLeft);
  }
  IDI_RETURN_IF_ERROR(f.Integer("width_px", &c.camera.width));
  IDI_RETURN_IF_ERROR(f.Integer("height_px", &c.camera.height));
  IDI_RETURN_IF_ERROR(f.Number("fx_px", &c.camera.params[kFx]));
  IDI_RETURN_IF_ERROR(f.Number("fy_px", &c.camera.params[kFy]));
  IDI_RETURN_IF_ERROR(f.Number("cx_px", &c.camera.params[kCx]));
  IDI_RETURN_IF_ERROR(f.Number("cy_px", &c.camera.params[kCy]));
  if (f.Has("distortion")) {
    IDI_ASSIGN_OR_RETURN(const std::vector<double> d, SceneNumbers(node["distortion"], source, path + ".distortion", 5));
    c.camera.params[kK1] = d[0];
    c.camera.params[kK2] = d[1];
    c.camera.params[kP1] = d[2];
    c.camera.params[kP2] = d[3];
    c.camera.params[kK3] = d[4];
  }
  IDI_RETURN_IF_ERROR(f.Vector3("position_mm", &c.position_mm));
  IDI_RETURN_IF_ERROR(f.Vector3("look_at_mm", &c.look_at_mm));
  IDI_RETURN_IF_ERROR(f.Number("roll_deg", &c.roll_deg));
  return c;
}

Status ParseLighting(const YAML::Node& node, const std::string& source, Lighting* l) {
  IDI_RETURN_IF_ERROR(CheckSceneMap(node, source, "lighting", {"ambient", "directional", "spotlights", "gradient"}));
  SceneFields f(node, source, "lighting");
  IDI_RETURN_IF_ERROR(f.Number("ambient", &l->ambient));
  if (f.Has("directional")) {
    const YAML::Node& list = node["directional"];
    if (!list.IsSequence()) return InvalidArgument(SceneWhere(source, list) + ": lighting.directional must be a list");
    l->directional.clear();
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = "lighting.directional[" + std::to_string(i) + "]";
      IDI_RETURN_IF_ERROR(CheckSceneMap(list[i], source, p, {"direction", "intensity"}));
      DirectionalLight d;
      SceneFields lf(list[i], source, p);
      IDI_RETURN_IF_ERROR(lf.Vector3("direction", &d.direction_to_light));
      IDI_RETURN_IF_ERROR(lf.Number("intensity", &d.intensity));
      l->directional.push_back(d);
    }
  }
  if (f.Has("spotlights")) {
    const YAML::Node& list = node["spotlights"];
    if (!list.IsSequence()) return InvalidArgument(SceneWhere(source, list) + ": lighting.spotlights must be a list");
    l->spotlights.clear();
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = "lighting.spotlights[" + std::to_string(i) + "]";
      IDI_RETURN_IF_ERROR(CheckSceneMap(list[i], source, p,
                                        {"position_mm", "direction", "intensity", "reference_distance_mm",
                                         "cone_half_angle_deg", "falloff_exponent"}));
      SpotLight s;
      s.reference_distance = 1000;
      double cone_deg = RadToDeg(s.cone_half_angle_rad);
      SceneFields sf(list[i], source, p);
      IDI_RETURN_IF_ERROR(sf.Vector3("position_mm", &s.position));
      IDI_RETURN_IF_ERROR(sf.Vector3("direction", &s.direction));
      IDI_RETURN_IF_ERROR(sf.Number("intensity", &s.intensity));
      IDI_RETURN_IF_ERROR(sf.Number("reference_distance_mm", &s.reference_distance));
      IDI_RETURN_IF_ERROR(sf.Number("cone_half_angle_deg", &cone_deg));
      IDI_RETURN_IF_ERROR(sf.Number("falloff_exponent", &s.falloff_exponent));
      s.cone_half_angle_rad = DegToRad(cone_deg);
      l->spotlights.push_back(s);
    }
  }
  if (f.Has("gradient")) {
    IDI_RETURN_IF_ERROR(CheckSceneMap(node["gradient"], source, "lighting.gradient", {"origin_mm", "per_mm", "min_factor"}));
    SceneFields gf(node["gradient"], source, "lighting.gradient");
    IDI_RETURN_IF_ERROR(gf.Vector3("origin_mm", &l->gradient.origin));
    IDI_RETURN_IF_ERROR(gf.Vector3("per_mm", &l->gradient.gradient));
    IDI_RETURN_IF_ERROR(gf.Number("min_factor", &l->gradient.min_factor));
  }
  return Status::Ok();
}

Status ParseImageSections(const YAML::Node& root, const std::string& source, RenderOptions* r) {
  if (root["image"]) {
    IDI_RETURN_IF_ERROR(CheckSceneMap(root["image"], source, "image", {"exposure_dn", "color"}));
    SceneFields f(root["image"], source, "image");
    IDI_RETURN_IF_ERROR(f.Number("exposure_dn", &r->exposure_dn));
    IDI_RETURN_IF_ERROR(f.Bool("color", &r->color));
  }
  if (root["optics"]) {
    IDI_RETURN_IF_ERROR(CheckSceneMap(root["optics"], source, "optics", {"psf_sigma_px", "vignetting"}));
    SceneFields f(root["optics"], source, "optics");
    IDI_RETURN_IF_ERROR(f.Number("psf_sigma_px", &r->psf_sigma_px));
    IDI_RETURN_IF_ERROR(f.Number("vignetting", &r->vignetting));
  }
  if (root["noise"]) {
    IDI_RETURN_IF_ERROR(CheckSceneMap(root["noise"], source, "noise",
                                      {"enabled", "read_noise_dn", "gain_dn_per_electron", "black_level_dn"}));
    SceneFields f(root["noise"], source, "noise");
    IDI_RETURN_IF_ERROR(f.Bool("enabled", &r->sensor.noise));
    IDI_RETURN_IF_ERROR(f.Number("read_noise_dn", &r->sensor.read_noise_dn));
    IDI_RETURN_IF_ERROR(f.Number("gain_dn_per_electron", &r->sensor.gain_dn_per_electron));
    IDI_RETURN_IF_ERROR(f.Number("black_level_dn", &r->sensor.black_level_dn));
    // Named here (with the line) rather than by RenderOptions::Check, which cannot say where.
    for (const char* key : {"read_noise_dn", "gain_dn_per_electron", "black_level_dn"}) {
      if (f.Has(key) && root["noise"][key].as<double>() < 0) {
        return InvalidArgument(SceneWhere(source, root["noise"][key]) + ": noise." + key + " must be >= 0, got " +
                               root["noise"][key].Scalar());
      }
    }
  }
  return Status::Ok();
}

std::string ObjectLabel(std::size_t i, const std::string& name) {
  return "objects[" + std::to_string(i) + "] '" + name + "'";
}
std::string CameraLabel(std::size_t i, const std::string& name) {
  return "cameras[" + std::to_string(i) + "] '" + name + "'";
}

Status CheckShape(const ObjectShape& s, const std::string& where) {
  const char* kind = ObjectKindName(s.kind);
  if (s.kind == ObjectKind::kCylinder) {
    if (!(s.radius > 0) || !(s.size_z > 0)) {
      return InvalidArgument(where + ": a cylinder needs radius_mm > 0 and height_mm > 0");
    }
  } else if (!(s.size_x > 0) || !(s.size_y > 0) || !(s.size_z > 0)) {
    return InvalidArgument(where + ": a " + kind + " needs size_mm > 0 in x, y and z");
  }
  if (s.kind == ObjectKind::kLBracket && !(s.thickness > 0 && s.thickness < s.size_x && s.thickness < s.size_z)) {
    return InvalidArgument(where + ": thickness_mm must be positive and less than the foot and the leg");
  }
  if (s.kind == ObjectKind::kTriangularPrism && !(std::abs(s.apex_x) <= 2 * s.size_x)) {
    return InvalidArgument(where + ": apex_x_mm must lie within twice the width of the centre");
  }
  auto albedo_ok = [](double a) { return a >= 0 && a <= 1; };
  if (!albedo_ok(s.albedo)) return InvalidArgument(where + ": albedo must be in [0, 1]");
  for (const double a : s.face_albedos) {
    if (!albedo_ok(a)) return InvalidArgument(where + ": face_albedos must be in [0, 1]");
  }
  if (!s.face_albedos.empty() && s.face_albedos.size() != static_cast<std::size_t>(FaceCount(s.kind))) {
    return InvalidArgument(where + ": face_albedos must list " + std::to_string(FaceCount(s.kind)) + " albedos");
  }
  return Status::Ok();
}

Rigid3d TableObjectPose(const RotaryTable& table, const TableObjectSpec& o) {
  return Translation(Vec3d(table.top_centre_world + Vec3d(o.at_mm.x(), o.at_mm.y(), 0.0))) * RotZ(DegToRad(o.yaw_deg));
}

}  // namespace

Rigid3d SceneCameraSpec::CamFromWorld() const {
  // Optical axis z towards the target, image x = z x up (right), image y = z x x (down): image up is
  // the world's +z (§2.2's pixel convention: x right, y down), then the roll about z.
  const Vec3d z = (look_at_mm - position_mm).normalized();
  const Vec3d x = z.cross(Vec3d::UnitZ()).normalized();
  const Vec3d y = z.cross(x);
  Mat3d world_from_cam_r;
  world_from_cam_r.col(0) = x;
  world_from_cam_r.col(1) = y;
  world_from_cam_r.col(2) = z;
  Rigid3d world_from_cam;
  world_from_cam.rotation = world_from_cam_r * RotZ(DegToRad(roll_deg)).rotation;
  world_from_cam.translation = position_mm;
  return world_from_cam.Inverse();
}

Status WorkcellSceneSpec::Check() const {
  const std::string& s = source;
  if (!table.top_centre_world.allFinite() || !(table.radius_mm > 0) || !(table.thickness_mm > 0) ||
      !(table.albedo >= 0 && table.albedo <= 1)) {
    return InvalidArgument(s + ": table needs a finite centre_mm, radius_mm > 0, thickness_mm > 0, albedo in [0, 1]");
  }
  const double floor_z = CellTwinOptions::DefaultWorkcell().floor_height_mm;
  if (!(table.top_centre_world.z() > floor_z + table.thickness_mm)) {
    return InvalidArgument(s + ": table.centre_mm's z must be above the floor (z = " + FormatNumber(floor_z) +
                           " mm) by more than the table's thickness");
  }
  if (clutter < 0 || clutter > 100) return InvalidArgument(s + ": clutter must be in 0..100");
  std::set<std::string> names;
  for (std::size_t i = 0; i < objects.size(); ++i) {
    const TableObjectSpec& o = objects[i];
    const std::string where = s + ": " + ObjectLabel(i, o.name);
    if (o.name.empty()) return InvalidArgument(where + ": the name must not be empty");
    if (!names.insert(o.name).second) return InvalidArgument(where + ": the name is used by another object");
    if (o.name == "table" || o.name == "table-pedestal" || o.name == "floor" || o.name.rfind("clutter", 0) == 0) {
      return InvalidArgument(where + ": the name is taken by the cell (table, floor, walls, clutterN)");
    }
    IDI_RETURN_IF_ERROR(CheckShape(o.shape, where));
    if (!o.at_mm.allFinite() || !std::isfinite(o.yaw_deg)) return InvalidArgument(where + ": at_mm and yaw_deg must be finite");
    const double reach = o.at_mm.norm() + ObjectFootprintRadius(o.shape);
    if (reach > table.radius_mm) {
      return InvalidArgument(where + ": does not fit on the table (reaches " + FormatNumber(reach) +
                             " mm from its centre, the table's radius is " + FormatNumber(table.radius_mm) + " mm)");
    }
  }
  if (cameras.empty()) return InvalidArgument(s + ": cameras: at least one camera is needed");
  std::set<std::string> camera_names;
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const SceneCameraSpec& c = cameras[i];
    const std::string where = s + ": " + CameraLabel(i, c.name);
    if (c.name.empty() || c.name.find_first_of("/\\ ") != std::string::npos) {
      return InvalidArgument(where + ": the name must be non-empty without spaces or slashes (it names the image file)");
    }
    if (!camera_names.insert(c.name).second) return InvalidArgument(where + ": the name is used by another camera");
    const CameraModel& k = c.camera;
    if (k.width < 16 || k.height < 16 || k.width > 8192 || k.height > 8192) {
      return InvalidArgument(where + ": width_px and height_px must be in 16..8192");
    }
    for (const double p : k.params) {
      if (!std::isfinite(p)) return InvalidArgument(where + ": the intrinsics must be finite");
    }
    if (!(k.fx() > 0) || !(k.fy() > 0)) return InvalidArgument(where + ": fx_px and fy_px must be positive");
    if (const Status d = CheckDistortionCoversImage(k); !d.ok()) {
      return InvalidArgument(where + ": distortion: " + std::string(d.message()));
    }
    if (!c.position_mm.allFinite() || !c.look_at_mm.allFinite() || !std::isfinite(c.roll_deg)) {
      return InvalidArgument(where + ": position_mm, look_at_mm and roll_deg must be finite");
    }
    const Vec3d axis = c.look_at_mm - c.position_mm;
    if (axis.norm() < 1.0) return InvalidArgument(where + ": look_at_mm must differ from position_mm");
    if (axis.normalized().cross(Vec3d::UnitZ()).norm() < 1e-3) {
      return InvalidArgument(where + ": the optical axis must not be vertical (image up is the world's +z)");
    }
    // Every object must be in front of the camera (its centre at a positive depth).
    const Rigid3d cam_from_world = c.CamFromWorld();
    for (std::size_t j = 0; j < objects.size(); ++j) {
      const TableObjectSpec& o = objects[j];
      const Vec3d centre = TableObjectPose(table, o) * Vec3d(0, 0, 0.5 * ObjectHeight(o.shape));
      const double depth = (cam_from_world * centre).z();
      if (!(depth > render.near_clip)) {
        return InvalidArgument(s + ": " + ObjectLabel(j, o.name) + " is behind " + CameraLabel(i, c.name) + " (depth " +
                               FormatNumber(depth) + " mm along its optical axis)");
      }
    }
  }
  const Status light = lighting.Check();
  if (!light.ok()) return InvalidArgument(s + ": lighting: " + light.message());
  for (std::size_t i = 0; i < laser_spots.size(); ++i) {
    const LaserSpot& l = laser_spots[i];
    if (!l.center.allFinite() || !(l.sigma > 0) || !(l.peak >= 0 && l.peak <= 1e6) || !std::isfinite(l.sigma)) {
      return InvalidArgument(s + ": laser_spots[" + std::to_string(i) +
                             "]: needs a finite center_mm, sigma_mm > 0, peak in [0, 1e6]");
    }
  }
  const Status r = render.Check();
  if (!r.ok()) return InvalidArgument(s + ": image/optics/noise: " + r.message());
  return Status::Ok();
}

WorkcellSceneSpec StandardWorkcellScene() {
  WorkcellSceneSpec w;
  auto object = [](const char* name, ObjectKind kind, Vec3d size, Vec2d at, double yaw, std::vector<double> faces) {
    TableObjectSpec o;
    o.name = name;
    o.shape.kind = kind;
    o.shape.size_x = size.x();
    o.shape.size_y = size.y();
    o.shape.size_z = size.z();
    o.shape.face_albedos = std::move(faces);
    o.at_mm = at;
    o.yaw_deg = yaw;
    return o;
  };
  w.objects.push_back(object("box", ObjectKind::kBox, Vec3d(110, 80, 70), Vec2d(-110, -110), 20,
                             {0.5, 0.75, 0.9, 0.55, 0.65, 0.8}));
  w.objects.push_back(object("prism", ObjectKind::kTriangularPrism, Vec3d(90, 120, 70), Vec2d(120, -100), -30,
                             {0.5, 0.85, 0.6, 0.7, 0.75}));
  TableObjectSpec bracket = object("bracket", ObjectKind::kLBracket, Vec3d(100, 90, 80), Vec2d(-100, 120), 50,
                                   {0.6, 0.7, 0.85, 0.75, 0.9, 0.65, 0.8, 0.7});
  bracket.shape.thickness = 12;
  w.objects.push_back(bracket);
  TableObjectSpec cyl;
  cyl.name = "cylinder";
  cyl.shape.kind = ObjectKind::kCylinder;
  cyl.shape.radius = 40;
  cyl.shape.size_z = 110;
  cyl.shape.face_albedos = {0.65, 0.9, 0.5};
  cyl.at_mm = Vec2d(120, 120);
  w.objects.push_back(cyl);
  // The Biclops head 1.2 m from the table, looking 40 deg down along +x; the cameras 200 mm apart.
  const Vec3d target = w.table.top_centre_world + Vec3d(0, 0, 50);
  const double el = DegToRad(40.0);
  const Vec3d head = target - 1200.0 * Vec3d(std::cos(el), 0.0, -std::sin(el));
  for (const auto& [name, dy] : {std::pair<const char*, double>{"left", 100.0}, {"right", -100.0}}) {
    SceneCameraSpec c;
    c.name = name;
    c.camera = BiclopsNominalCamera(dy > 0 ? BiclopsSide::kLeft : BiclopsSide::kRight);
    c.position_mm = Vec3d(std::round(head.x()), std::round(head.y() + dy), std::round(head.z()));
    c.look_at_mm = target;
    w.cameras.push_back(c);
  }
  w.lighting.ambient = 0.35;
  w.lighting.directional = {{Vec3d(0.3, -0.5, 1.0), 0.6}};  // as the cell twin lights the cell
  return w;
}

Result<WorkcellSceneSpec> ParseWorkcellSceneYaml(const std::string& text, const std::string& source) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    return ParseError(source + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  WorkcellSceneSpec w = StandardWorkcellScene();
  w.source = source;
  if (root.IsNull()) return w;  // an empty file: the standard scene
  IDI_RETURN_IF_ERROR(CheckSceneMap(root, source, "",
                                    {"seed", "table", "objects", "clutter", "tiled_floor", "cameras", "lighting",
                                     "laser_spots", "image", "optics", "noise", "name", "comment"}));
  SceneFields top(root, source, "");
  if (top.Has("seed")) {
    IDI_ASSIGN_OR_RETURN(const double seed, SceneNumber(root["seed"], source, "seed"));
    if (seed < 0 || seed != std::floor(seed) || seed > 9e15) {
      return InvalidArgument(SceneWhere(source, root["seed"]) + ": seed must be a non-negative integer");
    }
    w.seed = static_cast<uint64_t>(seed);
  }
  if (top.Has("table")) {
    IDI_RETURN_IF_ERROR(CheckSceneMap(root["table"], source, "table", {"centre_mm", "radius_mm", "thickness_mm", "albedo"}));
    SceneFields f(root["table"], source, "table");
    IDI_RETURN_IF_ERROR(f.Vector3("centre_mm", &w.table.top_centre_world));
    IDI_RETURN_IF_ERROR(f.Number("radius_mm", &w.table.radius_mm));
    IDI_RETURN_IF_ERROR(f.Number("thickness_mm", &w.table.thickness_mm));
    IDI_RETURN_IF_ERROR(f.Number("albedo", &w.table.albedo));
  }
  if (top.Has("objects")) {
    const YAML::Node& list = root["objects"];
    if (!list.IsSequence() && !list.IsNull()) return InvalidArgument(SceneWhere(source, list) + ": objects must be a list");
    w.objects.clear();
    for (std::size_t i = 0; i < list.size(); ++i) {
      IDI_ASSIGN_OR_RETURN(TableObjectSpec o, ParseTableObject(list[i], source, "objects[" + std::to_string(i) + "]"));
      w.objects.push_back(std::move(o));
    }
  }
  IDI_RETURN_IF_ERROR(top.Integer("clutter", &w.clutter));
  IDI_RETURN_IF_ERROR(top.Bool("tiled_floor", &w.tiled_floor));
  if (top.Has("cameras")) {
    const YAML::Node& list = root["cameras"];
    if (!list.IsSequence()) return InvalidArgument(SceneWhere(source, list) + ": cameras must be a list");
    const std::vector<SceneCameraSpec> standard = w.cameras;
    w.cameras.clear();
    for (std::size_t i = 0; i < list.size(); ++i) {
      // A camera starts from the standard camera of the same index (or the last one), named camN.
      SceneCameraSpec defaults = standard[std::min(i, standard.size() - 1)];
      if (i >= standard.size()) defaults.name = "cam" + std::to_string(i);
      IDI_ASSIGN_OR_RETURN(SceneCameraSpec c, ParseCamera(list[i], source, "cameras[" + std::to_string(i) + "]", defaults));
      w.cameras.push_back(std::move(c));
    }
  }
  if (top.Has("lighting")) IDI_RETURN_IF_ERROR(ParseLighting(root["lighting"], source, &w.lighting));
  if (top.Has("laser_spots")) {
    const YAML::Node& list = root["laser_spots"];
    if (!list.IsSequence()) return InvalidArgument(SceneWhere(source, list) + ": laser_spots must be a list");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = "laser_spots[" + std::to_string(i) + "]";
      IDI_RETURN_IF_ERROR(CheckSceneMap(list[i], source, p, {"center_mm", "sigma_mm", "peak"}));
      LaserSpot l;
      l.sigma = 2.0;
      l.peak = 60.0;
      SceneFields f(list[i], source, p);
      if (!f.Has("center_mm")) return InvalidArgument(SceneWhere(source, list[i]) + ": " + p + " needs center_mm");
      IDI_RETURN_IF_ERROR(f.Vector3("center_mm", &l.center));
      IDI_RETURN_IF_ERROR(f.Number("sigma_mm", &l.sigma));
      IDI_RETURN_IF_ERROR(f.Number("peak", &l.peak));
      w.laser_spots.push_back(l);
    }
  }
  IDI_RETURN_IF_ERROR(ParseImageSections(root, source, &w.render));
  IDI_RETURN_IF_ERROR(w.Check());
  return w;
}

Result<WorkcellSceneSpec> LoadWorkcellSceneFile(const std::string& path) {
  auto text = ReadFile(path);
  if (!text.ok()) return NotFound(path + ": cannot read the scene file (" + text.status().message() + ")");
  return ParseWorkcellSceneYaml(*text, path);
}

Result<BuiltWorkcellScene> BuildWorkcellScene(const WorkcellSceneSpec& spec) {
  IDI_RETURN_IF_ERROR(spec.Check());
  CellTwinOptions o;
  o.table = spec.table;
  o.clutter_objects = spec.clutter;
  o.tiled_floor = spec.tiled_floor;
  o.seed = spec.seed;
  o.render = spec.render;
  IDI_RETURN_IF_ERROR(o.Check());
  // The cell twin builds the cell (walls, tiled floor, table, clutter) exactly as its cameras see it.
  const CellTwin twin(o);
  BuiltWorkcellScene out;
  for (const TableObjectSpec& t : spec.objects) {
    CellObject c;
    c.name = t.name;
    c.shape = t.shape;
    c.world_from_object = TableObjectPose(spec.table, t);
    out.objects.push_back(c);
  }
  out.scene = twin.CurrentScene();
  for (const CellObject& c : out.objects) AddObjectToScene(c, &out.scene);
  out.scene.lighting = spec.lighting;
  out.scene.laser_spots = spec.laser_spots;
  const Status scene_ok = out.scene.Check();
  if (!scene_ok.ok()) return InvalidArgument(spec.source + ": " + scene_ok.message());
  for (std::size_t i = 0; i < spec.cameras.size(); ++i) {
    SceneView v;
    v.name = spec.cameras[i].name;
    v.camera = spec.cameras[i].camera;
    v.cam_from_world = spec.cameras[i].CamFromWorld();
    v.render = spec.render;
    v.render.seed = spec.seed * 1000003ULL + i;
    out.views.push_back(v);
  }
  return out;
}

}  // namespace idi::sim
