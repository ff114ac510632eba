#include "rmp/app/rmp_commands.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <memory>

#include "rmp/app/hardware_run.h"
#include "rmp/app/replay_run.h"
#include "rmp/app/sim_run.h"
#include "shared/runtime/systemd_notify.h"
#include "shared/util/atomic_file.h"

namespace idi::rmp {
namespace {

std::atomic<bool> g_stop{false};

extern "C" void RmpOnSignal(int /*sig*/) { g_stop.store(true); }

void InstallSignalHandlers() {
  struct sigaction sa {};
  sa.sa_handler = RmpOnSignal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGHUP, &sa, nullptr);
}

void PrintReport(const RunReport& r, bool json) {
  if (json) {
    std::cout << r.ToJson().dump() << "\n";
    return;
  }
  std::cout << fmt::format(
      "{}: {:.2f} m in {:.1f} s, lateral error rms {:.1f} mm max {:.1f} mm, track visible {:.1f} %, {} stereo pairs "
      "(perception median {:.2f} ms, p99 {:.2f} ms), {} commands ({})\n",
      r.completed ? "completed" : "not completed", r.distance_m, r.time_s, 1000 * r.lateral_error_rms_m,
      1000 * r.lateral_error_max_m, 100 * r.track_visible_fraction, r.frames, r.perception_ms_median, r.perception_ms_p99,
      r.commands, r.end);
}

struct SimCli {
  std::string track, record, can_log, png, config, report;
  double speed_mps = 0.0, max_time_s = 0.0;
  bool json = false, real_time = false;
};

Status RunSimCli(const SimCli& o) {
  if (o.track.empty()) return InvalidArgument("sim: --track TRACK.yaml is required");
  SimRunOptions so;
  if (!o.config.empty()) {
    IDI_ASSIGN_OR_RETURN(so.config, LoadRmpConfig(o.config));
    IDI_ASSIGN_OR_RETURN(so.config_text, ReadFile(o.config));
  }
  IDI_ASSIGN_OR_RETURN(so.track, LoadTrackFile(o.track));
  if (o.speed_mps > 0) so.track.speed_mps = o.speed_mps;
  if (so.track.speed_mps == 0) so.track.speed_mps = so.config.planner.cruise_speed_mps;
  so.record_dir = o.record;
  so.can_log = o.can_log;
  so.png = o.png;
  so.max_time_s = o.max_time_s;
  so.real_time = o.real_time || so.config.sim_real_time;
  g_stop.store(false);
  InstallSignalHandlers();
  so.stop = &g_stop;
  IDI_ASSIGN_OR_RETURN(const SimRunResult res, RunSimulation(so));
  if (!o.report.empty()) IDI_RETURN_IF_ERROR(WriteFileAtomically(o.report, res.report.ToJson().dump(2) + "\n"));
  PrintReport(res.report, o.json);
  if (g_stop.load()) return Cancelled("sim: stopped by a signal (zero commanded)");
  return Status::Ok();
}

std::string LogDirName(const std::string& state_dir) {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  localtime_r(&now, &tm);
  char buf[64];
  std::strftime(buf, sizeof(buf), "%Y%m%d-%H%M%S", &tm);
  return (std::filesystem::path(state_dir) / "logs" / buf).string();
}

struct RunCli {
  std::string config, record;
  bool json = false;
};

Status RunService(const RunCli& o) {
  IDI_ASSIGN_OR_RETURN(const RmpConfig config, LoadRmpConfig(o.config));
  IDI_ASSIGN_OR_RETURN(const std::string config_text, ReadFile(o.config));
  std::string record = o.record;
  if (record.empty() && config.record) {
    if (config.state_dir.empty()) return InvalidArgument(o.config + ": record: true needs state_dir");
    record = LogDirName(config.state_dir);
    std::filesystem::create_directories(std::filesystem::path(record).parent_path());
  }
  g_stop.store(false);
  InstallSignalHandlers();
  spdlog::info("idi-rmp run: backend {} ({})", BackendName(config.backend), o.config);
  RunReport report;
  switch (config.backend) {
    case Backend::kSim: {
      if (config.sim_track.empty()) return InvalidArgument(o.config + ": backend sim needs sim.track");
      SimRunOptions so;
      so.config = config;
      so.config_text = config_text;
      IDI_ASSIGN_OR_RETURN(so.track, LoadTrackFile(config.sim_track));
      if (so.track.speed_mps == 0) so.track.speed_mps = config.planner.cruise_speed_mps;
      so.record_dir = record;
      so.real_time = config.sim_real_time;
      so.stop = &g_stop;
      NotifyReady();
      auto res = RunSimulation(so);
      NotifyStopping();
      if (!res.ok()) return res.status();
      report = res->report;
      break;
    }
    case Backend::kReplay: {
      if (config.replay_dir.empty()) return InvalidArgument(o.config + ": backend replay needs replay.dir");
      NotifyReady();
      IDI_ASSIGN_OR_RETURN(const ReplayResult res, RunReplay({config.replay_dir, ""}));
      NotifyStopping();
      report = res.report;
      break;
    }
    case Backend::kHardware: {
      HardwareRunOptions ho;
      ho.config = config;
      ho.config_text = config_text;
      ho.record_dir = record;
      ho.stop = &g_stop;
      IDI_ASSIGN_OR_RETURN(report, RunHardware(ho));
      break;
    }
  }
  PrintReport(report, o.json);
  return Status::Ok();
}

}  // namespace

