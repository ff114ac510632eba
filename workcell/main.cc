// idi-workcell: the controller of the two-arm workcell (calibration, scanning, picking).
#include "shared/runtime/cli.h"
#include "workcell/app/calibrate_command.h"
#include "workcell/app/calibrate_ptu_command.h"
#include "workcell/app/cell_factory.h"
#include "workcell/app/features_command.h"
#include "workcell/app/kinematics_command.h"
#include "workcell/app/reconstruct_command.h"
#include "workcell/app/replay_command.h"
#include "workcell/app/scan_command.h"
#include "workcell/app/sim_render_command.h"
#include "workcell/service/service_commands.h"

int main(int argc, char** argv) {
  idi::CliApp cli(
      "idi-workcell: calibrates the RX-130 arms, the rail and the pan-tilt cameras, reconstructs objects\n"
      "from EMPL lines and IDI points, and picks them with the other arm.",
      "idi-workcell");
  idi::workcell::AddKinematicsCommand(cli);
  idi::workcell::AddFeaturesCommand(cli);
  idi::workcell::AddParamsCommand(cli);
  idi::workcell::AddCalibrateCommand(cli);
  idi::workcell::AddCalibratePtuCommand(cli);  // under `calibrate`, after robot|rtu
  idi::workcell::AddReconstructCommand(cli);
  idi::workcell::AddReplayCommands(cli);
  idi::workcell::AddScanCommand(cli);
  idi::workcell::AddSimRenderCommand(cli);
  idi::workcell::AddServiceCommands(cli, idi::workcell::MakeCell);
  return idi::RunCli(cli, argc, argv);
}
