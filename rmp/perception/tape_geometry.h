// From tape edges on the ground to the track's centre line (§8.12.4): the EMPL lines of the tape's two
// edges, placed on the ground, are paired into strips of the tape's width; each strip's midline is a
// piece of centre line, and pieces meeting at a corner are joined at the intersection of their lines
// (the centre line's IDI point). Pure 2D geometry in the vehicle's ground frame (metres).
#pragma once

#include <array>
#include <vector>

#include "rmp/track/track_observation.h"
#include "shared/geometry/rigid3.h"
#include "shared/util/status.h"

namespace idi::rmp {

// One tape edge on the ground: the confirmed segment of an EMPL line.
struct GroundEdge {
  Vec2d a = Vec2d::Zero(), b = Vec2d::Zero();
  // Which side of a->b the tape (the brighter or darker side, as configured) lies on: +1 left,
  // -1 right, 0 unknown.
  int tape_side = 0;
  // The segment's ends lie inside the image(s) (not cut by an image border).
  std::array<bool, 2> end_inside{true, true};
};

struct TapeGeometryOptions {
  double tape_width_m = 0.05;
  double width_tolerance_m = 0.02;      // |edge separation - width| allowed
  double max_edge_angle_deg = 5.0;      // the two edges of a strip are parallel to within this
  double min_overlap_m = 0.02;          // and overlap along the tape by at least this
  double join_distance_m = 0.06;        // + tape width: how far a strip's end may lie from the corner
  double max_turn_deg = 155.0;          // sharper joins are not a track
  double collinear_deg = 2.0;           // joins turning less than this have no vertex
  double min_piece_length_m = 0.04;

  // Sets the tape's width, and caps the width tolerance at half of it: a strip is accepted within that
  // of the width, so narrow tape (19 mm) keeps a tolerance that Check accepts.
  void SetTapeWidth(double width_m);
  Status Check() const;
};

// A strip: the midline of two paired edges, from end 0 to end 1.
struct CentreSegment {
  Vec2d a = Vec2d::Zero(), b = Vec2d::Zero();
  std::array<bool, 2> end_seen{false, false};  // both edges end inside the images there
  int edge1 = -1, edge2 = -1;                  // indices into the edges
};

// Pairs edges into strips of the tape's width.
std::vector<CentreSegment> PairTapeEdges(const std::vector<GroundEdge>& edges, const TapeGeometryOptions& options);

// Joins strips end to end at corners into pieces of centre line (each a polyline with a vertex per
// corner), dropping pieces shorter than min_piece_length_m.
std::vector<CentreLinePiece> ChainCentreSegments(const std::vector<CentreSegment>& segments,
                                                 const TapeGeometryOptions& options);

}  // namespace idi::rmp
