// Ground truth as JSON (written next to each rendered PNG):
// {"width", "height", "distorted": bool,
//  "camera": {"intrinsics": [fx, fy, cx, cy, k1, k2, p1, p2, k3], "cam_from_world": [3x4 row-major]},
//  "lines": [{"id", "object", "kind": "edge"|"silhouette", "vertices": [v1, v2], "p1": [x, y], "p2": [x, y],
//             "p1_world": [x, y, z], "p2_world": [x, y, z], "normal": [nx, ny], "offset": d,
//             "contrast_dn", "length_px"}],
//  "junctions": [{"id", "type", "is_vertex", "object", "vertex", "xy": [x, y], "point_world": [x, y, z],
//                 "lines": [ids]}],
//  "spots": [{"xy": [x, y], "centroid_xy": [x, y], "center_world": [x, y, z], "visible", "sigma_px"}],
//  "curves": [{"object", "kind", "points": [[x, y], ...]}]}
// Pixel coordinates follow the camera convention (integer = pixel centre). A line's normal/offset
// (normal . x = offset, unit normal) are in undistorted pixel coordinates: the image line itself when
// "distorted" is false, otherwise the line the edge becomes after removing the lens distortion.
#include <nlohmann/json.hpp>

#include "shared/sim/render/render.h"

namespace idi::sim {
namespace {

nlohmann::json J2(const Vec2d& v) { return {v.x(), v.y()}; }
nlohmann::json J3(const Vec3d& v) { return {v.x(), v.y(), v.z()}; }

}  // namespace

std::string GroundTruthToJson(const GroundTruth& truth) {
  nlohmann::json j;
  j["width"] = truth.width;
  j["height"] = truth.height;
  j["distorted"] = truth.camera.HasDistortion();
  nlohmann::json cam;
  cam["intrinsics"] = std::vector<double>(truth.camera.params.begin(), truth.camera.params.end());
  std::vector<double> m;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m.push_back(truth.cam_from_world.rotation(r, c));
    m.push_back(truth.cam_from_world.translation(r));
  }
  cam["cam_from_world"] = m;
  j["camera"] = cam;
  nlohmann::json lines = nlohmann::json::array();
  for (const TruthLine& l : truth.lines) {
    lines.push_back({{"id", l.id},
                     {"object", l.object},
                     {"kind", l.kind},
                     {"vertices", {l.v1, l.v2}},
                     {"p1", J2(l.p1_px)},
                     {"p2", J2(l.p2_px)},
                     {"p1_world", J3(l.p1_world)},
                     {"p2_world", J3(l.p2_world)},
                     {"normal", J2(l.normal)},
                     {"offset", l.offset},
                     {"contrast_dn", l.contrast_dn},
                     {"length_px", l.length_px}});
  }
  j["lines"] = lines;
  nlohmann::json junctions = nlohmann::json::array();
  for (const TruthJunction& t : truth.junctions) {
    junctions.push_back({{"id", t.id},
                         {"type", t.type},
                         {"is_vertex", t.is_vertex},
                         {"object", t.object},
                         {"vertex", t.vertex},
                         {"xy", J2(t.xy_px)},
                         {"point_world", J3(t.point_world)},
                         {"lines", t.lines}});
  }
  j["junctions"] = junctions;
  nlohmann::json spots = nlohmann::json::array();
  for (const TruthSpot& s : truth.spots) {
    spots.push_back({{"xy", J2(s.xy_px)},
                     {"centroid_xy", J2(s.centroid_px)},
                     {"center_world", J3(s.center_world)},
                     {"visible", s.visible},
                     {"sigma_px", s.sigma_px}});
  }
  j["spots"] = spots;
  nlohmann::json curves = nlohmann::json::array();
  for (const TruthCurve& c : truth.curves) {
    nlohmann::json pts = nlohmann::json::array();
    for (const Vec2d& p : c.points_px) pts.push_back(J2(p));
    curves.push_back({{"object", c.object}, {"kind", c.kind}, {"points", pts}});
  }
  j["curves"] = curves;
  return j.dump(1);
}

}  // namespace idi::sim
