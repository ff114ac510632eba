#include "rmp/app/track_spec.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>

#include "shared/runtime/yaml_error.h"
#include "shared/sim/render/shapes.h"
#include "shared/util/atomic_file.h"
#include "shared/util/units.h"

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
  if (!node.IsSequence() || node.size() != 2)
    return InvalidArgument(Where(source, node) + ": " + key + " must be [a, b]");
  IDI_ASSIGN_OR_RETURN(const double a, Number(node[0], source, key));
  IDI_ASSIGN_OR_RETURN(const double b, Number(node[1], source, key));
  return Vec2d(a, b);
}

// Defined with the scene's code below.
std::vector<std::pair<double, double>> TapedRanges(double length,
                                                   const std::vector<std::pair<double, double>>& without);
std::string PointName(const std::vector<Vec2d>& points, std::size_t i);

// Limits of a track the twin lays and the vehicle drives: the tape is a strip at least this long (and
// longer than it is wide: the perception pairs its long edges), and a given start lies this close to the
// first point and heads within this many radians of zero (a heading, not a count of turns).
constexpr double kMinTrackLengthM = 0.1;
constexpr double kMaxStartDistanceM = 1.0;
constexpr double kMaxStartYawRad = 4 * std::numbers::pi;

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
  if (!(tape_width_m > 0.005 && tape_width_m < 0.5))
    return InvalidArgument(source + ": tape_width_m must be in (0.005, 0.5)");
  if (points_m.size() < 2) return InvalidArgument(source + ": points_m needs at least two points");
  for (std::size_t i = 1; i < points_m.size(); ++i) {
    if ((points_m[i] - points_m[i - 1]).norm() < 1e-3) {
      return InvalidArgument(source + ": points_m[" + std::to_string(i) + "] repeats the point before it");
    }
  }
  if (!(speed_mps >= 0 && speed_mps <= 3.0)) return InvalidArgument(source + ": speed_mps must be in [0, 3]");
  const double len = Length();
  if (!(len >= kMinTrackLengthM && len > tape_width_m)) {
    return InvalidArgument(
        fmt::format("{}: points_m: the track is {:g} m long; a track must be at least {:g} m and "
                    "longer than its tape is wide (tape_width_m {:g})",
                    source,
                    len,
                    kMinTrackLengthM,
                    tape_width_m));
  }
  for (std::size_t i = 0; i < gaps_m.size(); ++i) {
    if (!(gaps_m[i].first >= 0 && gaps_m[i].second > gaps_m[i].first && gaps_m[i].second <= len)) {
      return InvalidArgument(source + ": gaps_m[" + std::to_string(i) +
                             "] must satisfy 0 <= from < to <= track length (" + FormatNumber(len) + " m)");
    }
  }
  // The tape the gaps leave: as much as a track needs (TapedRanges keeps pieces down to 1 mm).
  double taped = 0;
  for (const auto& [a, b] : TapedRanges(len, gaps_m)) taped += b - a;
  if (!(taped >= kMinTrackLengthM - 1e-9 && taped > tape_width_m)) {  // 1e-9: 1 - 0.9 is 0.0999...
    return InvalidArgument(fmt::format(
        "{}: gaps_m cover the whole track ({:g} m) but {:g} m: at least {:g} m of tape, and more than its width, "
        "must be laid",
        source,
        len,
        taped,
        std::max(kMinTrackLengthM, tape_width_m)));
  }
  if (has_start) {
    const std::string where = start_line > 0 ? fmt::format("{}:{}", source, start_line) : source;
    if (!(std::abs(start_yaw_rad) <= kMaxStartYawRad)) {
      return InvalidArgument(
          fmt::format("{}: start.yaw_rad {:g} must be within +-4 pi (a heading in radians)", where, start_yaw_rad));
    }
    const double d = std::hypot(start_x_m - points_m[0].x(), start_y_m - points_m[0].y());
    if (!(d <= kMaxStartDistanceM)) {
      return InvalidArgument(
          fmt::format("{}: start ({:g}, {:g}) is {:g} m from the track's first point {}; it must be "
                      "within {:g} m of it",
                      where,
                      start_x_m,
                      start_y_m,
                      d,
                      PointName(points_m, 0),
                      kMaxStartDistanceM));
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
        if (key == "points_m")
          t.points_m.push_back(p);
        else
          t.gaps_m.emplace_back(p.x(), p.y());
      }
    } else if (key == "start") {
      if (!v.IsMap()) return InvalidArgument(Where(source, v) + ": start must be {x_m, y_m, yaw_rad}");
      t.has_start = true;
      t.start_line = v.Mark().line + 1;
      std::set<std::string> start_seen;
      for (const auto& sk : v) {
        const std::string k = sk.first.as<std::string>();
        if (!start_seen.insert(k).second)
          return InvalidArgument(Where(source, sk.first) + ": key 'start." + k + "' given twice");
        IDI_ASSIGN_OR_RETURN(const double num, Number(sk.second, source, "start." + k));
        if (k == "x_m")
          t.start_x_m = num;
        else if (k == "y_m")
          t.start_y_m = num;
        else if (k == "yaw_rad")
          t.start_yaw_rad = num;
        else
          return InvalidArgument(Where(source, sk.first) + ": unknown key start." + k + " (x_m, y_m, yaw_rad)");
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

namespace {

// The arc length of every point of a polyline.
std::vector<double> ArcLengths(const std::vector<Vec2d>& points) {
  std::vector<double> s(points.size(), 0.0);
  for (std::size_t i = 1; i < points.size(); ++i) s[i] = s[i - 1] + (points[i] - points[i - 1]).norm();
  return s;
}

// The arc-length intervals of [0, length] outside `without` (unsorted, may overlap), each at least 1 mm.
std::vector<std::pair<double, double>> TapedRanges(double length,
                                                   const std::vector<std::pair<double, double>>& without) {
  std::vector<std::pair<double, double>> gaps = without;
  std::sort(gaps.begin(), gaps.end());
  std::vector<std::pair<double, double>> taped;
  double cursor = 0.0;
  auto add = [&taped](double a, double b) {
    if (b - a >= 1e-3) taped.emplace_back(a, b);
  };
  for (const auto& [a, b] : gaps) {
    if (a > cursor) add(cursor, a);
    cursor = std::max(cursor, b);
  }
  if (cursor < length) add(cursor, length);
  return taped;
}

// Whether the point at arc length `s` lies strictly inside the taped range [a, b] (it is a point of that
// stretch, not cut off by a gap or at its end).
bool InsideRange(double s, double a, double b) { return s > a + 1e-9 && s < b - 1e-9; }

}  // namespace

std::vector<std::vector<Vec2d>> TapedStretches(const std::vector<Vec2d>& points,
                                               const std::vector<std::pair<double, double>>& without_tape) {
  // Arc length of every vertex, then cut the polyline at every gap boundary.
  const std::vector<double> s = ArcLengths(points);
  const double len = s.back();
  auto at = [&](double sa) {
    sa = std::clamp(sa, 0.0, len);
    std::size_t i = 1;
    while (i + 1 < points.size() && s[i] < sa) ++i;
    const double f = (sa - s[i - 1]) / std::max(1e-12, s[i] - s[i - 1]);
    return Vec2d(points[i - 1] + f * (points[i] - points[i - 1]));
  };
  std::vector<std::vector<Vec2d>> out;
  for (const auto& [a, b] : TapedRanges(len, without_tape)) {
    std::vector<Vec2d> piece = {at(a)};
    for (std::size_t i = 1; i + 1 < points.size(); ++i) {
      if (InsideRange(s[i], a, b)) piece.push_back(points[i]);
    }
    piece.push_back(at(b));
    out.push_back(std::move(piece));
  }
  return out;
}

namespace {

// sim::MakeTapeStrip mitres the tape at each point of its centre line and turns it by at most 150 deg there.
constexpr double kMaxTapeTurnDeg = 150.0;

std::string PointName(const std::vector<Vec2d>& points, std::size_t i) {
  return fmt::format("points_m[{}] ({:g}, {:g})", i, points[i].x(), points[i].y());
}

// tan(turn / 2) at each point, signed (left turns positive), 0 at the two ends: a mitred joint reaches
// half the tape width times this along the segments on either side of it.
std::vector<double> HalfTurnTangents(const std::vector<Vec2d>& points) {
  std::vector<double> t(points.size(), 0.0);
  for (std::size_t i = 1; i + 1 < points.size(); ++i) {
    const Vec2d a = points[i] - points[i - 1], b = points[i + 1] - points[i];
    t[i] = std::tan(0.5 * std::atan2(a.x() * b.y() - a.y() * b.x(), a.dot(b)));
  }
  return t;
}

// The length a segment needs so that the mitred joints at its ends (half-turn tangents ta, tb) do not
// cross on either edge of a tape of `width` (the condition sim::MakeTapeStrip checks).
double LengthNeeded(double width, double ta, double tb) { return 0.5 * width * std::abs(ta + tb); }
bool SegmentLays(double length, double needed) { return length * (1.0 - 1e-6) > needed; }

// The twin lays every taped stretch as one strip or refuses: a sharper turn, or a segment too short for
// its turns, would otherwise leave a strip it cannot lay (once laid as a silent straight chord). Checked
// per stretch (TapedStretches), on the track's own points and segments so that the message can name
// them: a point in a gap does not turn the tape, and one at a gap's edge is a square end of it. The
// partial segments at a gap's edge are LayStretch's.
Status CheckTwinCanLay(const TrackSpec& track) {
  const std::vector<Vec2d>& p = track.points_m;
  const std::vector<double> s = ArcLengths(p);
  const std::vector<double> t = HalfTurnTangents(p);
  for (const auto& [a, b] : TapedRanges(s.back(), track.gaps_m)) {
    // A point where this stretch turns (not one of its ends).
    auto turns_at = [&, a = a, b = b](std::size_t i) { return i > 0 && i + 1 < p.size() && InsideRange(s[i], a, b); };
    for (std::size_t i = 1; i + 1 < p.size(); ++i) {
      if (!turns_at(i)) continue;
      const Vec2d u = p[i] - p[i - 1], v = p[i + 1] - p[i];
      const double turn_deg = RadToDeg(std::abs(std::atan2(u.x() * v.y() - u.y() * v.x(), u.dot(v))));
      if (turn_deg > kMaxTapeTurnDeg) {
        return InvalidArgument(
            fmt::format("{}: the track turns by {:.1f} deg at {}; the twin lays tape around turns of at most {:g} "
                        "deg (split a sharper corner into gentler turns)",
                        track.source,
                        turn_deg,
                        PointName(p, i),
                        kMaxTapeTurnDeg));
      }
    }
    for (std::size_t i = 0; i + 1 < p.size(); ++i) {
      if (s[i] < a - 1e-9 || s[i + 1] > b + 1e-9) continue;  // not wholly taped in this stretch
      const double length = (p[i + 1] - p[i]).norm();
      const double needed =
          LengthNeeded(track.tape_width_m, turns_at(i) ? t[i] : 0.0, turns_at(i + 1) ? t[i + 1] : 0.0);
      if (!SegmentLays(length, needed)) {
        return InvalidArgument(fmt::format(
            "{}: the segment from {} to {} is {:g} m long; the twin's tape (tape_width_m {:g}) needs more than "
            "{:g} m there to turn at its ends",
            track.source,
            PointName(p, i),
            PointName(p, i + 1),
            length,
            track.tape_width_m,
            needed));
      }
    }
  }
  return Status::Ok();
}

// Lays one taped stretch. Its turns and whole segments are the track's (CheckTwinCanLay passed), but a
// gap ending just before a corner leaves an end segment too short to turn there: that segment is laid as
// a straight piece of its own, square ends meeting at the corner. The piece that remains then starts (or
// ends) square at that corner, and its new end segment may be too short for the turn at its other end:
// end segments are peeled until the rest lays.
Status LayStretch(const TrackSpec& track,
                  const std::vector<Vec2d>& stretch,
                  const sim::Material& material,
                  int* k,
                  sim::Scene* scene) {
  using Piece = std::vector<Vec2d>;
  // MakeTapeStrip's reason, with the start of the piece that it refused.
  auto lay = [&](const Piece& piece, bool report) -> Result<bool> {
    auto strip = sim::MakeTapeStrip("tape" + std::to_string(*k), piece, track.tape_width_m, 0.0, material);
    if (strip.ok()) {
      ++*k;
      scene->solids.push_back(std::move(*strip));
      return true;
    }
    if (!report) return false;
    return InvalidArgument(fmt::format("{}: cannot lay the tape that starts at ({:g}, {:g}): {}",
                                       track.source,
                                       piece.front().x(),
                                       piece.front().y(),
                                       strip.status().message()));
  };
  const double w = track.tape_width_m;
  std::size_t begin = 0, end = stretch.size() - 1;  // the piece stretch[begin..end] still to lay
  std::vector<Piece> tail;                          // end segments peeled off, last first
  while (true) {
    const Piece piece(stretch.begin() + static_cast<std::ptrdiff_t>(begin),
                      stretch.begin() + static_cast<std::ptrdiff_t>(end) + 1);
    const std::size_t n = piece.size();
    IDI_ASSIGN_OR_RETURN(const bool laid, lay(piece, n < 3));  // a straight piece has nothing to peel
    if (laid) break;
    const std::vector<double> t = HalfTurnTangents(piece);
    if (!SegmentLays((piece[1] - piece[0]).norm(), LengthNeeded(w, 0.0, t[1]))) {
      IDI_RETURN_IF_ERROR(lay({piece[0], piece[1]}, true).status());
      ++begin;
    } else if (!SegmentLays((piece[n - 1] - piece[n - 2]).norm(), LengthNeeded(w, t[n - 2], 0.0))) {
      tail.push_back({piece[n - 2], piece[n - 1]});
      --end;
    } else {
      return lay(piece, true).status();  // not its ends: the reason, named
    }
  }
  for (auto it = tail.rbegin(); it != tail.rend(); ++it) IDI_RETURN_IF_ERROR(lay(*it, true).status());
  return Status::Ok();
}

}  // namespace

Result<sim::Scene> BuildTrackScene(const TrackSpec& track, const TrackSceneOptions& o) {
  IDI_RETURN_IF_ERROR(track.Check());
  IDI_RETURN_IF_ERROR(CheckTwinCanLay(track));
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
  scene.solids.push_back(
      sim::MakeRectangle("floor", Vec3d(c.x(), c.y(), 0.0), Vec3d::UnitX(), Vec3d::UnitY(), half.x(), half.y(), floor));
  int k = 0;
  for (const auto& stretch : TapedStretches(track.points_m, track.gaps_m)) {
    IDI_RETURN_IF_ERROR(LayStretch(track, stretch, sim::Gray(o.tape_albedo), &k, &scene));
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
