// idi-rmp's driving commands:
//   sim     --track TRACK.yaml --json [--record DIR] [--can-log FILE] [--png FILE] [--config FILE]
//           the closed loop in the twin (DESIGN.md §6)
//   replay  DIR --json [--can-log FILE]   the pipeline on a drive log; exit 1 when its commands differ
//                                         from the recorded ones
//   run     --config FILE                 the service: hardware, replay or sim backend from the config
#pragma once

#include "shared/runtime/cli.h"

namespace idi::rmp {

// Gives `sim` (the command the renderer's `sim render` hangs under; created here when absent) its own
// action: the closed loop. The action runs only when no subcommand of `sim` was given.
CLI::App* AddSimRunCommand(CliApp& cli, CLI::App* sim = nullptr);
void AddReplayCommand(CliApp& cli);
void AddRunCommand(CliApp& cli);

}  // namespace idi::rmp
