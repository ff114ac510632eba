#include "workcell/devices/staubli/staubli_joints.h"

#include "shared/util/units.h"

namespace idi::workcell {

ControllerJointsDeg ModelRadToControllerDeg(const Joints& q_model_rad) {
  ControllerJointsDeg out{};
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = RadToDeg(q_model_rad[i]) - kRx130ControllerToModelDeg[i];
  return out;
}

Joints ControllerDegToModelRad(const ControllerJointsDeg& q_controller_deg) {
  Joints out{};
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = DegToRad(q_controller_deg[i] + kRx130ControllerToModelDeg[i]);
  return out;
}

ControllerJointsDeg Rx130ControllerMinDeg() { return ModelRadToControllerDeg(Rx130JointLimits().min); }
ControllerJointsDeg Rx130ControllerMaxDeg() { return ModelRadToControllerDeg(Rx130JointLimits().max); }

}  // namespace idi::workcell