CLI::App* AddSimRunCommand(CliApp& cli, CLI::App* sim) {
  auto o = std::make_shared<SimCli>();
  if (sim == nullptr) sim = cli.app.add_subcommand("sim", "the closed loop in the digital twin (and its tools)");
  sim->add_option("--track", o->track, "TRACK.yaml: the taped track (DESIGN.md §6)");
  sim->add_flag("--json", o->json, "print the report as JSON on stdout");
  sim->add_option("--record", o->record, "write a drive log (images, CAN, ticks) to this new folder");
  sim->add_option("--can-log", o->can_log, "write the RMP's CAN traffic in candump -l format");
  sim->add_option("--png", o->png, "write the track with the driven path and the lateral error");
  sim->add_option("--report", o->report, "also write the JSON report to this file");
  sim->add_option("--config", o->config, "rmp.yaml: rig, planner, control, sim options and faults");
  sim->add_option("--speed-mps", o->speed_mps, "cruise speed (default: the track's speed_mps, else the config's)");
  sim->add_option("--max-time-s", o->max_time_s, "simulated time limit (default: from the track's length)");
  sim->add_flag("--real-time", o->real_time, "pace the twin with the wall clock");
  sim->parse_complete_callback([&cli, sim, o] {
    if (sim->get_subcommands().empty()) cli.selected = [o] { return RunSimCli(*o); };
  });
  return sim;
}

void AddReplayCommand(CliApp& cli) {
  auto o = std::make_shared<ReplayOptions>();
  auto json = std::make_shared<bool>(false);
  CLI::App* cmd = cli.AddCommand(&cli.app, "replay", "re-run the pipeline on a drive log and compare the commands", [o, json] {
    IDI_ASSIGN_OR_RETURN(const ReplayResult res, RunReplay(*o));
    PrintReport(res.report, *json);
    return Status::Ok();
  });
  cmd->add_option("dir", o->dir, "the drive log folder (idi-rmp sim --record, or the vehicle's state_dir/logs)")->required();
  cmd->add_flag("--json", *json, "print the report as JSON on stdout");
  cmd->add_option("--can-log", o->can_log, "write the replayed driver's CAN frames in candump -l format");
}

void AddRunCommand(CliApp& cli) {
  auto o = std::make_shared<RunCli>();
  CLI::App* cmd = cli.AddCommand(&cli.app, "run", "drive: the service (hardware, replay or sim backend from the config)",
                                 [o] { return RunService(*o); });
  cmd->add_option("--config", o->config, "rmp.yaml (e.g. /etc/idi/rmp.yaml)")->required();
  cmd->add_option("--record", o->record, "write a drive log to this new folder (default: state_dir/logs/<time> if record: true)");
  cmd->add_flag("--json", o->json, "print the final report as JSON on stdout");
}

}  // namespace idi::rmp
