// Accuracy checks on held-out data: the spread of laser lines aimed at one point (§4.5.4, Fig. 4.10)
// and the spread of one arm's laser lines carried into the other arm's frame (§5.4.4, Fig. 5.3).
#pragma once

#include <vector>

#include "shared/calib/rail_calibration.h"
#include "shared/calib/robot_calibration.h"
#include "shared/geometry/lines.h"
#include "shared/util/status.h"

namespace idi::calib {

struct SpreadStats {
  Vec3d center = Vec3d::Zero();  // the point closest to all lines (or the reference point)
  double max_mm = 0;
  double mean_mm = 0;
  double std_mm = 0;
  std::vector<Vec2d> projected;  // each line's hit on the plane through `center`, relative to it (mm)
};

// §4.5.4: the point closest to all lines, the lines' hits on the plane through it perpendicular to
// their mean direction, and the radii of those hits from it. Needs at least 2 non-parallel lines.
Result<SpreadStats> LaserSpread(const std::vector<Line3d>& lines);
// The same radii about a given reference point.
Result<SpreadStats> SpreadAbout(const std::vector<Line3d>& lines, const Vec3d& reference);

// The laser lines of readings (one base position) with a model.
std::vector<Line3d> LaserLines(const ParamSet& robot, const ParamSet& laser, const std::vector<Joints>& readings);

// §5.4.4: both arms aim at one point from many configurations and rail positions. The point is located
// from robot 2's lines (in its rail frame R2); robot 1's lines are carried into R2 with psi and spread
// about it.
Result<SpreadStats> RailTransferSpread(const std::vector<RailReading>& readings, const ArmModel& arm1,
                                       const ArmModel& arm2, const std::array<double, 4>& psi);

}  // namespace idi::calib
