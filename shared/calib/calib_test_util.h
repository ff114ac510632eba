// Test helpers: arms that differ from nominal as real ones do, and exact aiming data made with them.
#pragma once

#include <random>
#include <vector>

#include "shared/calib/acquisition.h"
#include "shared/calib/rail_calibration.h"
#include "shared/calib/robot_calibration.h"
#include "shared/kinematics/aiming.h"

namespace idi::calib::testing {

// An arm whose parameters are off nominal by Table 4.3-like amounts.
inline ArmModel PerturbedArm(unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  ArmModel a;
  for (std::size_t i = 0; i < a.robot.size(); ++i) {
    a.robot.set_value(i, a.robot.value(i) + (a.robot.spec(i).unit == Unit::kDegree ? DegToRad(0.05) : 0.5) * n(rng));
  }
  for (std::size_t i = 0; i < a.laser.size(); ++i) {
    a.laser.set_value(i, (a.laser.spec(i).unit == Unit::kDegree ? DegToRad(0.3) : 1.0) * n(rng));
  }
  a.rail.set_value(kPhiL, DegToRad(0.2) * n(rng));
  a.rail.set_value(kPhiM, DegToRad(0.2) * n(rng));
  return a;
}

// Readings that aim `arm` exactly at `point` (set 1) and at point - D t (set 2, the base moved by D
// along the rail), `per_set` each.
inline RobotCalibrationData ExactRobotData(const ArmModel& arm, const Vec3d& point, double distance_mm, int per_set,
                                           unsigned seed) {
  RobotCalibrationData d;
  d.distance_mm = distance_mm;
  d.method = TranslationMethod::kTranslate;
  const Vec3d t = RailDirectionInBase(arm.rail.value(kPhiL), arm.rail.value(kPhiM));
  PlanOptions po;
  po.seed = seed;
  for (int set = 1; set <= 2; ++set) {
    const Vec3d p = set == 1 ? point : Vec3d(point - distance_mm * t);
    const auto q = PlanAimConfigurations(arm.robot, arm.laser, p, per_set, Rx130JointLimits(), po);
    IDI_CHECK(q.ok(), q.status().ToString());
    for (const Joints& j : *q) d.readings.push_back({set, j, 0});
    po.seed += 1000;
  }
  return d;
}

}  // namespace idi::calib::testing
