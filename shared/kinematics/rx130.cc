#include "shared/kinematics/rx130.h"

#include <cmath>

namespace idi {

std::vector<ParamSpec> Rx130ParamSpecs() {
  return {
      {"alpha2", Unit::kDegree, -90.0, "link 2 twist (DH)"},
      {"a2", Unit::kMillimetre, 0.0, "link 2 length (DH)"},
      {"theta2", Unit::kDegree, 0.0, "joint 2 offset"},
      {"d2", Unit::kMillimetre, 0.0, "link 2 offset (DH)"},
      {"alpha3", Unit::kDegree, 0.0, "link 3 twist (Hayati)"},
      {"a3", Unit::kMillimetre, 625.0, "upper arm length (Hayati)"},
      {"theta3", Unit::kDegree, -180.0, "joint 3 offset"},
      {"beta3", Unit::kDegree, 0.0, "link 3 rotation about y (Hayati)"},
      {"alpha4", Unit::kDegree, -90.0, "link 4 twist (DH); Table 3.1's +90 is a misprint"},
      {"a4", Unit::kMillimetre, 0.0, "link 4 length (DH)"},
      {"theta4", Unit::kDegree, 0.0, "joint 4 offset"},
      {"d4", Unit::kMillimetre, 625.0, "forearm length (DH)"},
      {"alpha5", Unit::kDegree, 90.0, "link 5 twist (DH)"},
      {"a5", Unit::kMillimetre, 0.0, "link 5 length (DH)"},
      {"theta5", Unit::kDegree, 0.0, "joint 5 offset"},
      {"d5", Unit::kMillimetre, 0.0, "link 5 offset (DH)"},
      {"alpha6", Unit::kDegree, -90.0, "link 6 twist (DH)"},
      {"a6", Unit::kMillimetre, 0.0, "link 6 length (DH)"},
  };
}

std::vector<ParamSpec> LaserParamSpecs() {
  return {
      {"theta_x", Unit::kDegree, 0.0, "laser tilt about the flange x axis"},
      {"theta_y", Unit::kDegree, 0.0, "laser tilt about the flange y axis"},
      {"px", Unit::kMillimetre, 0.0, "laser line offset along x"},
      {"py", Unit::kMillimetre, 0.0, "laser line offset along y"},
  };
}

ParamSet Rx130Nominal() { return ParamSet(Rx130ParamSpecs()); }
ParamSet LaserNominal() { return ParamSet(LaserParamSpecs()); }

bool JointLimits::Contains(const Joints& q, double margin) const {
  for (std::size_t i = 0; i < q.size(); ++i) {
    if (!(q[i] >= min[i] + margin && q[i] <= max[i] - margin)) {
      return false;
    }
  }
  return true;
}

int JointLimits::FirstViolation(const Joints& q) const {
  for (std::size_t i = 0; i < q.size(); ++i) {
    if (!(q[i] >= min[i] && q[i] <= max[i])) {
      return static_cast<int>(i);
    }
  }
  return -1;
}

JointLimits Rx130JointLimits() {
  const std::array<double, kRx130Joints> controller_min = {-160, -137.5, -142.5, -270, -105, -270};
  const std::array<double, kRx130Joints> controller_max = {160, 137.5, 142.5, 270, 120.5, 270};
  JointLimits limits;
  for (std::size_t i = 0; i < kRx130Joints; ++i) {
    limits.min[i] = DegToRad(controller_min[i] + kRx130ControllerToModelDeg[i]);
    limits.max[i] = DegToRad(controller_max[i] + kRx130ControllerToModelDeg[i]);
  }
  return limits;
}

std::array<Line3d, kRx130Joints> Rx130JointAxes(const ParamSet& robot, const Joints& q) {
  const double* p = robot.data();
  std::array<Rigid3d, kRx130Joints> frames;
  frames[0] = RotZ(q[0]);
  frames[1] = frames[0] * DhLink(p[kAlpha2], p[kA2], p[kTheta2] + q[1], p[kD2]);
  frames[2] = frames[1] * HayatiLink(p[kAlpha3], p[kA3], p[kBeta3], p[kTheta3] + q[2]);
  frames[3] = frames[2] * DhLink(p[kAlpha4], p[kA4], p[kTheta4] + q[3], p[kD4]);
  frames[4] = frames[3] * DhLink(p[kAlpha5], p[kA5], p[kTheta5] + q[4], p[kD5]);
  frames[5] = frames[4] * DhLink(p[kAlpha6], p[kA6], kRx130Theta6Rad + q[5], kRx130D6Mm);
  std::array<Line3d, kRx130Joints> axes;
  for (std::size_t i = 0; i < kRx130Joints; ++i) {
    axes[i] = {frames[i].translation, frames[i].rotation.col(2)};
  }
  return axes;
}

Joints QuantizeToEncoders(const Joints& q) {
  Joints out{};
  for (std::size_t i = 0; i < kRx130Joints; ++i) {
    const double counts_per_rad = kRx130CountsPerDeg[i] * kDegPerRad;
    out[i] = std::round(q[i] * counts_per_rad) / counts_per_rad;
  }
  return out;
}

}  // namespace idi
