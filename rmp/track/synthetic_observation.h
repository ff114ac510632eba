// An ideal perception for tests and studies of the track model and the planner without images: the
// true centre line clipped to what the cameras see, with optional noise. Never used by the binary's
// pipeline (which perceives the track from images).
#pragma once

#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "rmp/track/pose2.h"
#include "rmp/track/track_observation.h"

namespace idi::rmp {

struct SyntheticTrack {
  std::vector<Vec2d> centre_m;                     // world frame, in order
  std::vector<std::pair<double, double>> gaps_m;  // stretches (arc length from the start) without tape
};

struct SyntheticObservationOptions {
  double sample_spacing_m = 0.01;
  double noise_m = 0.0;       // white noise on each piece's vertices
  double bias_m = 0.0;        // common lateral offset of the whole observation (calibration error)
};

// The pieces of `track` visible in all `footprints_vehicle` from `world_from_vehicle`, in the vehicle
// frame. Corners of the true polyline stay vertices of the pieces.
TrackObservation SyntheticObservation(const SyntheticTrack& track, const Pose2& world_from_vehicle,
                                      const std::vector<std::vector<Vec2d>>& footprints_vehicle,
                                      int64_t timestamp_ns, const SyntheticObservationOptions& options = {},
                                      std::mt19937_64* rng = nullptr);

}  // namespace idi::rmp
