// `idi-workcell calibrate robot|rtu` (DESIGN.md §6): ViCKi robot calibration (chapter 4) and rail
// calibration (chapter 5) from observation files, or the whole procedure in the digital twin (--sim).
#pragma once

#include "shared/runtime/cli.h"

namespace idi::workcell {

void AddCalibrateCommand(CliApp& cli);

}  // namespace idi::workcell
