// idi-rmp: the Segway RMP follows a taped track with two fixed cameras (§8.12.4).
#include "rmp/app/fov_command.h"
#include "rmp/app/rmp_commands.h"
#include "rmp/app/sim_render_command.h"
#include "shared/runtime/cli.h"

int main(int argc, char** argv) {
  idi::CliApp cli(
      "idi-rmp: finds a taped track with two fixed cameras, triangulates it onto the ground and drives\n"
      "a Segway RMP along it over CAN.",
      "idi-rmp");
  idi::rmp::AddFovCommand(cli);
  idi::rmp::AddSimRenderCommand(cli, idi::rmp::AddSimRunCommand(cli));
  idi::rmp::AddReplayCommand(cli);
  idi::rmp::AddRunCommand(cli);
  return idi::RunCli(cli, argc, argv);
}
