// `idi-workcell calibrate robot|rtu` (DESIGN.md §6): ViCKi robot calibration (chapter 4) and rail
// calibration (chapter 5) from observation files, or the whole procedure in the digital twin (--sim).
#pragma once

#include <functional>
#include <string>

#include "shared/runtime/cli.h"

namespace idi::workcell {

// `calibrate robot`: from files, or (sim) acquisition and all in the digital twin of seed `seed`.
struct RobotCommandOptions {
  std::string observations, method = "translate", out, validate, report, plots;
  double distance_mm = 0;
  double spot_sigma_mm = 0.05;
  double distance_sigma_mm = 0.1414;  // two rail moves of 0.1 mm repeatability
  bool sim = false;
  unsigned seed = 1;
  int arm = 1;
  int readings = 540;
  std::function<bool()> cancelled;  // --sim: polled between readings (the service's stop)
};

// `calibrate rtu`: robot 1 and 2 from their files (with sim: calibrated in the twin when missing).
struct RtuCommandOptions {
  std::string observations, robot1, robot2, out, report, plots;
  double spot_sigma_mm = 0.05;
  double rail_sigma_mm = 0.1;
  bool sim = false;
  unsigned seed = 1;
  int readings = 500;
  std::function<bool()> cancelled;  // --sim: polled between readings (the service's stop)
};

Status RunCalibrateRobot(const RobotCommandOptions& options);
Status RunCalibrateRtu(const RtuCommandOptions& options);
void AddCalibrateCommand(CliApp& cli);

}  // namespace idi::workcell
