#include "rmp/track/synthetic_observation.h"

#include <cmath>

#include "rmp/track/polygon.h"
#include "rmp/track/pose2.h"

namespace idi::rmp {
namespace {

bool InsideAll(const std::vector<std::vector<Vec2d>>& polys, const Vec2d& p) {
  for (const auto& poly : polys) {
    if (!PointInPolygon(poly, p)) return false;
  }
  return !polys.empty();
}

}  // namespace

TrackObservation SyntheticObservation(const SyntheticTrack& track, const Pose2& world_from_vehicle,
                                      const std::vector<std::vector<Vec2d>>& footprints_vehicle, int64_t timestamp_ns,
                                      const SyntheticObservationOptions& options, std::mt19937_64* rng) {
  TrackObservation obs;
  obs.timestamp_ns = timestamp_ns;
  obs.footprints_m = footprints_vehicle;
  const Pose2 vehicle_from_world = world_from_vehicle.Inverse();
  // Samples along the track: (vehicle-frame point, is a true vertex, tape present, in view).
  struct Sample {
    Vec2d p;
    bool vertex;
    bool tape;
    bool visible;
  };
  std::vector<Sample> samples;
  double s = 0.0;
  auto tape_at = [&](double sa) {
    for (const auto& [a, b] : track.gaps_m) {
      if (sa > a && sa < b) return false;
    }
    return true;
  };
  for (std::size_t i = 1; i < track.centre_m.size(); ++i) {
    const Vec2d a = track.centre_m[i - 1], b = track.centre_m[i];
    const double len = (b - a).norm();
    const int n = std::max(1, static_cast<int>(std::ceil(len / options.sample_spacing_m)));
    for (int k = (i == 1 ? 0 : 1); k <= n; ++k) {
      const double f = static_cast<double>(k) / n;
      const Vec2d pv = vehicle_from_world * Vec2d(a + (b - a) * f);
      samples.push_back({pv, k == n || k == 0, tape_at(s + f * len), InsideAll(footprints_vehicle, pv)});
    }
    s += len;
  }
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (std::size_t i = 0; i < samples.size();) {
    if (!(samples[i].tape && samples[i].visible)) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j + 1 < samples.size() && samples[j + 1].tape && samples[j + 1].visible) ++j;
    if (j > i) {
      CentreLinePiece piece;
      for (std::size_t k = i; k <= j; ++k) {
        if (k == i || k == j || samples[k].vertex) piece.points_m.push_back(samples[k].p);
      }
      // The tape ends in view when the neighbouring sample is visible but has no tape (or there is none).
      piece.end_seen[0] = i == 0 || (samples[i - 1].visible && !samples[i - 1].tape);
      piece.end_seen[1] = j + 1 == samples.size() || (samples[j + 1].visible && !samples[j + 1].tape);
      if (options.noise_m > 0 && rng != nullptr) {
        for (Vec2d& p : piece.points_m) p += options.noise_m * Vec2d(gauss(*rng), gauss(*rng));
      }
      if (options.bias_m != 0.0) {
        for (Vec2d& p : piece.points_m) p.y() += options.bias_m;
      }
      obs.pieces.push_back(std::move(piece));
    }
    i = j + 1;
  }
  return obs;
}

}  // namespace idi::rmp
