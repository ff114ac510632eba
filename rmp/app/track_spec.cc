#include "rmp/app/track_spec.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "shared/runtime/yaml_error.h"
#include "shared/sim/render/shapes.h"
#include "shared/util/atomic_file.h"

namespace idi::rmp {
namespace {

std::string Where(const std::string& source, const YAML::Node& node) {
  return source + ":" + std::to_string(node.Mark().line + 1);
}

Result<double> Number(const YAML::Node& node, const std::string& source, const std::string& key) {
  try {
    const double v = node.as<double>();
    if (!std::isfinite(v)) return InvalidArgument(Where(source, node) + ": " + key + " is not a finite number");
    return v;
  } catch (const YAML::Exception&) {
    return InvalidArgument(Where(source, node) + ": " + key + " must be a number");
  }
}

Result<Vec2d> Pair(const YAML::Node& node, const std::string& source, const std::string& key) {
  if (!node.IsSequence() || node.size() != 2) return InvalidArgument(Where(source, node) + ": " + key + " must be [a, b]");
  IDI_ASSIGN_OR_RETURN(const double a, Number(node[0], source, key));
  IDI_ASSIGN_OR_RETURN(const double b, Number(node[1], source, key));
  return Vec2d(a, b);
}

}  // namespace

double TrackSpec::Length() const {
  double len = 0.0;
  for (std::size_t i = 1; i < points_m.size(); ++i) len += (points_m[i] - points_m[i - 1]).norm();
  return len;
}

void TrackSpec::StartPose(double* x, double* y, double* yaw) const {
  if (has_start) {
    *x = start_x_m;
    *y = start_y_m;
    *yaw = start_yaw_rad;
    return;
  }
  const Vec2d d = points_m[1] - points_m[0];
  *x = points_m[0].x();
  *y = points_m[0].y();
  *yaw = std::atan2(d.y(), d.x());
}

Status TrackSpec::Check() const {
  if (!(tape_width_m > 0.005 && tape_width_m < 0.5)) return InvalidArgument(source + ": tape_width_m must be in (0.005, 0.5)");
  if (points_m.size() < 2) return InvalidArgument(source + ": points_m needs at least two points");
  for (std::size_t i = 1; i < points_m.size(); ++i) {
    if ((points_m[i] - points_m[i - 1]).norm() < 1e-3) {
      return InvalidArgument(source + ": points_m[" + std::to_string(i) + "] repeats the point before it");
    }
  }
  if (!(speed_mps >= 0 && speed_mps <= 3.0)) return InvalidArgument(source + ": speed_mps must be in [0, 3]");
  const double len = Length();
  for (std::size_t i = 0; i < gaps_m.size(); ++i) {
    if (!(gaps_m[i].first >= 0 && gaps_m[i].second > gaps_m[i].first && gaps_m[i].second <= len)) {
      return InvalidArgument(source + ": gaps_m[" + std::to_string(i) + "] must satisfy 0 <= from < to <= track length (" +
                             std::to_string(len) + " m)");
    }
  }
  return Status::Ok();
}

Result<TrackSpec> ParseTrackYaml(const std::string& text, const std::string& source) try {
  const YAML::Node root = YAML::Load(text);
  if (!root.IsMap()) return ParseError(source + ": expected a map with tape_width_m and points_m");
  TrackSpec t;
  t.source = source;
  std::set<std::string> seen;
  for (const auto& kv : root) {
    const std::string key = kv.first.as<std::string>();
    const YAML::Node& v = kv.second;
    // A repeated points_m would append a second track to the first.
    if (!seen.insert(key).second) return InvalidArgument(Where(source, kv.first) + ": key '" + key + "' given twice");
    if (key == "tape_width_m") {
      IDI_ASSIGN_OR_RETURN(t.tape_width_m, Number(v, source, key));
    } else if (key == "speed_mps") {
      IDI_ASSIGN_OR_RETURN(t.speed_mps, Number(v, source, key));
    } else if (key == "points_m" || key == "gaps_m") {
      if (!v.IsSequence()) return InvalidArgument(Where(source, v) + ": " + key + " must be a list of [a, b]");
      for (std::size_t i = 0; i < v.size(); ++i) {
        IDI_ASSIGN_OR_RETURN(const Vec2d p, Pair(v[i], source, key + "[" + std::to_string(i) + "]"));
        if (key == "points_m") t.points_m.push_back(p); else t.gaps_m.emplace_back(p.x(), p.y());
      }
    } else if (key == "start") {
      if (!v.IsMap()) return InvalidArgument(Where(source, v) + ": start must be {x_m, y_m, yaw_rad}");
      t.has_start = true;
      for (const auto& sk : v) {
        const std::string k = sk.first.as<std::string>();
        IDI_ASSIGN_OR_RETURN(const double num, Number(sk.second, source, "start." + k));
        if (k == "x_m") t.start_x_m = num;
        else if (k == "y_m") t.start_y_m = num;
        else if (k == "yaw_rad") t.start_yaw_rad = num;
        else return InvalidArgument(Where(source, sk.first) + ": unknown key start." + k + " (x_m, y_m, yaw_rad)");
      }
    } else if (key == "name" || key == "comment") {
      continue;
    } else {
      return InvalidArgument(Where(source, kv.first) + ": unknown key '" + key + "'");
    }
  }
  if (!root["points_m"]) return InvalidArgument(source + ": missing points_m");
  IDI_RETURN_IF_ERROR(t.Check());
  return t;
} catch (const YAML::Exception& e) {
  return YamlError(source, e);
}

Result<TrackSpec> LoadTrackFile(const std::string& path) {
  auto text = ReadFile(path);
  if (!text.ok()) return NotFound(path + ": cannot read the track file (" + text.status().message() + ")");
  return ParseTrackYaml(*text, path);
}

std::vector<std::vector<Vec2d>> TapedStretches(const std::vector<Vec2d>& points,
                                               const std::vector<std::pair<double, double>>& without_tape) {
  // Arc length of every vertex, then cut the polyline at every gap boundary.
  std::vector<double> s(points.size(), 0.0);
  for (std::size_t i = 1; i < points.size(); ++i) s[i] = s[i - 1] + (points[i] - points[i - 1]).norm();
  const double len = s.back();
  auto at = [&](double sa) {
    sa = std::clamp(sa, 0.0, len);
    std::size_t i = 1;
    while (i + 1 < points.size() && s[i] < sa) ++i;
    const double f = (sa - s[i - 1]) / std::max(1e-12, s[i] - s[i - 1]);
    return Vec2d(points[i - 1] + f * (points[i] - points[i - 1]));
  };
  std::vector<std::pair<double, double>> gaps = without_tape;
  std::sort(gaps.begin(), gaps.end());
  std::vector<std::pair<double, double>> taped;
  double cursor = 0.0;
  for (const auto& [a, b] : gaps) {
    if (a > cursor) taped.emplace_back(cursor, a);
    cursor = std::max(cursor, b);
  }
  if (cursor < len) taped.emplace_back(cursor, len);
  std::vector<std::vector<Vec2d>> out;
  for (const auto& [a, b] : taped) {
    if (b - a < 1e-3) continue;
    std::vector<Vec2d> piece = {at(a)};
    for (std::size_t i = 1; i + 1 < points.size(); ++i) {
      if (s[i] > a + 1e-9 && s[i] < b - 1e-9) piece.push_back(points[i]);
    }
    piece.push_back(at(b));
    out.push_back(std::move(piece));
  }
  return out;
}

Result<sim::Scene> BuildTrackScene(const TrackSpec& track, const TrackSceneOptions& o) {
  IDI_RETURN_IF_ERROR(track.Check());
  sim::Scene scene;
  // A floor large enough around the track.
  Vec2d lo = track.points_m[0], hi = lo;
  for (const Vec2d& p : track.points_m) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Vec2d c = 0.5 * (lo + hi);
  const Vec2d half = 0.5 * (hi - lo) + Vec2d(8.0, 8.0);
  sim::Material floor = sim::Gray(o.floor_albedo);
  floor.texture.noise_amplitude = o.floor_noise;
  floor.texture.noise_scale = o.floor_noise_scale_m;
  floor.texture.seed = o.seed;
  scene.solids.push_back(sim::MakeRectangle("floor", Vec3d(c.x(), c.y(), 0.0), Vec3d::UnitX(), Vec3d::UnitY(), half.x(), half.y(), floor));
  std::vector<std::pair<double, double>> without = track.gaps_m;
  int k = 0;
  for (const auto& stretch : TapedStretches(track.points_m, without)) {
    // A stretch shorter than its mitred joints allow is laid as its straight chord.
    auto strip = sim::MakeTapeStrip("tape" + std::to_string(k++), stretch, track.tape_width_m, 0.0, sim::Gray(o.tape_albedo));
    if (!strip.ok()) {
      auto chord = sim::MakeTapeStrip("tape" + std::to_string(k++), {stretch.front(), stretch.back()}, track.tape_width_m, 0.0,
                                      sim::Gray(o.tape_albedo));
      if (!chord.ok()) return InvalidArgument(track.source + ": cannot lay the tape: " + strip.status().message());
      scene.solids.push_back(*chord);
      continue;
    }
    scene.solids.push_back(*strip);
  }
  // Covers: a mat over the tape along the covered stretch (on top of it: layer 2).
  for (const auto& [a, b] : o.covered_m) {
    for (const auto& stretch : TapedStretches(track.points_m, {{0.0, a}, {b, track.Length()}})) {
      auto mat = sim::MakeTapeStrip("cover", stretch, o.cover_width_m, 0.0, sim::Gray(o.cover_albedo));
      if (!mat.ok()) return InvalidArgument(track.source + ": cannot lay the cover: " + mat.status().message());
      mat->layer = 2;
      scene.solids.push_back(*mat);
    }
  }
  return scene;
}

}  // namespace idi::rmp
