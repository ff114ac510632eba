#include "shared/kinematics/rtu.h"

namespace idi {

std::vector<ParamSpec> RailParamSpecs() {
  return {
      {"phi_l", Unit::kDegree, 0.0, "rail direction in the base frame: rotation about z"},
      {"phi_m", Unit::kDegree, 0.0, "rail direction in the base frame: then rotation about y"},
  };
}

std::vector<ParamSpec> RobotToRobotParamSpecs() {
  return {
      {"psi_x", Unit::kMillimetre, 0.0, "robot 2 rail frame origin in robot 1 rail frame, x"},
      {"psi_y", Unit::kMillimetre, 0.0, "... y"},
      {"psi_z", Unit::kMillimetre, 0.0, "... z"},
      {"psi_alpha", Unit::kDegree, 0.0, "twist about the rail direction"},
  };
}

}  // namespace idi
