// `idi-workcell reconstruct --views VIEWS.yaml --json [--ply FILE] [--overlay DIR]` (DESIGN.md §6).
#pragma once

#include "shared/runtime/cli.h"

namespace idi::workcell {

void AddReconstructCommand(CliApp& cli);

}  // namespace idi::workcell
