// TRACK.yaml (DESIGN.md §6) and the twin's scene of a taped track.
//
// INTERIM: the renderer's engineer owns TRACK.yaml loading and the track scenes (shared/sim/scene);
// until that lands, this is the closed loop's own minimal version, kept apart so it can be swapped
// for theirs. Format:
//   tape_width_m: 0.05
//   points_m: [[x, y], ...]         centre line on the ground, in order; the track ends at the last point
//   start: {x_m, y_m, yaw_rad}      optional (default: the first point, facing the second); within 1 m of
//                                   the first point, |yaw_rad| <= 4 pi
//   speed_mps: 0.5                  optional cruise speed
//   gaps_m: [[from, to], ...]       optional stretches (arc length from the first point) without tape
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "shared/geometry/rigid3.h"
#include "shared/sim/render/scene.h"
#include "shared/util/status.h"

namespace idi::rmp {

struct TrackSpec {
  std::string source;  // file name, for messages
  double tape_width_m = 0.05;
  std::vector<Vec2d> points_m;
  bool has_start = false;
  double start_x_m = 0.0, start_y_m = 0.0, start_yaw_rad = 0.0;
  int start_line = 0;      // start's line in the file, for messages (0: not read from one)
  double speed_mps = 0.0;  // 0: not given
  std::vector<std::pair<double, double>> gaps_m;

  double Length() const;
  // The start pose (given, or the first point facing the second).
  void StartPose(double* x, double* y, double* yaw) const;
  Status Check() const;
};

Result<TrackSpec> ParseTrackYaml(const std::string& text, const std::string& source);
Result<TrackSpec> LoadTrackFile(const std::string& path);

struct TrackSceneOptions {
  double floor_albedo = 0.35;
  double floor_noise = 0.15;  // texture amplitude
  double floor_noise_scale_m = 0.2;
  double tape_albedo = 0.85;
  // Stretches (arc length) where something covers the tape: a dark mat lies over it.
  std::vector<std::pair<double, double>> covered_m;
  double cover_width_m = 0.3;
  double cover_albedo = 0.22;
  uint64_t seed = 1;
};

// Floor, tape pieces (split at the gaps) and covers. InvalidArgument naming the file, the point and its
// coordinates when the twin cannot lay the tape: a turn sharper than 150 deg, or a segment too short for
// the mitred turns at its ends.
Result<sim::Scene> BuildTrackScene(const TrackSpec& track, const TrackSceneOptions& options = {});

// The centre line split into the stretches where tape lies (not in a gap or covered).
std::vector<std::vector<Vec2d>> TapedStretches(const std::vector<Vec2d>& points,
                                               const std::vector<std::pair<double, double>>& without_tape);

}  // namespace idi::rmp
