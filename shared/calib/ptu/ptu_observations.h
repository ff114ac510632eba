// Observations of the single-point pan-tilt camera calibration (chapter 6): for every image, the
// camera, the TCF pose the arm reported (eq. 3.10), the PTU readings and the spot's pixel.
//
// CSV contract (DESIGN.md §6): header
//   camera,x_mm,y_mm,z_mm,alpha_deg,beta_deg,gamma_deg,pan_deg,tilt_deg,u_px,v_px
// columns in any order, `camera` is `left` or `right`, blank lines and lines starting with '#' are
// skipped. Pixels follow shared/camera/pinhole.h (integer values at pixel centres).
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "shared/geometry/rigid3.h"
#include "shared/kinematics/biclops.h"
#include "shared/util/status.h"
#include "shared/util/units.h"

namespace idi::calib {

struct PtuObservation {
  BiclopsSide camera = BiclopsSide::kLeft;
  TcfPose tcf;  // ^B T_E, eq. 3.10
  double pan_rad = 0;
  double tilt_rad = 0;
  Vec2d pixel_px = Vec2d::Zero();
  int source_line = 0;  // line of the CSV file it came from; 0 when it did not come from a file
};

// The PTU-D46's travel (device-protocols.md §2: pan ±3090, tilt −907..+604 positions of 185.1428
// arc-seconds at reset): pan ±158.9°, tilt −46.6°..+31.1°, in the unit's own angles.
struct PtuRange {
  static constexpr double kStepDeg = 185.1428 / 3600;  // one position, degrees
  double pan_min_rad = DegToRad(-3090 * kStepDeg);
  double pan_max_rad = DegToRad(3090 * kStepDeg);
  double tilt_min_rad = DegToRad(-907 * kStepDeg);
  double tilt_max_rad = DegToRad(604 * kStepDeg);
  Status Check() const;
  // A reading at an end stop is in range: the limits and the readings are both whole position counts,
  // converted by different routes, so they may differ in the last bits (1e-9 rad is 2e-5 of a count).
  bool Contains(double pan_rad, double tilt_rad) const {
    constexpr double kTol = 1e-9;
    return pan_rad >= pan_min_rad - kTol && pan_rad <= pan_max_rad + kTol && tilt_rad >= tilt_min_rad - kTol &&
           tilt_rad <= tilt_max_rad + kTol;
  }
};

// Parses the CSV text; `where` (a file name) prefixes messages, which also name the line and column.
// A row whose u_px/v_px is empty is an image where the spot was not found: an error, not a row to skip.
Result<std::vector<PtuObservation>> ParsePtuObservationsCsv(std::string_view text, const std::string& where);
// The CSV text for `observations` (header first; angles in degrees, 17 significant digits).
std::string FormatPtuObservationsCsv(const std::vector<PtuObservation>& observations);

// Checks a data set before calibration: finite values, every PTU reading inside `range`, no image with
// two spots (two rows for one camera at the same arm pose and PTU readings, the §6.4.3 assumption of a
// single bright spot broken). Messages name `where` and the line (or the observation index).
Status CheckPtuObservations(const std::vector<PtuObservation>& observations, const PtuRange& range,
                            const std::string& where);

// Observations of one camera.
std::vector<PtuObservation> SelectCamera(const std::vector<PtuObservation>& observations, BiclopsSide camera);

}  // namespace idi::calib
