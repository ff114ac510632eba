// `idi-rmp sim render [--track FILE] --out DIR [--views N] [--config FILE] [--json]`: example images of
// the vehicle twin - both fixed cameras rendering the taped track (rmp/app/track_spec.h) from the
// vehicle standing at N places along it - each as <view>-<camera>.png with its ground truth
// <view>-<camera>.json beside it (shared/sim/scene/image_files.h).
#pragma once

#include <string>
#include <vector>

#include "rmp/app/rmp_config.h"
#include "rmp/app/track_spec.h"
#include "shared/runtime/cli.h"
#include "shared/sim/scene/image_files.h"

namespace idi::rmp {

// The standard track (rmp/app/tracks/standard.yaml), built in so `sim render` works without files.
TrackSpec StandardTrack();

struct TrackRenderOptions {
  int views = 3;  // vehicle poses: the start, then evenly along the track up to 1 m before its end
};

struct TrackView {
  double s_m = 0.0;  // arc length along the centre line
  double x_m = 0.0, y_m = 0.0, yaw_rad = 0.0;
  std::vector<sim::WrittenImage> images;  // left, right
};

// Renders the rig's cameras of `config` (rig, sim.render, sim.scene, sim.seed) at each view into
// `out_dir` (created when missing).
Result<std::vector<TrackView>> RenderTrackViews(const TrackSpec& track, const RmpConfig& config,
                                                const TrackRenderOptions& options, const std::string& out_dir);

// Adds `sim render` under `sim` (AddSimRunCommand's return value).
void AddSimRenderCommand(CliApp& cli, CLI::App* sim);

}  // namespace idi::rmp
