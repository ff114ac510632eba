// What perception reports about the track in one stereo frame: pieces of the tape's centre line on
// the ground, in the vehicle frame (origin on the ground midway between the wheels, x forward, y left,
// metres), and where the cameras could see the ground at all.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "shared/geometry/rigid3.h"

namespace idi::rmp {

struct CentreLinePiece {
  // Centre line of one continuous run of tape: straight legs joined at the corners the perception
  // found (a vertex per corner), in order along the tape (either direction).
  std::vector<Vec2d> points_m;
  // The tape visibly ends at points_m.front() / points_m.back(): both edges end inside the images,
  // with ground beyond them in view (a gap, a covered stretch or the track's end). False when the
  // tape runs out of the images there.
  std::array<bool, 2> end_seen{false, false};
  double sigma_m = 0.005;  // position uncertainty of the centre line
};

struct TrackObservation {
  int64_t timestamp_ns = 0;  // exposure time of the stereo pair
  std::vector<CentreLinePiece> pieces;
  // Ground polygons (vehicle frame) each camera sees; tape missing inside both means no tape there.
  std::vector<std::vector<Vec2d>> footprints_m;
};

}  // namespace idi::rmp
