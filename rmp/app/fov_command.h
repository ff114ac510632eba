// `idi-rmp fov`: where on the ground each fixed camera looks (the footprint the planner must keep the
// track inside, §8.12.4).
#pragma once

#include "shared/runtime/cli.h"

namespace idi::rmp {

void AddFovCommand(CliApp& cli);

}  // namespace idi::rmp
