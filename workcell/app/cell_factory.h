// What `idi-workcell run` serves (workcell/service/service_commands.h): the devices of the configured
// backend and the jobs they can do.
//
//   sim       the digital twin of `sim.seed` (shared/sim/workcell): arms, rail, lasers and wall cameras;
//             jobs calibrate-robot1, calibrate-robot2, calibrate-rail and calibrate-ptu, each the same
//             procedure as `idi-workcell calibrate ... --sim`, results in the job's run folder and the
//             calibration committed as a new version (robot1, robot2, rail, ptu).
//   hardware  the Staubli arms (VAL3 server over TCP), the PTUs and the Barrett hand (serial): connect,
//             home (arms read, PTUs to 0/0, hand initialised), stop all, health. Calibration on the
//             real cell needs the wall camera's spot observer, which is not wired yet: the hardware
//             backend serves no calibration jobs and says so at start.
#pragma once

#include "workcell/service/service_commands.h"

namespace idi::workcell {

Result<Cell> MakeCell(const WorkcellConfig& config);

}  // namespace idi::workcell
