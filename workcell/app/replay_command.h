// `idi-workcell replay DIR`: re-runs a recorded run's pipeline on a desktop (scans: the structure
// from the recorded images and poses); `idi-workcell export-rawlog DIR OUT.rawlog`: the recorded images
// as an MRPT rawlog for RawLogViewer / rawlog-edit.
#pragma once

#include "shared/runtime/cli.h"

namespace idi::workcell {

void AddReplayCommands(CliApp& cli);

}  // namespace idi::workcell
