// The twin's object scenes for the vision front end's corner statistics (issue 4): three to five boxes,
// triangular prisms and L-brackets on a table before a wall, and the score of IDI points against their
// rendered ground truth. Shared by features_bench (section D) and the integration test that guards it.
#pragma once

#include <functional>
#include <map>
#include <random>
#include <vector>

#include "shared/features/features.h"
#include "shared/sim/render/render.h"

namespace idi::test {

// A random scene (the same for the same generator state). `clutter`: value-noise texture on the table
// and the wall. Scene units are mm; the objects stand within 350 mm of the origin, 10 mm or more apart
// (no two solids interpenetrate).
sim::Scene RandomObjectScene(std::mt19937& rng, bool clutter);

// IDI points of one image against its ground truth.
//  - True corners: projected 3D vertices (junction types L, Y, arrow, multi) where at least two of the
//    meeting lines are visible over >= 20 px with >= 10 DN contrast. Found: an IDI point within 2 px.
//  - Spurious: IDI points farther than 3 px from every true junction of any type (occlusion
//    T-junctions are real image junctions).
//  - A missed corner's cause: fewer than two of its lines found (a line within 2 deg of the true one
//    and 2 px of its middle); or found, but fewer than two confirmed segments reach the corner within
//    their extensions; or other.
struct CornerScore {
  int total = 0, found = 0, points = 0, spurious = 0;
  int miss_line_not_found = 0, miss_segment_short = 0, miss_other = 0;
  // Corners whose counted lines all meet at less than kNearlyCollinearDeg in the image (a slight bend of
  // a silhouette): how many there are and how many of them were missed. The detector makes no point
  // from lines at less than IdiOptions::min_angle_deg (10 by default), and such a bend is usually fitted
  // as one line.
  int nearly_collinear = 0, nearly_collinear_missed = 0;
  // Corners with at least two resolvable lines (see Resolvable), and how many of them were found; the
  // same for those of them that are not nearly collinear either.
  int resolvable = 0, resolvable_found = 0;
  int resolvable_angled = 0, resolvable_angled_found = 0;
  std::vector<double> errors_px;  // of the found corners

  void Add(const CornerScore& o);
};
// `to_fit` maps truth pixels into the detector's coordinates (undistorted when it models distortion);
// `blur_sigma_px` is the PSF the image was rendered with (for CornerScore::resolvable).
CornerScore ScoreCorners(const sim::GroundTruth& truth,
                         const FeatureResult& result,
                         const std::function<Vec2d(const Vec2d&)>& to_fit,
                         double blur_sigma_px = 1.0);

inline constexpr double kNearlyCollinearDeg = 10.0;

// Whether a true line counts for a corner (visible over >= 20 px with >= kVisibleContrastDn contrast).
bool CountsForCorners(const sim::TruthLine& line);
inline constexpr double kVisibleContrastDn = 10.0;
// The lines of junction `j` that count for a corner, looked up by id in `lines` (the truth's lines).
std::vector<const sim::TruthLine*> CountedLines(const sim::TruthJunction& j,
                                                const std::map<int, const sim::TruthLine*>& lines);
// Whether `line` can be told apart from the other edges of the image: it has a stretch of at least
// kResolvableRunPx px all of whose points lie more than 2 blur_sigma_px + 1 px from every other true
// line of >= kVisibleContrastDn contrast (any length). Closer than that the two blurred steps make one
// gradient ridge: an L-bracket's plate seen edge-on, the two sides of a thin wedge. Distances
// are taken in the image to the straight chords between the lines' ends (under distortion a line bows
// by a pixel or so from its chord).
bool Resolvable(const sim::TruthLine& line, const std::vector<sim::TruthLine>& all, double blur_sigma_px);
inline constexpr double kResolvableRunPx = 20.0;
// The cosine of the widest angle between two of `counted` (in the image; 1 for fewer than two).
double WidestCos(const std::vector<const sim::TruthLine*>& counted);
// The detected line that explains a true one (within 2 deg, and 2 px at the true segment's middle), if any.
const EmplLine* MatchTruthLine(const FeatureResult& result, const Vec2d& normal, const Vec2d& a, const Vec2d& b);

}  // namespace idi::test
