// The one place where joint readings change convention between the CS8 controller (degrees, the
// controller's zero) and the kinematic model (radians, shared/kinematics/rx130.h: model = controller
// + kRx130ControllerToModelDeg). Everything the arm driver, its emulator and the simulated arm send
// or receive goes through these two functions.
#pragma once

#include <array>

#include "shared/kinematics/rx130.h"

namespace idi::workcell {

using ControllerJointsDeg = std::array<double, kRx130Joints>;

ControllerJointsDeg ModelRadToControllerDeg(const Joints& q_model_rad);
Joints ControllerDegToModelRad(const ControllerJointsDeg& q_controller_deg);

// The RX-130's joint ranges in the controller's convention (degrees), i.e. Rx130JointLimits() moved
// back by the offset; the emulator and the simulated arm enforce these as the controller would.
ControllerJointsDeg Rx130ControllerMinDeg();
ControllerJointsDeg Rx130ControllerMaxDeg();

}  // namespace idi::workcell
