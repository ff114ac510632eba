// Finger kinematics of the Barrett BH8 hand (§3.5): where the fingers are for a spread and finger
// readings. Used by the grasp procedure (to put the palm at the height where the fingertips meet the
// planned contacts) and by the twin's grasp physics (with the hand's true dimensions).
//
// Palm frame: origin at the palm centre, z out of the palm (towards the object), x from the thumb
// (finger 3) towards fingers 1 and 2. Each finger has a proximal link hinged at a knuckle on the palm
// circle and a distal link coupled to it, both turning in the vertical plane of the finger's closing
// direction. At reading 0 the proximal link splays `open_angle_deg` outward and the distal link is bent
// `distal_bend_deg` back inward (so the fingertips hang straight down, the widest opening); closing by
// a reading r turns the proximal link by r and the distal link by r (1 + distal_ratio). The thumb is
// fixed on the -x side; fingers 1 and 2 move round the palm with the spread: side by side at y = +-25 mm
// opposite the thumb at spread 0, the three closing lines meeting in the centre 120 deg apart at 60 deg.
#pragma once

#include <array>
#include <cmath>

#include "shared/geometry/rigid3.h"

namespace idi {

struct BarrettHandParams {
  double knuckle_radius_mm = 50;
  double proximal_mm = 70;
  double distal_mm = 58;
  double open_angle_deg = 40;
  double distal_bend_deg = 40;
  double distal_ratio = 1.0 / 3.0;
  double pad_radius_mm = 9;      // half the fingertip's thickness
  double closed_deg = 140;       // range of the finger reading
  // Finite and positive lengths, a finger range in (0, 360] deg (an infinite one made the tip search
  // run for ever), finite angles.
  bool Valid() const {
    for (double v : {knuckle_radius_mm,
                     proximal_mm,
                     distal_mm,
                     open_angle_deg,
                     distal_bend_deg,
                     distal_ratio,
                     pad_radius_mm,
                     closed_deg}) {
      if (!std::isfinite(v)) return false;
    }
    return knuckle_radius_mm > 0 && proximal_mm > 0 && distal_mm > 0 && pad_radius_mm > 0 && closed_deg > 0 &&
           closed_deg <= 360 && distal_ratio >= 0;
  }
};

// Finger k: 0 and 1 are fingers 1 and 2 (they spread), 2 is the thumb (finger 3).
struct BarrettFingerFrame {
  Vec3d knuckle = Vec3d::Zero();   // palm frame
  Vec3d closing = Vec3d::UnitX();  // unit, in the palm plane: where the finger moves when closing
  Vec3d hinge = Vec3d::UnitY();    // unit: a positive turn about it closes the finger
};
BarrettFingerFrame BarrettFingerAt(const BarrettHandParams& hand, int finger, double spread_rad);

// Knuckle, joint between the links, and fingertip (centres of the link axes), palm frame.
std::array<Vec3d, 3> BarrettFingerPoints(const BarrettHandParams& hand, int finger, double spread_rad,
                                         double reading_rad);

// Closing onto a vertical face (a plane parallel to the palm's z axis, facing the finger) at
// `face_distance_mm` from the palm centre along the finger's outward direction (-closing): the
// reading at which the fingertip pad touches it and the contact's depth below the palm (palm z).
// false when the fingertip cannot reach it (too far out or closer in than the fully closed finger).
bool BarrettTipOnFace(const BarrettHandParams& hand, int finger, double spread_rad, double face_distance_mm,
                      double* reading_rad, double* depth_mm);

}  // namespace idi
