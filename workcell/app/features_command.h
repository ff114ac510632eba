// `idi-workcell features IMAGE... --json [--overlay DIR] [--camera FILE]`: EMPL lines and IDI points
// of each image (DESIGN.md §6), one JSON object per image per line.
#pragma once

#include "shared/runtime/cli.h"

namespace idi::workcell {

void AddFeaturesCommand(CliApp& cli);

}  // namespace idi::workcell
