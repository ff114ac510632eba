#include "shared/kinematics/barrett_hand.h"

#include <cmath>

#include "shared/util/units.h"

namespace idi {

BarrettFingerFrame BarrettFingerAt(const BarrettHandParams& hand, int finger, double spread) {
  BarrettFingerFrame g;
  const double r = hand.knuckle_radius_mm;
  if (finger == 2) {
    g.knuckle = Vec3d(-r, 0, 0);
    g.closing = Vec3d::UnitX();
  } else {
    const double sign = finger == 0 ? 1.0 : -1.0;
    const double psi = kPi / 6 + spread / 2;  // round the palm circle: 30 deg at spread 0, 60 deg at 60
    g.knuckle = Vec3d(r * std::cos(psi), sign * r * std::sin(psi), 0);
    g.closing = Vec3d(-std::cos(spread), -sign * std::sin(spread), 0);
  }
  g.hinge = Vec3d::UnitZ().cross(g.closing);
  return g;
}

std::array<Vec3d, 3> BarrettFingerPoints(const BarrettHandParams& hand, int finger, double spread, double reading) {
  const BarrettFingerFrame g = BarrettFingerAt(hand, finger, spread);
  const double phi1 = reading - DegToRad(hand.open_angle_deg);
  const double phi2 = phi1 + DegToRad(hand.distal_bend_deg) + hand.distal_ratio * reading;
  const Vec3d elbow = g.knuckle + hand.proximal_mm * (std::cos(phi1) * Vec3d::UnitZ() + std::sin(phi1) * g.closing);
  const Vec3d tip = elbow + hand.distal_mm * (std::cos(phi2) * Vec3d::UnitZ() + std::sin(phi2) * g.closing);
  return {g.knuckle, elbow, tip};
}

bool BarrettTipOnFace(const BarrettHandParams& hand, int finger, double spread, double face_distance_mm,
                      double* reading_rad, double* depth_mm) {
  if (!hand.Valid() || finger < 0 || finger > 2 || !std::isfinite(spread) || !std::isfinite(face_distance_mm)) {
    return false;
  }
  const BarrettFingerFrame g = BarrettFingerAt(hand, finger, spread);
  // Outward coordinate of the fingertip's pad surface minus the face's: positive while the finger is out.
  auto gap = [&](double r) {
    return BarrettFingerPoints(hand, finger, spread, r)[2].dot(-g.closing) - hand.pad_radius_mm - face_distance_mm;
  };
  const double closed = DegToRad(hand.closed_deg), step = DegToRad(0.5);
  if (!(gap(0) > 0)) return false;
  double lo = 0, hi = -1;
  for (double r = step; r <= closed + 1e-12; r += step) {
    if (gap(r) <= 0) {
      hi = r;
      break;
    }
    lo = r;
  }
  if (hi < 0) return false;
  for (int it = 0; it < 60; ++it) {
    const double mid = 0.5 * (lo + hi);
    (gap(mid) > 0 ? lo : hi) = mid;
  }
  const double r = 0.5 * (lo + hi);
  if (reading_rad != nullptr) *reading_rad = r;
  if (depth_mm != nullptr) *depth_mm = BarrettFingerPoints(hand, finger, spread, r)[2].z();
  return true;
}

}  // namespace idi
