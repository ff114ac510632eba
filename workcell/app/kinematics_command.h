// `idi-workcell kinematics`: forward kinematics of the RX-130 with its laser tool, and laser aiming.
// `idi-workcell params`: writes a model's nominal parameter file, the template for calibrations.
#pragma once

#include "shared/runtime/cli.h"

namespace idi::workcell {

void AddKinematicsCommand(CliApp& cli);
void AddParamsCommand(CliApp& cli);

}  // namespace idi::workcell
